#!/usr/bin/env python3
"""The seed scene path traced, for both renderers: res/scenes/seed-mitsuba.toml
is res/scenes/seed.toml (Spot the textured cow, the yellow Stanford bunny, a
translucent light-grey sphere and a reflective floor board under light from
straight above and a dim sky) with every material written in lobes that
Lucent's path tracer and Mitsuba 3 implement identically, and every mesh a
PLY file both load.

  seed.py meshes      write res/meshes/seed-mitsuba/{cow,sphere,board}.ply
  seed.py render --spp N --seed S --out STEM [--variant llvm_ad_rgb]
                      Mitsuba's render of res/scenes/seed-mitsuba.toml, read by
                      twin.py (so the two cannot drift apart): STEM.exr, STEM.png
                      and one JSON line with render_s (after a 1-spp warm-up)

Run with the Mitsuba peer's venv (numpy, mitsuba). The meshes are binary
little-endian PLY written exactly as Lucent loads the seed scene's
sources:

- cow.ply: res/meshes/spot/cow.obj as Lucent's OBJ loader reads it
  (lucent-assets obj.rs): one vertex per distinct (position, texture
  coordinate) corner in order of first use, triangles in file order, and
  the normals it computes for a file without any (no `vn`, no `s`): at each
  vertex the sum of its triangles' cross products weighted by their corner
  angles, normalised (TriMesh::compute_smooth_normals), in float32.
  Mitsuba's OBJ reader would weld and smooth differently.
- sphere.ply: Lucent's `shape = "sphere"` (lucent-geom shapes::icosphere,
  the same subdivision order, float32, normals = positions) at
  SPHERE_SUBDIVISIONS, without its unused UVs.
- board.ply: Lucent's `shape = "cube"` (shapes::cuboid: 24 vertices, flat
  normals), without UVs.

The bunny is res/meshes/heavy/bunny.ply (heavy.py: the Stanford bunny with
area-weighted vertex normals).
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import twin  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCENE = os.path.join(ROOT, "res", "scenes", "seed-mitsuba.toml")
MESHES = os.path.join(ROOT, "res", "meshes", "seed-mitsuba")
COW = os.path.join(ROOT, "res", "meshes", "spot", "cow.obj")
# seed.toml's sphere has 5 (20480 triangles, a 512 kB file); 4 (5120) keeps
# the committed file at 128 kB and shades the same at the seed's size.
SPHERE_SUBDIVISIONS = 4


def write_ply(path, pos, normals, uvs, faces, comments):
    head = ["ply", "format binary_little_endian 1.0"] + ["comment " + c for c in comments]
    head += ["element vertex %d" % len(pos)] + ["property float %s" % p for p in "xyz"]
    cols = [pos, normals]
    head += ["property float %s" % p for p in ("nx", "ny", "nz")]
    if uvs is not None:
        head += ["property float u", "property float v"]
        cols.append(uvs)
    head += ["element face %d" % len(faces), "property list uchar int vertex_indices", "end_header"]
    verts = np.concatenate([np.asarray(c, dtype="<f4") for c in cols], axis=1)
    f = np.zeros(len(faces), dtype=np.dtype([("n", "u1"), ("i", "<i4", 3)]))
    f["n"] = 3
    f["i"] = faces
    with open(path, "wb") as out:
        out.write(("\n".join(head) + "\n").encode("ascii"))
        out.write(np.ascontiguousarray(verts).tobytes())
        out.write(f.tobytes())


def read_cow(path):
    """Positions, UVs and triangles as Lucent's OBJ loader unifies them."""
    pos, uv, key_of, out_pos, out_uv, tris = [], [], {}, [], [], []
    with open(path) as f:
        for line in f:
            w = line.split("#", 1)[0].split()
            if not w:
                continue
            if w[0] == "v":
                pos.append([np.float32(x) for x in w[1:4]])
            elif w[0] == "vt":
                uv.append([np.float32(x) for x in w[1:3]])
            elif w[0] == "f":
                poly = []
                for corner in w[1:]:
                    parts = corner.split("/")
                    if len(parts) != 2:
                        sys.exit("%s: expected v/vt corners, got '%s'" % (path, corner))
                    v, t = int(parts[0]) - 1, int(parts[1]) - 1
                    if (v, t) not in key_of:
                        key_of[(v, t)] = len(out_pos)
                        out_pos.append(pos[v])
                        out_uv.append(uv[t])
                    poly.append(key_of[(v, t)])
                tris += [[poly[0], a, b] for a, b in zip(poly[1:], poly[2:])]
            elif w[0] in ("vn", "s"):
                sys.exit("%s: has %s lines; this copy assumes none" % (path, w[0]))
    return np.array(out_pos, dtype=np.float32), np.array(out_uv, dtype=np.float32), np.array(tris)


