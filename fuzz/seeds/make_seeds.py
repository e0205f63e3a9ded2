#!/usr/bin/env python3
"""Writes the hand-made seeds of the fuzz targets added for hardening into fuzz/corpus/<target>/.

Run from the repository root: python3 fuzz/seeds/make_seeds.py (needs Pillow for the PNG and
JPEG seeds: pip install pillow). The EXR seeds start from two tiny renders committed beside
this script (render_4x3.exr, render_1x1.exr: `stereotrace render --scene cornell --frames 1
--spp 1 --res 4x3`), one of them patched to claim 65536x65536 pixels. Seeds are named by
content hash, as libFuzzer names its own, so rerunning the script adds nothing twice.
"""
import hashlib
import io
import os
import random
import struct
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
SEP = b"#@@\n"


def put(target, data):
    d = os.path.join(ROOT, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, hashlib.sha1(data).hexdigest()), "wb") as f:
        f.write(data)


def random_seeds(target, rng, count, lengths):
    for _ in range(count):
        put(target, bytes(rng.randrange(256) for _ in range(rng.choice(lengths))))


OBJ = b"""mtllib scene.mtl
v -1 0 -1
v 1 0 -1
v 1 0 1
v -1 0 1
v 0 1 0
vn 0 1 0
vt 0 0
vt 1 0
vt 1 1
usemtl white
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/3/1
usemtl lamp
f 1 2 5
"""
MTL = b"""newmtl white
Kd 0.8 0.8 0.8
newmtl lamp
Kd 0 0 0
Ke 4 4 4
newmtl glass
Kd 1 1 1
d 0.2
newmtl shiny
Ks 0.5 0.5 0.5
Ns 200
"""
CAMERA = b'{"eye": [0, 0.5, 3], "target": [0, 0.3, 0], "up": [0, 1, 0], "vfov_deg": 60, "meters_per_unit": 1.0}'
LIGHTS = [
    b'[{"type": "area", "material": "lamp", "radiance": [4, 4, 4]}]',
    b'[{"type": "constant", "radiance": [0.1, 0.2, 0.3]}]',
    b'[{"type": "point", "position": [0, 2, 0], "intensity": [5, 5, 5]}]',
    b'[{"type": "sun", "direction": [0.3, 1, 0.2], "irradiance": [3, 3, 3]}]',
    b'[{"type": "sky", "zenith": [0.2, 0.3, 0.8], "horizon": [0.8, 0.8, 0.9], "ground": [0.1, 0.1, 0.1]}]',
    b'[{"type": "sunsky", "sun_direction": [0.3, 0.8, 0.1]}]',
    b'[{"type": "envmap", "filename": null, "to_world": [[1,0,0],[0,1,0],[0,0,1]]}]',
    b'[]',
]

MANIFESTS = [
    b'mesh = "base"\nframes = 4\n',
    b'''name = "fuzz"
mesh = "base/scene.obj"
meters_per_unit = 1.0
frames = 3
glass = "skip"
folder_lights = false
[camera]
vfov_deg = 60.0
keys = [ { frame = 0, eye = [0, 1, 3], target = [0, 0, 0] }, { frame = 2, eye = [1, 1, 3], target = [0, 0, 0], up = [0, 1, 0] } ]
[[lights]]
type = "moving-sphere"
radius = 0.15
radiance = [30, 28, 25]
keys = [ { frame = 0, translation = [-1, 2, 0] }, { frame = 2, translation = [1, 2, 0], yaw_deg = 10 } ]
[materials.all]
kind = "glossy"
roughness = 0.3
specular = 0.5
[[materials.set]]
name = "whi*"
kind = "mirror"
[effects]
textures = false
[tolerances]
position = 0.1
depth_relative = 0.03
normal_degrees = 25.0
''',
    b'mesh = "base"\n[[lights]]\ntype = "point"\nposition = [0, 2, 0]\nintensity = [1e30, 0, 0]\n',
    b'mesh = "base"\n[[lights]]\ntype = "sun"\ndirection = [0, 1, 0]\nirradiance = [2, 2, 2]\n',
    b'mesh = "base"\n[[lights]]\ntype = "quad"\ncorner = [0, 2, 0]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]\nradiance = [5, 5, 5]\n',
    b'mesh = "base"\nframes = 0\n',
    b'mesh = "missing"\n',
    b'mesh = "base"\n[[lights]]\ntype = "moving-point"\nintensity = [3, 3, 3]\nkeys = [ { frame = 0, translation = [0, 2, 0] } ]\n',
]


