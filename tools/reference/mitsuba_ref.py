#!/usr/bin/env python3
"""An independent reference for stereotrace's images: Mitsuba 3 (`scalar_rgb`).

It reads a scene folder in the shared format (scene.obj, scene.mtl, camera.json, lights.json;
see ../shared/scenes/README.md) with its own OBJ/MTL parser, not stereotrace's loader, builds
the same scene in Mitsuba with the paper's estimator settings (the `path` integrator with
max_depth 3: one primary and one secondary bounce with next-event estimation; max_depth 2
for direct lighting only), renders the camera of camera.json with a box pixel filter, and
compares the result with a stereotrace render of the same view.

    mitsuba_ref.py render FOLDER --res 128x128 --spp 1024 --out ref.exr [--bounces 1]
                   [--diffuse] [--opaque] [--skip-glass]
    mitsuba_ref.py compare OURS.exr REF.exr            # mean per channel, 8x8-block rel. RMSE
    mitsuba_ref.py check SCENE --stereotrace BIN ...   # both renders + comparison; exit 1 if
                                                       # outside the tolerances
                   [--ours SPEC]                       # stereotrace renders SPEC (e.g. SCENE
                                                       # as glTF) while Mitsuba reads SCENE
    mitsuba_ref.py table --stereotrace BIN             # RESULTS.md's table (every case below)

SCENE for `check` is a scene folder or a built-in name (exported with
`stereotrace export-scene`). The overrides mean what a stereotrace manifest's `[effects]`
section means (glossy = false, mirror = false: materials become diffuse, a mirror of its
reflectance `Ks`; alpha_masks = false: cut-outs opaque) and `glass = "skip"`; `check` writes
that manifest for stereotrace, and this script applies the same rules to the MTL itself.

Conventions shared with stereotrace (and where Mitsuba's defaults differ):
- reflection is two-sided (stereotrace faces the shading normal to the incoming ray), so every
  BSDF is wrapped in `twosided`; emitters are one-sided on the winding normal, so emissive
  faces get no vertex normals;
- positions are scaled by camera.json's `meters_per_unit` (stereotrace renders in metres;
  radiance is scale-free, point-light intensities are not scaled);
- `map_Kd` images are sRGB (Mitsuba's bitmap decodes them), filtered bilinearly with
  wrapping, and OBJ's v = 0 is the bottom row (Mitsuba's texture v = 0 is the top: v is
  flipped when the mesh is built).

What has no Mitsuba equivalent here is refused with exit code 2 and a reason: stereotrace's
glossy lobe (a Lambert base plus a GGX lobe added, not a Mitsuba plugin), its binary alpha
test (Mitsuba's `mask` is stochastic and counts as a bounce), transparent glass cut-outs
(`null` interactions count as bounces), and the sun/sky approximation.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

UNSUPPORTED = 2


class Unsupported(Exception):
    """A scene feature with no matching Mitsuba construct."""


# ---- the shared folder format ---------------------------------------------------------------


def parse_mtl(path):
    materials, current = {}, None
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            key, _, rest = line.partition(" ")
            rest = rest.strip()
            if key == "newmtl":
                current = {"name": rest, "Kd": [0.8, 0.8, 0.8], "Ks": [0, 0, 0], "Ke": [0, 0, 0]}
                materials[rest] = current
            elif current is None:
                continue
            elif key in ("Kd", "Ks", "Ke"):
                current[key] = [float(x) for x in rest.split()[:3]]
            elif key in ("Pr", "Pm", "Ns", "d", "Tr"):
                current[key] = float(rest.split()[0])
            elif key == "illum":
                current["illum"] = int(rest.split()[0])
            elif key in ("map_Kd", "map_d"):
                current[key] = rest.split()[-1]  # options before the file name are ignored
    return materials


def parse_obj(path):
    """Triangles grouped by material: {material: list of (positions, uvs or None, normals or None)}."""
    v, vt, vn = [], [], []
    groups, material, mtllib = {}, None, None

    def index(token, count):
        i = int(token)
        return i - 1 if i > 0 else count + i

    with open(path, encoding="utf-8") as f:
        for raw in f:
            parts = raw.split()
            if not parts or parts[0].startswith("#"):
                continue
            tag = parts[0]
            if tag == "v":
                v.append([float(x) for x in parts[1:4]])
            elif tag == "vt":
                vt.append([float(x) for x in parts[1:3]])
            elif tag == "vn":
                vn.append([float(x) for x in parts[1:4]])
            elif tag == "usemtl":
                material = parts[1] if len(parts) > 1 else None
            elif tag == "mtllib":
                mtllib = raw.split(None, 1)[1].strip()
            elif tag == "f":
                corners = []
                for c in parts[1:]:
                    fields = c.split("/")
                    corners.append(
                        (
                            index(fields[0], len(v)),
                            index(fields[1], len(vt)) if len(fields) > 1 and fields[1] else None,
                            index(fields[2], len(vn)) if len(fields) > 2 and fields[2] else None,
                        )
                    )
                for k in range(1, len(corners) - 1):  # fan triangulation
                    tri = (corners[0], corners[k], corners[k + 1])
                    pos = [v[c[0]] for c in tri]
                    uv = [vt[c[1]] for c in tri] if all(c[1] is not None for c in tri) else None
                    nrm = [vn[c[2]] for c in tri] if all(c[2] is not None for c in tri) else None
                    groups.setdefault(material, []).append((pos, uv, nrm))
    return groups, mtllib


# ---- the Mitsuba scene -------------------------------------------------------------------------


def rgb(value):
    return {"type": "rgb", "value": [float(x) for x in value]}


def material_bsdf(mi, m, folder, opts):
    """The Mitsuba BSDF of MTL material `m` under the override rules (see the module notes)."""
    illum = m.get("illum", 2 if max(m["Ks"]) > 0 else 1)
    if illum in (4, 6, 7, 9):
        raise Unsupported(f"material {m['name']}: glass is a transparent cut-out in stereotrace; pass --skip-glass")
    if "map_d" in m and not opts.opaque:
        raise Unsupported(f"material {m['name']}: alpha mask (map_d); pass --opaque (stereotrace: alpha_masks = false)")
    roughness = m.get("Pr")
    if roughness is None:
        ns = max(m.get("Ns", 0.0), 0.0)
        roughness = math.sqrt(math.sqrt(2.0 / (ns + 2.0))) if "Ns" in m else 1.0
    kd = m["Kd"]
    if illum in (3, 5, 8) and roughness <= 0.02:
        if opts.diffuse:
            return twosided({"type": "diffuse", "reflectance": rgb(m["Ks"])})
        return twosided({"type": "conductor", "material": "none", "specular_reflectance": rgb(m["Ks"])})
    if (illum == 2 and max(m["Ks"]) > 0) or illum in (3, 5, 8):
        if not opts.diffuse:
            raise Unsupported(f"material {m['name']}: stereotrace's glossy lobe has no Mitsuba plugin; pass --diffuse")
    if "map_Kd" in m:
        texture = os.path.join(folder, m["map_Kd"])
        if not os.path.isfile(texture):
            raise Unsupported(f"material {m['name']}: texture {texture} is missing")
        reflectance = {"type": "bitmap", "filename": texture, "filter_type": "bilinear", "wrap_mode": "repeat"}
    else:
        reflectance = rgb([min(max(c, 0.0), 1.0) for c in kd])
    return twosided({"type": "diffuse", "reflectance": reflectance})


def twosided(bsdf):
    return {"type": "twosided", "bsdf": bsdf}


def build_mesh(mi, name, tris, scale, bsdf, emission):
    import drjit as dr

    n = len(tris)
    positions = np.array([t[0] for t in tris], dtype=np.float64).reshape(n * 3, 3) * scale
    # Normals only where every triangle of the group has them and the group does not emit
    # (emitters are one-sided on the winding normal, which Mitsuba takes from face normals).
    normals = None
    if emission is None and all(t[2] is not None for t in tris):
        normals = np.array([t[2] for t in tris], dtype=np.float64).reshape(n * 3, 3)
    uvs = None
    if all(t[1] is not None for t in tris):
        uvs = np.array([t[1] for t in tris], dtype=np.float64).reshape(n * 3, 2)
        uvs[:, 1] = 1.0 - uvs[:, 1]
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    if emission is not None:
        props["emitter"] = mi.load_dict({"type": "area", "radiance": rgb(emission)})
    if normals is None:
        props["face_normals"] = True
    mesh = mi.Mesh(
        name,
        vertex_count=3 * n,
        face_count=n,
        props=props,
        has_vertex_normals=normals is not None,
        has_vertex_texcoords=uvs is not None,
    )
    params = mi.traverse(mesh)
    params["vertex_positions"] = dr.scalar.ArrayXf(positions.astype(np.float32).ravel())
    params["faces"] = dr.scalar.ArrayXu(np.arange(3 * n, dtype=np.uint32))
    if normals is not None:
        params["vertex_normals"] = dr.scalar.ArrayXf(normals.astype(np.float32).ravel())
    if uvs is not None:
        params["vertex_texcoords"] = dr.scalar.ArrayXf(uvs.astype(np.float32).ravel())
    params.update()
    return mesh


def light_emitters(folder, scale):
    path = os.path.join(folder, "lights.json")
    if not os.path.isfile(path):
        return {}
    with open(path, encoding="utf-8") as f:
        lights = json.load(f)
    out = {}
    for i, light in enumerate(lights):
        kind = light["type"]
        if kind == "area":
            continue  # geometry with Ke in the MTL
        if kind == "constant":
            out[f"light{i}"] = {"type": "constant", "radiance": rgb(light["radiance"])}
        elif kind == "point":
            position = [float(x) * scale for x in light["position"]]
            out[f"light{i}"] = {"type": "point", "position": position, "intensity": rgb(light["intensity"])}
        elif kind == "envmap":
            import mitsuba as mi

            matrix = [row[:] for row in light["to_world"]]
            if len(matrix) == 3:
                matrix = [r + [0.0] for r in matrix] + [[0.0, 0.0, 0.0, 1.0]]
            out[f"light{i}"] = {
                "type": "envmap",
                "filename": os.path.join(folder, light["filename"]),
                "scale": float(light.get("scale", 1.0)),
                "to_world": mi.ScalarTransform4f(matrix),
            }
        else:
            raise Unsupported(f"lights.json entry {i}: light type {kind!r} has no Mitsuba equivalent here")
    return out


def render(folder, width, height, spp, bounces, opts, out_path, seed=7):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    with open(os.path.join(folder, "camera.json"), encoding="utf-8") as f:
        camera = json.load(f)
    scale = float(camera.get("meters_per_unit", 1.0))
    groups, mtllib = parse_obj(os.path.join(folder, "scene.obj"))
    materials = parse_mtl(os.path.join(folder, mtllib or "scene.mtl"))
    scene = {"type": "scene"}
    for k, (name, tris) in enumerate(sorted(groups.items(), key=lambda kv: str(kv[0]))):
        m = materials.get(name) or {"name": str(name), "Kd": [0.8, 0.8, 0.8], "Ks": [0, 0, 0], "Ke": [0, 0, 0]}
        illum = m.get("illum", 1)
        if illum in (4, 6, 7, 9) and opts.skip_glass:
            continue
        bsdf = material_bsdf(mi, m, folder, opts)
        emission = m["Ke"] if max(m["Ke"]) > 0 else None
        scene[f"mesh{k}"] = build_mesh(mi, f"mesh{k}", tris, scale, bsdf, emission)
    scene.update(light_emitters(folder, scale))
    eye = [c * scale for c in camera["eye"]]
    target = [c * scale for c in camera["target"]]
    scene["sensor"] = {
        "type": "perspective",
        "fov": float(camera["vfov_deg"]),
        "fov_axis": "y",
        "near_clip": 1e-4,
        "far_clip": 1e7,
        "to_world": mi.ScalarTransform4f().look_at(origin=eye, target=target, up=camera.get("up", [0, 1, 0])),
        "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
    }
    scene["integrator"] = {"type": "path", "max_depth": 2 + bounces, "hide_emitters": False}
    loaded = mi.load_dict(scene)
    start = time.perf_counter()
    image = mi.render(loaded, spp=spp, seed=seed)
    seconds = time.perf_counter() - start
    mi.util.write_bitmap(out_path, image)
    return np.array(image), seconds


# ---- comparison ------------------------------------------------------------------------------


def read_exr(path):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    return np.array(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32))[:, :, :3]


def compare(ours, ref, block=8):
    """Per-channel means and their relative difference, and the relative RMSE of the means
    of block x block tiles (over tiles and channels, divided by the reference's mean)."""
    h, w = (ref.shape[0] // block) * block, (ref.shape[1] // block) * block
    tiles = lambda im: im[:h, :w].reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))
    a, b = tiles(ours.astype(np.float64)), tiles(ref.astype(np.float64))
    mean_ours, mean_ref = ours.reshape(-1, 3).mean(axis=0), ref.reshape(-1, 3).mean(axis=0)
    return {
        "mean_ours": mean_ours.tolist(),
        "mean_ref": mean_ref.tolist(),
        "mean_rel_diff": ((mean_ours - mean_ref) / mean_ref).tolist(),
        "block_rel_rmse": float(np.sqrt(((a - b) ** 2).mean()) / b.mean()),
        "non_finite_ours": int((~np.isfinite(ours)).sum()),
    }


