#!/usr/bin/env python3
"""The heavy scene (res/scenes/heavy.toml) for both renderers: 16 instanced
Stanford dragons and 8 bunnies (2.16 M triangles) on a ground plane under a
one-sided area light, all diffuse.

  heavy.py meshes                   write res/meshes/heavy/*.ply from ../shared/assets
  heavy.py render --spp N --seed S --out STEM [--variant llvm_ad_rgb]
                                    Mitsuba's render of res/scenes/heavy.toml: the scene is
                                    read from Lucent's TOML (objects, transforms, materials,
                                    camera, depth, size), so the two cannot drift apart;
                                    prints one JSON line with render_s (after a 1-spp warm-up)

Run with the Mitsuba peer's venv (numpy, mitsuba). The derived meshes are
binary little-endian PLY with vertex normals, so both renderers shade with
the same normals: the dragon without the ground quad its file carries (the
last 4 vertices and 2 faces), the bunny with area-weighted normals computed
here (its file has none).
"""
import argparse
import json
import math
import os
import sys
import time
import tomllib

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
ASSETS = os.path.abspath(os.path.join(ROOT, "..", "shared", "assets"))
SCENE = os.path.join(ROOT, "res", "scenes", "heavy.toml")
MESHES = os.path.join(ROOT, "res", "meshes", "heavy")


def read_header(f):
    lines = []
    while True:
        line = f.readline().decode("ascii").strip()
        lines.append(line)
        if line == "end_header":
            return lines


def read_dragon(path):
    """The VCG dragon: float x y z nx ny nz, int flags; faces uchar n, int[3], int flags."""
    with open(path, "rb") as f:
        head = read_header(f)
        nv = int(next(l for l in head if l.startswith("element vertex")).split()[2])
        nf = int(next(l for l in head if l.startswith("element face")).split()[2])
        v = np.frombuffer(f.read(nv * 28), dtype=np.dtype([("p", "<f4", 6), ("flags", "<i4")]))
        fc = np.frombuffer(f.read(nf * 17), dtype=np.dtype([("n", "u1"), ("i", "<i4", 3), ("flags", "<i4")]))
    assert (fc["n"] == 3).all()
    return v["p"][:, :3].astype(np.float32), v["p"][:, 3:].astype(np.float32), fc["i"].astype(np.int32)


def read_bunny(path):
    with open(path, "rb") as f:
        head = read_header(f)
        nv = int(next(l for l in head if l.startswith("element vertex")).split()[2])
        nf = int(next(l for l in head if l.startswith("element face")).split()[2])
        rest = f.read().decode("ascii").split("\n")
    pos = np.array([[float(x) for x in l.split()[:3]] for l in rest[:nv]], dtype=np.float32)
    faces = np.array([[int(x) for x in l.split()[1:4]] for l in rest[nv:nv + nf]], dtype=np.int32)
    return pos, faces


def area_normals(pos, faces):
    p = pos.astype(np.float64)
    fn = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    n = np.zeros_like(p)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0, n / np.maximum(length, 1e-300), [0.0, 1.0, 0.0])
    return n.astype(np.float32)


def write_ply(path, pos, normals, faces, comments):
    head = ["ply", "format binary_little_endian 1.0"] + ["comment " + c for c in comments]
    head += ["element vertex %d" % len(pos), "property float x", "property float y", "property float z"]
    if normals is not None:
        head += ["property float nx", "property float ny", "property float nz"]
    head += ["element face %d" % len(faces), "property list uchar int vertex_indices", "end_header"]
    verts = pos if normals is None else np.concatenate([pos, normals], axis=1)
    fdt = np.dtype([("n", "u1"), ("i", "<i4", 3)])
    f = np.zeros(len(faces), dtype=fdt)
    f["n"] = 3
    f["i"] = faces
    with open(path, "wb") as out:
        out.write(("\n".join(head) + "\n").encode("ascii"))
        out.write(np.ascontiguousarray(verts, dtype="<f4").tobytes())
        out.write(f.tobytes())


def meshes():
    os.makedirs(MESHES, exist_ok=True)
    pos, nrm, faces = read_dragon(os.path.join(ASSETS, "stanford-dragon-100k", "dragon.ply"))
    # Drop the ground quad (vertices 50000..50003, the last 2 faces).
    keep = (faces < 50000).all(axis=1)
    assert keep.sum() == len(faces) - 2
    write_ply(os.path.join(MESHES, "dragon.ply"), pos[:50000], nrm[:50000], faces[keep],
              ["derived by xtask/mitsuba/heavy.py from shared/assets/stanford-dragon-100k/dragon.ply:",
               "its ground quad (last 4 vertices, 2 faces) and flags dropped, normals kept"])
    pos, faces = read_bunny(os.path.join(ASSETS, "stanford-bunny", "bun_zipper.ply"))
    write_ply(os.path.join(MESHES, "bunny.ply"), pos, area_normals(pos, faces), faces,
              ["derived by xtask/mitsuba/heavy.py from shared/assets/stanford-bunny/bun_zipper.ply:",
               "positions and faces kept, area-weighted vertex normals added"])
    g = 6.0
    ground = np.array([[-g, 0, -g], [g, 0, -g], [g, 0, g], [-g, 0, g]], dtype=np.float32)
    quad = np.array([[0, 2, 1], [0, 3, 2]], dtype=np.int32)  # normal +y
    write_ply(os.path.join(MESHES, "ground.ply"), ground, None, quad, ["heavy scene: ground, y = 0"])
    s, y = 1.5, 6.0
    light = np.array([[-s, y, -s], [s, y, -s], [s, y, s], [-s, y, s]], dtype=np.float32)
    write_ply(os.path.join(MESHES, "light.ply"), light, None, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32),
              ["heavy scene: area light, emits down (-y, the counter-clockwise normal)"])
    print("wrote", MESHES)


