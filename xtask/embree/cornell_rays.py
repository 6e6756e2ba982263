#!/usr/bin/env python3
"""The path tracer's kind of rays on the Cornell box, for xtask/embree/bench.sh.

    PEER/.venv/bin/python xtask/embree/cornell_rays.py PEER/out [N] [SEED]

Run with the Embree peer's Python (its loader reads the PLYs). Writes into
the folder given:

- cornell.ply: the nine meshes of res/meshes/cornell-mitsuba (what
  res/scenes/cornell-mitsuba.toml renders, none of them transformed) as one
  mesh, in file-name order (10 264 triangles);
- cornell_walls.ply: the floor, ceiling, three walls and the light alone
  (12 large triangles); cornell_spheres.ply: the two tessellated spheres
  alone (10 240 small ones);
- NAME.inside.rays for each of the three: the same N rays (default 1 M,
  seed 1), from points uniform in the middle 96 % of the box's extent on
  each axis, in uniform directions. Like a path's bounces inside the box,
  most start near nothing and end on a wall (86 % hit the full box, the
  rest leave through its open front).

bench.sh times them as MESHES="cornell cornell_walls cornell_spheres"
SETS=inside. The files are rewritten on every run (a few seconds).
"""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
MESHES = os.path.join(ROOT, "res", "meshes", "cornell-mitsuba")
WALLS = ["back_wall", "ceiling", "floor", "left_wall", "light", "right_wall"]
SPHERES = ["diffuse_sphere", "glass_sphere"]


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    try:
        n = int(sys.argv[2]) if len(sys.argv) > 2 else 1_000_000
        seed = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    except ValueError as e:
        sys.exit(f"cornell_rays.py: N and SEED must be whole numbers ({e})")
    if n < 1:
        sys.exit(f"cornell_rays.py: N must be at least 1, not {n}")
    # The peer's loader and writers: the peer folder is the parent of `out`.
    peer = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(out) or not os.path.isfile(os.path.join(peer, "embree_rays.py")):
        sys.exit(f"cornell_rays.py: {out} is not the out/ folder of an Embree peer set up by compare.sh")
    sys.path.insert(0, peer)
    import embree_rays as er

    everything = sorted(f[:-4] for f in os.listdir(MESHES) if f.endswith(".ply"))
    groups = {"cornell": everything, "cornell_walls": WALLS, "cornell_spheres": SPHERES}
    lo = hi = None
    for name, parts in groups.items():
        vs, fs, base = [], [], 0
        for p in parts:
            v, f = er.load_mesh(os.path.join(MESHES, p + ".ply"))[:2]
            vs.append(v)
            fs.append(f + base)
            base += len(v)
        v, f = np.concatenate(vs), np.concatenate(fs)
        er.write_ply(os.path.join(out, name + ".ply"), v, f)
        if name == "cornell":
            lo, hi = v.min(0).astype(np.float64), v.max(0).astype(np.float64)
        print(f"{name}.ply: {len(f)} triangles")
    rng = np.random.default_rng(seed)
    c, e = (lo + hi) * 0.5, hi - lo
    orig = (c - 0.48 * e) + rng.random((n, 3)) * (0.96 * e)
    z = rng.random(n) * 2.0 - 1.0
    phi = rng.random(n) * 2.0 * np.pi
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    for name in groups:
        er.write_rays(os.path.join(out, name + ".inside.rays"), orig.astype(np.float32), dirs.astype(np.float32))
    print(f"{n} rays inside the box (seed {seed}) for each")


if __name__ == "__main__":
    main()