def smooth_normals(pos, tris):
    """TriMesh::compute_smooth_normals, in float32 like Lucent."""
    p = pos[tris]  # (n, 3 corners, xyz)
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]).astype(np.float32)
    ok = np.isfinite(cross).all(1) & (cross != 0).any(1)
    acc = np.zeros_like(pos)

    def unit(v):
        n = np.linalg.norm(v, axis=1, keepdims=True).astype(np.float32)
        return np.where(n > 0, v / np.where(n > 0, n, 1), 0).astype(np.float32)

    for corner in range(3):
        e1 = unit(p[:, (corner + 1) % 3] - p[:, corner])
        e2 = unit(p[:, (corner + 2) % 3] - p[:, corner])
        angle = np.arccos(np.clip(np.einsum("ij,ij->i", e1, e2), -1, 1)).astype(np.float32)
        w = np.where(ok & np.isfinite(angle), angle, 0)[:, None] * cross
        np.add.at(acc, tris[ok, corner], w[ok])
    return unit(acc)


def icosphere(subdivisions):
    """lucent-geom's shapes::icosphere, step for step, in float32."""
    t = np.float32((1.0 + np.sqrt(np.float32(5.0))) / 2.0)
    base = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
            [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]

    def normalize(v):
        # glam's Vec3::normalize: v * (1 / sqrt(x x + y y + z z)), in order.
        x, y, z = (np.float32(c) for c in v)
        length = np.sqrt(x * x + y * y + z * z)
        return np.array([x, y, z], dtype=np.float32) * (np.float32(1.0) / length)

    pos = [normalize(p) for p in base]
    faces = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
             [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
             [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(subdivisions):
        mid = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                pos.append(normalize(pos[a] + pos[b]))
                mid[key] = len(pos) - 1
            return mid[key]

        nxt = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            nxt += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = nxt
    pos = np.array(pos, dtype=np.float32)
    return pos, pos.copy(), np.array(faces)


def cuboid():
    """lucent-geom's shapes::cuboid: the unit cube, flat normals."""
    axes = np.eye(3, dtype=np.float32)
    pos, nrm, faces = [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = axes[axis] * np.float32(sign)
            t1 = axes[(axis + 1) % 3] * np.float32(sign)
            t2 = np.cross(n, t1)
            b = len(pos)
            for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                pos.append(0.5 * n + (du - 0.5) * t1 + (dv - 0.5) * t2)
                nrm.append(n)
            faces += [[b, b + 1, b + 2], [b, b + 2, b + 3]]
    return np.array(pos, dtype=np.float32), np.array(nrm, dtype=np.float32), np.array(faces)


def meshes():
    os.makedirs(MESHES, exist_ok=True)
    pos, uv, tris = read_cow(COW)
    write_ply(os.path.join(MESHES, "cow.ply"), pos, smooth_normals(pos, tris), uv, tris,
              ["res/meshes/spot/cow.obj (Keenan Crane's Spot) as Lucent's OBJ loader reads it:",
               "corners unified per (v, vt), angle-weighted smooth normals; by xtask/mitsuba/seed.py"])
    pos, nrm, faces = icosphere(SPHERE_SUBDIVISIONS)
    write_ply(os.path.join(MESHES, "sphere.ply"), pos, nrm, None, faces,
              ["Lucent's shape \"sphere\": icosphere, %d subdivisions, unit radius;" % SPHERE_SUBDIVISIONS,
               "by xtask/mitsuba/seed.py"])
    pos, nrm, faces = cuboid()
    write_ply(os.path.join(MESHES, "board.ply"), pos, nrm, None, faces,
              ["Lucent's shape \"cube\": -0.5..0.5, flat normals; by xtask/mitsuba/seed.py"])
    print("wrote", MESHES)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("meshes")
    twin.add_render_args(sub.add_parser("render"))
    a = p.parse_args()
    if a.cmd == "meshes":
        meshes()
    else:
        try:
            twin.render(SCENE, a.spp, a.seed, a.out, a.variant)
        except twin.TwinError as e:
            sys.exit("%s: %s" % (SCENE, e))


if __name__ == "__main__":
    sys.exit(main())