def png_and_jpeg_seeds():
    try:
        from PIL import Image
    except ImportError:
        print("Pillow missing: PNG/JPEG seeds skipped (pip install pillow)", file=sys.stderr)
        return
    rng = random.Random(7)
    def img(mode, size):
        im = Image.new(mode, size)
        bands = len(im.getbands())
        im.putdata([tuple(rng.randrange(256) for _ in range(bands)) if bands > 1 else rng.randrange(256)
                    for _ in range(size[0] * size[1])])
        return im
    for mode, size in [("RGB", (4, 3)), ("RGBA", (3, 5)), ("L", (8, 1)), ("LA", (1, 8)), ("P", (5, 5))]:
        out = io.BytesIO()
        img(mode, size).save(out, format="PNG")
        put("image", b"\x01" + out.getvalue())
    out = io.BytesIO()
    img("I;16", (3, 3)).save(out, format="PNG")
    put("image", b"\x01" + out.getvalue())
    for mode, size, progressive in [("RGB", (8, 8), False), ("L", (9, 7), False), ("RGB", (16, 3), True)]:
        out = io.BytesIO()
        img(mode, size).save(out, format="JPEG", quality=50, progressive=progressive)
        put("image", b"\x02" + out.getvalue())


def exr_seeds():
    here = os.path.dirname(os.path.abspath(__file__))
    for name in ["render_4x3.exr", "render_1x1.exr"]:
        with open(os.path.join(here, name), "rb") as f:
            data = f.read()
        put("image", b"\x00" + data)
        if name == "render_4x3.exr":
            huge = bytearray(data)
            for attr in [b"dataWindow\0box2i\0", b"displayWindow\0box2i\0"]:
                at = huge.index(attr) + len(attr)
                huge[at + 12:at + 20] = struct.pack("<ii", 65535, 65535)
            put("image", b"\x00" + bytes(huge))


def cache_seeds(rng):
    def image(w, h, values):
        return struct.pack("<II", w, h) + b"".join(struct.pack("<f", v) for v in values)
    put("cache_entry", image(2, 1, [0.5, 1.0, float("nan"), 0.0, 1e30, -1.0]))
    put("cache_entry", image(1, 1, [1.0, 2.0, 3.0]))
    put("cache_entry", struct.pack("<II", 1, 2) + b"".join(struct.pack("<d", v) for v in range(6)))
    put("cache_entry", struct.pack("<II", 3, 1) + bytes([0, 1, 255]))
    put("cache_entry", struct.pack("<II", 0xFFFFFFFF, 0xFFFFFFFF))
    put("cache_entry", b"STEVCACH" + struct.pack("<I", 1) + struct.pack("<I", 4) + b"fuzz")
    random_seeds("cache_entry", rng, 4, [0, 7, 40, 200])


def gltf_document(bin_bytes, rest, glb=False):
    """A glTF document of one buffer around `rest`: JSON with a data URI, or a GLB."""
    import base64
    import json

    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": len(bin_bytes)}]}
    if not glb:
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bin_bytes).decode()
    doc.update(rest)
    text = json.dumps(doc, separators=(",", ":")).encode()
    if not glb:
        return text
    text += b" " * (-len(text) % 4)
    body = bin_bytes + b"\0" * (-len(bin_bytes) % 4)
    total = 12 + 8 + len(text) + 8 + len(body)
    return (b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(text)) + b"JSON" + text
            + struct.pack("<I", len(body)) + b"BIN\0" + body)


