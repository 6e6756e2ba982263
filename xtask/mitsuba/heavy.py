#!/usr/bin/env python3
"""The heavy scene (res/scenes/heavy.toml) for both renderers: 16 instanced
Stanford dragons and 8 bunnies (2.16 M triangles) on a ground plane under a
one-sided area light, all diffuse.

  heavy.py meshes                   write res/meshes/heavy/*.ply from ../shared/assets
  heavy.py render --spp N --seed S --out STEM [--variant llvm_ad_rgb]
                                    Mitsuba's render of res/scenes/heavy.toml: twin.py reads
                                    Lucent's TOML (objects, transforms, materials, camera,
                                    depth, size), so the two cannot drift apart (every object
                                    sharing its mesh file with another is an instance of one
                                    shape group); prints one JSON line with render_s (after a
                                    1-spp warm-up)

Run with the Mitsuba peer's venv (numpy, mitsuba). The derived meshes are
binary little-endian PLY with vertex normals, so both renderers shade with
the same normals: the dragon without the ground quad its file carries (the
last 4 vertices and 2 faces), the bunny with area-weighted normals computed
here (its file has none).
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import twin  # noqa: E402

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


def main():
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("meshes")
    r = sub.add_parser("render")
    twin.add_render_args(r)
    a = p.parse_args()
    if a.cmd == "meshes":
        meshes()
    else:
        twin.render(SCENE, a.spp, a.seed, a.out, a.variant)


if __name__ == "__main__":
    sys.exit(main())
