#!/usr/bin/env python3
"""The Mitsuba 3 twin of res/scenes/envmap-mitsuba.toml: a diffuse, a rough
conductor and a mirror sphere on a diffuse ground, lit only by the Royal
Esplanade HDR map (Mitsuba's `envmap` emitter, rotated 60 degrees about +y).
Run with the Mitsuba peer's venv (../shared/peers/mitsuba/requirements.txt).

  envmap.py meshes                     write res/meshes/envmap-mitsuba/*.ply (ASCII, vertex normals)
  envmap.py render --spp N --seed S --out STEM [--variant V]
                                       Mitsuba's render: STEM.exr, STEM.png, STEM.json (s/spp)
  envmap.py rmse REF.exr TEST.exr...   RMSE of each TEST against REF (linear radiance), JSON
  envmap.py average OUT.exr IN.exr...  the mean of equal-spp renders

Both renderers load the same PLY files; the scene below restates the TOML.
Glass is left out on purpose: the sun's caustic through it onto the ground
is a light-specular-diffuse path that neither unidirectional tracer converges.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
MESHES = os.path.join(ROOT, "res", "meshes", "envmap-mitsuba")
MAP = os.path.join(ROOT, "res", "envmaps", "royal_esplanade_1k.hdr")

# Must match res/scenes/envmap-mitsuba.toml.
WIDTH, HEIGHT, FOV_Y = 320, 240, 35.0
CENTER, RADIUS, THETA_DEG, PHI_DEG = (0.0, 0.5, 0.0), 4.5, 15.0, 90.0
ROTATION_DEG = 60.0
MAX_DEPTH = 8
SPHERES = {
    # name: (centre, radius)
    "diffuse": ((-0.75, 0.6, 0.0), 0.6),
    "rough": ((0.75, 0.6, 0.0), 0.6),
    "mirror": ((0.0, 0.35, 1.1), 0.35),
}
MATERIALS = {
    "ground": {"type": "diffuse", "reflectance": [0.5, 0.5, 0.5]},
    "diffuse": {"type": "diffuse", "reflectance": [0.7, 0.25, 0.2]},
    "rough": {"type": "roughconductor", "reflectance": [0.95, 0.75, 0.4], "alpha": 0.25},
    "mirror": {"type": "conductor", "reflectance": [0.9, 0.9, 0.9]},
}
GROUND_HALF = 6.0


def f32(x):
    return "%.9g" % float(np.float32(x))


def write_ply(path, verts, normals, faces, comment):
    with open(path, "w", newline="\n") as f:
        f.write("ply\nformat ascii 1.0\ncomment %s\n" % comment)
        f.write("element vertex %d\n" % len(verts))
        for p in ("x", "y", "z", "nx", "ny", "nz"):
            f.write("property float %s\n" % p)
        f.write("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(faces))
        for v, n in zip(verts, normals):
            f.write(" ".join(f32(c) for c in (*v, *n)) + "\n")
        for t in faces:
            f.write("3 %d %d %d\n" % tuple(t))


def uv_sphere(center, radius, n_lat=32, n_lon=64):
    """Rings of latitude between two pole vertices; outward, counter-clockwise."""
    verts, normals = [], []
    normals.append((0.0, 1.0, 0.0))
    for i in range(1, n_lat):
        t = math.pi * i / n_lat
        for j in range(n_lon):
            p = 2 * math.pi * j / n_lon
            normals.append((math.sin(t) * math.cos(p), math.cos(t), math.sin(t) * math.sin(p)))
    normals.append((0.0, -1.0, 0.0))
    normals = np.array(normals)
    verts = np.asarray(center) + radius * normals
    ring = lambda i, j: 1 + (i - 1) * n_lon + (j % n_lon)
    bottom = len(normals) - 1
    faces = []
    for j in range(n_lon):
        faces.append((0, ring(1, j + 1), ring(1, j)))
        faces.append((bottom, ring(n_lat - 1, j), ring(n_lat - 1, j + 1)))
    for i in range(1, n_lat - 1):
        for j in range(n_lon):
            a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1)
            faces += [(a, b, d), (a, d, c)]
    faces = np.array(faces)
    tri = verts[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.einsum("ij,ij->i", fn, tri.mean(1) - np.asarray(center)) > 0)
    return verts, normals, faces


def meshes():
    os.makedirs(MESHES, exist_ok=True)
    h = GROUND_HALF
    g = np.array([(-h, 0, -h), (-h, 0, h), (h, 0, h), (h, 0, -h)], dtype=np.float64)
    write_ply(os.path.join(MESHES, "ground.ply"), g, np.tile((0.0, 1.0, 0.0), (4, 1)),
              np.array([(0, 1, 2), (0, 2, 3)]), "xtask/mitsuba/envmap.py: ground square, +y up")
    for name, (c, r) in SPHERES.items():
        v, n, f = uv_sphere(c, r)
        write_ply(os.path.join(MESHES, name + ".ply"), v, n, f,
                  "xtask/mitsuba/envmap.py: UV sphere, centre %s radius %s" % (c, r))


def camera_origin():
    t, p = math.radians(THETA_DEG), math.radians(PHI_DEG)
    return [CENTER[0] + RADIUS * math.cos(t) * math.cos(p), CENTER[1] + RADIUS * math.sin(t),
            CENTER[2] + RADIUS * math.cos(t) * math.sin(p)]


def scene_dict(mi):
    def bsdf(m):
        rgb = {"type": "rgb", "value": m["reflectance"]}
        if m["type"] == "diffuse":
            inner = {"type": "diffuse", "reflectance": rgb}
        elif m["type"] == "conductor":
            inner = {"type": "conductor", "material": "none", "specular_reflectance": rgb}
        else:
            inner = {"type": "roughconductor", "material": "none", "distribution": "ggx",
                     "alpha": m["alpha"], "specular_reflectance": rgb}
        return {"type": "twosided", "material": inner}

    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH, "rr_depth": 5},
        "sensor": {
            "type": "perspective", "fov": FOV_Y, "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=camera_origin(), target=list(CENTER),
                                                       up=[0, 1, 0]),
            "sampler": {"type": "independent"},
            "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
        "sky": {"type": "envmap", "filename": MAP, "scale": 1.0,
                "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], ROTATION_DEG)},
    }
    for name in ["ground", *SPHERES]:
        d["obj_" + name] = {"type": "ply", "filename": os.path.join(MESHES, name + ".ply"),
                            "face_normals": False, "bsdf": bsdf(MATERIALS[name])}
    return d


def render(a):
    import mitsuba as mi
    mi.set_variant(a.variant)
    mi.set_log_level(mi.LogLevel.Error)
    scene = mi.load_dict(scene_dict(mi))
    np.array(mi.render(scene, spp=1, seed=10**6))  # warm-up (LLVM compiles kernels)
    acc = np.zeros((HEIGHT, WIDTH, 3))
    done, k, t0 = 0, 0, time.perf_counter()
    while done < a.spp:
        n = min(64, a.spp - done)
        acc += np.array(mi.render(scene, spp=n, seed=a.seed * 100003 + k), dtype=np.float64) * n
        done, k = done + n, k + 1
    secs = time.perf_counter() - t0
    img = np.ascontiguousarray(acc / a.spp, dtype=np.float32)
    bmp = mi.Bitmap(img, mi.Bitmap.PixelFormat.RGB)
    bmp.write(a.out + ".exr")
    bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(a.out + ".png")
    info = {"variant": a.variant, "spp": a.spp, "seed": a.seed, "render_s": round(secs, 3),
            "s_per_spp": round(secs / a.spp, 5)}
    json.dump(info, open(a.out + ".json", "w"))
    print(json.dumps(info))


def load(path):
    import mitsuba as mi
    if not mi.variant():
        mi.set_variant("scalar_rgb")
    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("meshes")
    r = sub.add_parser("render")
    r.add_argument("--spp", type=int, required=True)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--out", required=True)
    r.add_argument("--variant", default="scalar_rgb")
    c = sub.add_parser("rmse")
    c.add_argument("ref")
    c.add_argument("tests", nargs="+")
    v = sub.add_parser("average")
    v.add_argument("out")
    v.add_argument("inputs", nargs="+")
    a = ap.parse_args()
    if a.cmd == "meshes":
        meshes()
    elif a.cmd == "render":
        render(a)
    elif a.cmd == "rmse":
        ref = load(a.ref)
        for t in a.tests:
            img = load(t)
            print(json.dumps({"test": t, "rmse": float(np.sqrt(np.mean((img - ref) ** 2))),
                              "mean": [round(float(x), 5) for x in img.reshape(-1, 3).mean(0)],
                              "ref_mean": [round(float(x), 5) for x in ref.reshape(-1, 3).mean(0)]}))
    elif a.cmd == "average":
        import mitsuba as mi
        img = np.mean([load(p) for p in a.inputs], axis=0).astype(np.float32)
        mi.Bitmap(np.ascontiguousarray(img), mi.Bitmap.PixelFormat.RGB).write(a.out)


if __name__ == "__main__":
    sys.exit(main())