def to_world(mi, o):
    t = o.get("translate", [0.0, 0.0, 0.0])
    r = o.get("rotate_deg", [0.0, 0.0, 0.0])
    s = o.get("scale", 1.0)
    s = [s, s, s] if isinstance(s, (int, float)) else s
    # Lucent: translate * rotate (about x, then y, then z, fixed axes) * scale.
    m = mi.ScalarTransform4f().translate(t)
    m = m @ mi.ScalarTransform4f().rotate([0, 0, 1], r[2])
    m = m @ mi.ScalarTransform4f().rotate([0, 1, 0], r[1])
    m = m @ mi.ScalarTransform4f().rotate([1, 0, 0], r[0])
    return m @ mi.ScalarTransform4f().scale(s)


def rgb(x):
    return [float(x)] * 3 if isinstance(x, (int, float)) else [float(c) for c in x]


def mitsuba_dict(mi, scene):
    cam, rs = scene["camera"], scene["render"]
    th, ph, rad = math.radians(cam["theta_deg"]), math.radians(cam["phi_deg"]), cam["radius"]
    c = cam["center"]
    origin = [rad * math.cos(th) * math.cos(ph) + c[0], rad * math.sin(th) + c[1],
              rad * math.cos(th) * math.sin(ph) + c[2]]
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": rs["max_depth"], "rr_depth": 5, "hide_emitters": False},
        "sensor": {
            "type": "perspective", "fov": cam["fov_y_deg"], "fov_axis": "y", "near_clip": 0.01,
            "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=c, up=[0, 1, 0]),
            "sampler": {"type": "independent"},
            "film": {"type": "hdrfilm", "width": rs["width"], "height": rs["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
    }
    for name, m in scene["materials"].items():
        if "emission" in m:
            continue
        d["mat_" + name] = {"type": "twosided",
                            "material": {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb(m["kd"])}}}
    scene_dir = os.path.dirname(SCENE)
    groups = {}
    for i, o in enumerate(scene["objects"]):
        m = scene["materials"][o["material"]]
        path = os.path.normpath(os.path.join(scene_dir, o["mesh"]))
        shape = {"type": "ply", "filename": path, "face_normals": False}
        if "emission" in m:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": rgb(m["emission"])}}
            shape["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}
        else:
            shape["bsdf"] = {"type": "ref", "id": "mat_" + o["material"]}
        if not o.get("instance", False):
            shape["to_world"] = to_world(mi, o)
            d["obj_%d" % i] = shape
            continue
        key = (path, o["material"])
        if key not in groups:
            groups[key] = "grp_%d" % len(groups)
            d[groups[key]] = {"type": "shapegroup", "shape": shape}
        d["inst_%d" % i] = {"type": "instance", "shapegroup": {"type": "ref", "id": groups[key]},
                            "to_world": to_world(mi, o)}
    return d


def render(a):
    import mitsuba as mi
    mi.set_variant(a.variant)
    with open(SCENE, "rb") as f:
        scene = tomllib.load(f)
    # Lucent's TOML has no `instance` key: every object that shares its mesh
    # file with another is an instance of one shape group here.
    count = {}
    for o in scene["objects"]:
        count[o["mesh"]] = count.get(o["mesh"], 0) + 1
    for o in scene["objects"]:
        o["instance"] = count[o["mesh"]] > 1
    t0 = time.perf_counter()
    s = mi.load_dict(mitsuba_dict(mi, scene))
    t_load = time.perf_counter() - t0
    np.array(mi.render(s, spp=1, seed=10**6))  # warm-up (LLVM kernels)
    # Passes of at most 64 spp (one wavefront holds every sample of a
    # pass), each with its own seed, averaged; as cornell.py renders.
    t0 = time.perf_counter()
    acc, done, k = 0.0, 0, 0
    while done < a.spp:
        n = min(64, a.spp - done)
        acc = acc + np.array(mi.render(s, spp=n, seed=a.seed * 1000 + k), dtype=np.float64) * n
        done, k = done + n, k + 1
    img = (acc / a.spp).astype(np.float32)
    t_render = time.perf_counter() - t0
    bmp = mi.Bitmap(np.ascontiguousarray(img), mi.Bitmap.PixelFormat.RGB)
    bmp.write(a.out + ".exr")
    bmp.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(a.out + ".png")
    print(json.dumps({"variant": a.variant, "spp": a.spp, "load_s": round(t_load, 3),
                      "render_s": round(t_render, 3), "s_per_spp": round(t_render / a.spp, 4),
                      "mean_radiance": [round(float(x), 5) for x in img.reshape(-1, 3).mean(0)]}))


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("meshes")
    r = sub.add_parser("render")
    r.add_argument("--spp", type=int, default=16)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--variant", default="llvm_ad_rgb")
    r.add_argument("--out", required=True)
    a = p.parse_args()
    meshes() if a.cmd == "meshes" else render(a)


if __name__ == "__main__":
    sys.exit(main())
