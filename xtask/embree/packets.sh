#!/usr/bin/env bash
# Lucent's packet walk against its single-ray walk on the Embree peer's
# camera rays, interleaved: for each round, mesh (bunny, dragon), ray set
# (1280x720 primary rays at the default camera and at 1.2 radii) and order,
# `lucent-bench rays` once ray by ray and once with --packets (sixteen
# consecutive rays at a time), closest and any hit, 1 thread, each run under
# `flock /tmp/lucent-bench.lock`.
#
#   xtask/embree/packets.sh [ROUNDS] [OUT]     (defaults: 3, /tmp/lucent-packets.jsonl)
#
# Orders: rows (the file's scanline order: sixteen pixels of one row), tiles
# (4x4 pixel tiles), samples (sixteen jittered rays per pixel, every fourth
# pixel each way, as a pixel's samples are traced); see `lucent-bench rays
# --help`. Prints one JSON line per run into OUT, then a markdown table: the
# medians of Mrays/s and of the per-round ratios packets / single.
#
# env: PEER=/tmp/embree-peer (the ray files of xtask/embree/compare.sh)
#      ASSETS=<repo>/../shared/assets   LUCENT_BENCH=path/to/lucent-bench
#      (default: this checkout's release build)   REPS=3
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
ROUNDS=${1:-3}
OUT=${2:-/tmp/lucent-packets.jsonl}
PEER=${PEER:-/tmp/embree-peer}
ASSETS=${ASSETS:-$ROOT/../shared/assets}
REPS=${REPS:-3}
if [[ -z ${LUCENT_BENCH:-} ]]; then
  cargo build --release -q -p lucent-bench --manifest-path "$ROOT/Cargo.toml"
  LUCENT_BENCH=$ROOT/target/release/lucent-bench
fi
declare -A MESH=([bun_zipper]=$ASSETS/stanford-bunny/bun_zipper.ply [dragon]=$ASSETS/stanford-dragon-100k/dragon.ply)
: >"$OUT"
for round in $(seq "$ROUNDS"); do
  for n in bun_zipper dragon; do
    for set in close primary; do
      rays=$PEER/out/$n.$set.rays
      [[ -f $rays ]] || { echo "no $rays: run xtask/embree/compare.sh first" >&2; exit 2; }
      for order in rows tiles samples; do
        order_args=()
        [[ $order != rows ]] && order_args=(--order "$order" --width 1280)
        for who in single packets; do
          packet_args=()
          [[ $who == packets ]] && packet_args=(--packets)
          line=$(flock /tmp/lucent-bench.lock "$LUCENT_BENCH" rays --mesh "${MESH[$n]}" --rays "$rays" --threads 1 \
            --reps "$REPS" --occluded /dev/null "${order_args[@]}" "${packet_args[@]}" 2>/dev/null | tail -1)
          echo "{\"round\":$round,\"case\":\"$n.$set\",\"order\":\"$order\",\"who\":\"$who\",\"load\":\"$(cut -d' ' -f1 /proc/loadavg)\",\"out\":$line}" >>"$OUT"
        done
      done
    done
  done
  echo "round $round done, load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
done
python3 - "$OUT" <<'PY'
import collections, json, statistics as st, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
by = collections.defaultdict(list)
for r in rows:
    by[(r["case"], r["order"], r["who"])].append(r)
print("| rays | order | closest: single | packets | ratio | any hit: single | packets | ratio |")
print("|---|---|---:|---:|---:|---:|---:|---:|")
for case, order in sorted({(r["case"], r["order"]) for r in rows}):
    s, p = by[(case, order, "single")], by[(case, order, "packets")]
    med = lambda runs, k: st.median(x["out"][k] for x in runs)
    ratio = lambda k: st.median(b["out"][k] / a["out"][k] for a, b in zip(s, p))
    print(f"| {case} | {order} | {med(s, 'mrays_s'):.1f} | {med(p, 'mrays_s'):.1f} | {ratio('mrays_s'):.2f} "
          f"| {med(s, 'occluded_mrays_s'):.1f} | {med(p, 'occluded_mrays_s'):.1f} | {ratio('occluded_mrays_s'):.2f} |")
loads = [float(r["load"]) for r in rows]
print(f"\nrounds: {len(rows) // 24}; load {min(loads):.2f} to {max(loads):.2f}")
PY
