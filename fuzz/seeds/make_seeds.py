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


if __name__ == "__main__":
    main()