# ---- check: both renders, one table row ------------------------------------------------------


def overrides_manifest(scene_dir, opts):
    effects = []
    if opts.diffuse:
        effects += ["glossy = false", "mirror = false"]
    if opts.opaque:
        effects += ["alpha_masks = false"]
    lines = [f'name = "{os.path.basename(os.path.normpath(scene_dir))}-reference"', f"mesh = {json.dumps(os.path.abspath(scene_dir))}"]
    if opts.skip_glass:
        lines.append('glass = "skip"')
    if effects:
        lines += ["", "[effects]"] + effects
    return "\n".join(lines) + "\n"


def check(args):
    width, height = (int(x) for x in args.res.lower().split("x"))
    work = args.work or tempfile.mkdtemp(prefix="mitsuba-ref-")
    os.makedirs(work, exist_ok=True)
    if os.path.isdir(args.scene):
        folder, ours_spec = args.scene, args.ours or args.scene
        if args.diffuse or args.opaque or args.skip_glass:
            ours_spec = os.path.join(work, "scene.toml")
            with open(ours_spec, "w", encoding="utf-8") as f:
                f.write(overrides_manifest(folder, args))
    else:  # a built-in: Mitsuba gets its export, stereotrace the built-in itself
        folder, ours_spec = os.path.join(work, "export"), args.scene
        subprocess.run([args.stereotrace, "export-scene", args.scene, "--out", folder], check=True)
    run = [args.stereotrace, "render", "--scene", ours_spec, "--res", f"{width}x{height}", "--spp", str(args.spp)]
    run += ["--frames", "1", "--eye", "left", "--eye-separation", "0", "--bounces", str(args.bounces)]
    run += ["--out", os.path.join(work, "ours")]
    printed = subprocess.run(run, check=True, capture_output=True, text=True).stdout
    ours_seconds = float(re.search(r" in ([0-9.]+) s ", printed).group(1))
    produced = [os.path.join(r, f) for r, _, fs in os.walk(os.path.join(work, "ours")) for f in fs if f == "left_000.exr"]
    if len(produced) != 1:
        sys.exit(f"expected one left_000.exr from stereotrace, found {produced}")
    ours = read_exr(produced[0])
    ref, ref_seconds = render(folder, width, height, args.spp, args.bounces, args, os.path.join(work, "mitsuba.exr"))
    result = compare(ours, ref)
    result.update(scene=args.label or args.scene, res=f"{width}x{height}", spp=args.spp, bounces=args.bounces)
    # Render time only (scene loading and BVH builds excluded on both sides), both on all cores.
    samples = width * height * args.spp
    result.update(ours_seconds=ours_seconds, mitsuba_seconds=ref_seconds)
    result.update(ours_msamples_per_s=samples / ours_seconds / 1e6, mitsuba_msamples_per_s=samples / ref_seconds / 1e6)
    worst_mean = max(abs(d) for d in result["mean_rel_diff"])
    result["pass"] = worst_mean <= args.mean_tol and result["block_rel_rmse"] <= args.block_tol and not result["non_finite_ours"]
    print(json.dumps(result))
    return 0 if result["pass"] else 1


