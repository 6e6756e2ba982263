#!/usr/bin/env python3
"""Medians over rounds of xtask/embree/bench.sh results, with Lucent/Embree
(and Lucent/baseline) ratios. Usage: summarize.py results.jsonl"""
import json
import statistics
import sys
from collections import defaultdict

rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
by = defaultdict(list)
for r in rows:
    by[(r["case"], r["who"], r.get("threads"))].append(r)


def med(rs, key):
    vals = [r[key] for r in rs if key in r]
    return statistics.median(vals) if vals else float("nan")


cases = sorted({r["case"] for r in rows}, key=lambda c: (c.split(".")[0], c))
print(f"rounds: {max(r['round'] for r in rows)}; Mrays/s medians over rounds; ratio = Lucent / Embree")
head = "| case | query | threads | Embree | Lucent | ratio | baseline | Lucent/baseline |"
print(head)
print("|" + "---|" * (head.count("|") - 1))
for c in cases:
    e = by[(c, "embree", None)]
    for q, lk, ek in (("closest", "mrays_s", "closest_T{}_mrays_s"), ("any hit", "occluded_mrays_s", "occluded_T{}_mrays_s")):
        for t in (1, 2):
            em = med(e, ek.format(t))
            lu = med(by[(c, "lucent", t)], lk)
            ba = med(by[(c, "baseline", t)], lk)
            print(f"| {c} | {q} | {t} | {em:.2f} | {lu:.2f} | {lu / em:.2f} | {ba:.2f} | {lu / ba:.2f} |")
if any(r["who"] == "lucent_packets" for r in rows):
    print()
    print("Lucent's packet queries (`--packets`: sixteen consecutive rays of the file at a time) on the same rays:")
    print("| case | query | threads | Embree | Lucent packets | ratio | Lucent packets / Lucent |")
    print("|---|---|---|---|---|---|---|")
    for c in cases:
        e = by[(c, "embree", None)]
        for q, lk, ek in (("closest", "mrays_s", "closest_T{}_mrays_s"), ("any hit", "occluded_mrays_s", "occluded_T{}_mrays_s")):
            for t in (1, 2):
                em = med(e, ek.format(t))
                lp = med(by[(c, "lucent_packets", t)], lk)
                lu = med(by[(c, "lucent", t)], lk)
                print(f"| {c} | {q} | {t} | {em:.2f} | {lp:.2f} | {lp / em:.2f} | {lp / lu:.2f} |")
print()
print("| case | Embree build ms (2 CPUs) | Lucent build ms 1 thread | 2 threads | ratio (2 thr) | baseline ms | Lucent bytes/tri |")
print("|---|---|---|---|---|---|---|")
for c in cases:
    e = med(by[(c, "embree", None)], "build_s") * 1e3
    l1 = med(by[(c, "lucent", 1)], "build_s") * 1e3
    l2 = med(by[(c, "lucent", 2)], "build_s") * 1e3
    b1 = med(by[(c, "baseline", 1)], "build_s") * 1e3
    bpt = med(by[(c, "lucent", 1)], "bytes_per_triangle")
    print(f"| {c} | {e:.1f} | {l1:.1f} | {l2:.1f} | {l2 / e:.2f} | {b1:.1f} | {bpt:.1f} |")
