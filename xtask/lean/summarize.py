#!/usr/bin/env python3
"""Medians and ratios from xtask/lean/bench.sh: summarize.py OUT_DIR."""
import collections
import json
import os
import statistics
import sys

out = sys.argv[1] if len(sys.argv) > 1 else "/tmp/lucent-lean"


def rows(name):
    path = os.path.join(out, name)
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [json.loads(line) for line in f if line.strip()]


time = collections.defaultdict(lambda: collections.defaultdict(list))
for r in rows("time.jsonl"):
    time[r["config"]][r["variant"]].append(r)
if time:
    print("| scene, integrator | contender | rounds | render wall s (median) | process CPU s (median) | rays | load |")
    print("|---|---|---|---|---|---|---|")
    for config, vs in time.items():
        med = {}
        for v, rs in vs.items():
            wall = statistics.median(x["out"]["render_s_median"] for x in rs)
            cpu = statistics.median(x["cpu_ms"] for x in rs) / 1000
            rays = sorted({x["out"]["rays"] for x in rs})
            load = f"{min(x['load'] for x in rs)} to {max(x['load'] for x in rs)}"
            med[v] = (wall, cpu)
            print(f"| {config} | {v} | {len(rs)} | {wall:.4f} | {cpu:.3f} | {', '.join(map(str, rays))} | {load} |")
        for v in ("all", "base"):
            if v in med and "lean" in med:
                print(f"| {config} | {v} / lean | | {med[v][0] / med['lean'][0]:.3f} | {med[v][1] / med['lean'][1]:.3f} | | |")
ir = rows("instructions.jsonl")
if ir:
    lean = {r["config"]: r["ir_per_render"] for r in ir if r["variant"] == "lean"}
    print()
    print("| scene, integrator | contender | instructions per render | / lean |")
    print("|---|---|---|---|")
    for r in ir:
        base = lean.get(r["config"])
        ratio = f"{r['ir_per_render'] / base:.4f}" if base else ""
        print(f"| {r['config']} | {r['variant']} | {r['ir_per_render']:,} | {ratio} |")