# The comparison recorded in RESULTS.md: (label, scene, resolution, spp, bounces, overrides).
TABLE = [
    ("cornell-box", "cornell-box", "256x256", 1024, 1, []),
    ("cornell-box (direct only)", "cornell-box", "256x256", 1024, 0, []),
    ("sponza (diffuse)", "sponza", "320x180", 512, 1, ["diffuse", "opaque", "skip_glass"]),
    ("living-room (diffuse)", "living-room", "320x180", 512, 1, ["diffuse", "opaque", "skip_glass"]),
    ("cornell (built-in)", "@cornell", "256x256", 1024, 1, []),
    ("atrium (built-in)", "@atrium", "320x180", 512, 1, []),
]


def table(args):
    """Runs every case of TABLE, each `check` in its own process (Mitsuba's scalar thread pool
    hung on the second render of one process here), and prints one Markdown row per case."""
    rows, failed = [], 0
    for label, scene, res, spp, bounces, flags in TABLE:
        spec = scene[1:] if scene.startswith("@") else os.path.join(args.shared, scene)
        cmd = [sys.executable, os.path.abspath(__file__), "check", spec, "--stereotrace", args.stereotrace]
        cmd += ["--res", res, "--spp", str(spp), "--bounces", str(bounces), "--label", label]
        cmd += ["--work", os.path.join(args.work, label.split()[0] + ("-direct" if bounces == 0 else ""))]
        cmd += ["--" + f.replace("_", "-") for f in flags]
        print(f"{label} ...", file=sys.stderr)
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode not in (0, 1):
            sys.exit(f"{label}: check failed\n{done.stdout}\n{done.stderr}")
        failed += done.returncode
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
    print("| scene | image | spp | bounces | mean R / G / B (ours vs Mitsuba) | 8x8-block rel. RMSE | ours Msamples/s | Mitsuba Msamples/s | ratio |")
    print("|---|---|---:|---:|---|---:|---:|---:|---:|")
    for r in rows:
        diffs = " / ".join(f"{d * 100:+.2f} %" for d in r["mean_rel_diff"])
        ratio = r["ours_msamples_per_s"] / r["mitsuba_msamples_per_s"]
        print(
            f"| {r['scene']} | {r['res']} | {r['spp']} | {r['bounces']} | {diffs} | {r['block_rel_rmse'] * 100:.2f} % "
            f"| {r['ours_msamples_per_s']:.2f} | {r['mitsuba_msamples_per_s']:.2f} | {ratio:.2f} |"
        )
    return 1 if failed else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    for name in ("render", "check"):
        p = sub.add_parser(name)
        p.add_argument("scene" if name == "check" else "folder")
        p.add_argument("--res", default="128x128")
        p.add_argument("--spp", type=int, default=256)
        p.add_argument("--bounces", type=int, choices=(0, 1), default=1)
        p.add_argument("--diffuse", action="store_true", help="glossy and mirror materials become diffuse")
        p.add_argument("--opaque", action="store_true", help="alpha masks are ignored")
        p.add_argument("--skip-glass", action="store_true", help="glass triangles are dropped")
        if name == "render":
            p.add_argument("--out", required=True)
        else:
            p.add_argument("--stereotrace", required=True, help="the stereotrace binary")
            p.add_argument("--work", help="folder for intermediate files (default: a new temporary one)")
            p.add_argument("--label", help="scene name in the output row")
            p.add_argument(
                "--ours",
                help="what stereotrace renders instead of SCENE (a folder): the same scene in another form, "
                "for example converted to glTF; Mitsuba still reads SCENE's OBJ",
            )
            p.add_argument("--mean-tol", type=float, default=0.02)
            p.add_argument("--block-tol", type=float, default=0.05)
    p = sub.add_parser("table", help="the RESULTS.md comparison: every case of TABLE, one Markdown row each")
    p.add_argument("--stereotrace", required=True)
    p.add_argument("--shared", default=os.path.join(os.path.dirname(__file__), "../../../shared/scenes"))
    p.add_argument("--work", default=tempfile.mkdtemp(prefix="mitsuba-table-"))
    p = sub.add_parser("compare")
    p.add_argument("ours")
    p.add_argument("ref")
    args = parser.parse_args()
    try:
        if args.command == "render":
            width, height = (int(x) for x in args.res.lower().split("x"))
            render(args.folder, width, height, args.spp, args.bounces, args, args.out)
            return 0
        if args.command == "table":
            return table(args)
        if args.command == "compare":
            print(json.dumps(compare(read_exr(args.ours), read_exr(args.ref))))
            return 0
        return check(args)
    except Unsupported as e:
        print(f"unsupported: {e}", file=sys.stderr)
        return UNSUPPORTED


if __name__ == "__main__":
    sys.exit(main())