def gltf_seeds():
    """A lit quad: as JSON and GLB; with a camera, point/spot/directional lights and PBR
    materials; as a strip; with an alpha-masked PNG texture; with node transforms."""
    positions = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0)
    normals = struct.pack("<12f", *([0, 0, 1] * 4))
    uvs = struct.pack("<8f", 0, 1, 1, 1, 1, 0, 0, 0)
    indices = struct.pack("<6H", 0, 1, 2, 0, 2, 3) + b"\0\0"
    bin_bytes = positions + normals + uvs + indices
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 48},
             {"buffer": 0, "byteOffset": 96, "byteLength": 32}, {"buffer": 0, "byteOffset": 128, "byteLength": 12}]
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
        {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
    ]
    primitive = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 0}
    lamp = {"emissiveFactor": [1, 0.8, 0.6], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5}}}
    base = {"bufferViews": views, "accessors": accessors, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}], "meshes": [{"primitives": [primitive]}], "materials": [lamp]}
    put("gltf", gltf_document(bin_bytes, base))
    put("gltf", gltf_document(bin_bytes, base, glb=True))
    q = 0.70710677
    lit = dict(base)
    lit["nodes"] = [
        {"mesh": 0, "children": [1], "rotation": [-q, 0, 0, q], "scale": [-2, 2, 2]},
        {"mesh": 0, "translation": [0, 0, 0.5]},
        {"camera": 0, "translation": [0.5, 0.5, 3]},
        {"translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"translation": [1, 2, 0], "rotation": [-q, 0, 0, q], "extensions": {"KHR_lights_punctual": {"light": 1}}},
        {"rotation": [-q, 0, 0, q], "extensions": {"KHR_lights_punctual": {"light": 2}}},
    ]
    lit["scenes"] = [{"nodes": [0, 2, 3, 4, 5]}]
    lit["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}]
    lit["materials"] = [
        {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.7, 0.6, 1], "metallicFactor": 1, "roughnessFactor": 0.3},
         "extensions": {"KHR_materials_specular": {"specularFactor": 0.5}}},
    ]
    lit["extensionsUsed"] = ["KHR_lights_punctual", "KHR_materials_specular"]
    lit["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "point", "intensity": 10, "color": [1, 0.9, 0.8]},
        {"type": "spot", "intensity": 30, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}, "range": 9},
        {"type": "directional", "intensity": 2},
    ]}}
    put("gltf", gltf_document(bin_bytes, lit, glb=True))
    strip = dict(base)
    strip["meshes"] = [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 5, "material": 0}]}]
    put("gltf", gltf_document(bin_bytes, strip))
    # Refused files: a cycle, an index past the vertices, an unsupported required extension,
    # a truncated GLB.
    put("gltf", gltf_document(bin_bytes, dict(base, nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}])))
    far = [dict(a) for a in accessors]
    far[3]["count"] = 600
    put("gltf", gltf_document(bin_bytes, dict(base, accessors=far)))
    put("gltf", gltf_document(bin_bytes, dict(base, extensionsUsed=["KHR_draco_mesh_compression"],
                                             extensionsRequired=["KHR_draco_mesh_compression"])))
    put("gltf", gltf_document(bin_bytes, base, glb=True)[:300])
    try:
        from PIL import Image
    except ImportError:
        print("Pillow missing: the textured glTF seed is not written", file=sys.stderr)
        return
    png = io.BytesIO()
    Image.frombytes("RGBA", (2, 2), bytes([255, 0, 0, 255, 0, 255, 0, 40, 0, 0, 255, 200, 255, 255, 255, 0])).save(png, "PNG")
    import base64

    textured = dict(base)
    textured["materials"] = [lamp, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0},
                                    "alphaMode": "MASK", "alphaCutoff": 0.3}]
    textured["meshes"] = [{"primitives": [primitive, dict(primitive, material=1)]}]
    textured["textures"] = [{"source": 0}]
    textured["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()}]
    put("gltf", gltf_document(bin_bytes, textured))


def main():
    rng = random.Random(2026)
    random_seeds("ssim", rng, 12, [0, 8, 30, 120, 600])
    random_seeds("traverse", rng, 12, [3, 40, 200, 800])
    random_seeds("raster", rng, 12, [8, 60, 250, 900])
    for lights in LIGHTS:
        put("scene_folder", SEP.join([OBJ, MTL, CAMERA, lights]))
    put("scene_folder", SEP.join([b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", b"", CAMERA, b"[]"]))
    put("scene_folder", SEP.join([b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", b"", CAMERA, b"[]"]))
    put("scene_folder", SEP.join([OBJ, MTL, b'{"eye": [0,0,0], "target": [0,0,0], "vfov_deg": 1e-30}', b"[]"]))
    for m in MANIFESTS:
        put("manifest", m)
    png_and_jpeg_seeds()
    exr_seeds()
    cache_seeds(rng)
    gltf_seeds()
    # Added later, with its own stream so the seeds above stay as they were.
    random_seeds("gradient", random.Random(2030), 12, [0, 6, 40, 150, 700])
    random_seeds("variance_blend", random.Random(2031), 12, [0, 8, 40, 150, 700])
    random_seeds("atrous", random.Random(2032), 16, [0, 8, 40, 150, 700])
    random_seeds("clamp", random.Random(2033), 12, [0, 8, 40, 150, 700])


if __name__ == "__main__":
    main()
