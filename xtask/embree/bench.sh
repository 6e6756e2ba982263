#!/usr/bin/env bash
# Interleaved speed comparison: Lucent's traversal core vs Intel Embree.
#
#   xtask/embree/bench.sh [ROUNDS] [OUT_DIR]     (defaults: 3, /tmp/lucent-vs-embree)
#   env: PEER=/tmp/embree-peer  BASELINE=path/to/an/older/lucent-bench (optional;
#        a 'lucent' from before lucent-bench: BASELINE_CMD="bench rays")
#        PACKETS=1 also times Lucent's packet queries on the same rays
#        (`lucent-bench rays --packets`: sixteen consecutive rays of the file
#        at a time, i.e. sixteen neighbouring pixels of a camera's rays; the
#        random rays go back to the single-ray walk), as "lucent_packets"
#        MESHES="bun_zipper dragon"  SETS="close primary random"  REPS=5
#        (or MESHES="cornell cornell_walls cornell_spheres" SETS=inside: the
#        Cornell box, its six large wall and light triangles alone and its
#        two spheres alone, with 1M rays from inside the box, the path
#        tracer's kind of ray there; see cornell_rays.py)
#        ASSETS=$ROOT/../shared/assets (the meshes; set it in a worktree elsewhere)
#
# Needs the ray and hit files made by xtask/embree/compare.sh. Each round runs,
# for every mesh and ray set, Embree (closest + any hit, 1 and 2 threads, BVH
# build on 2 CPUs), then `lucent-bench rays` with 1 and 2 threads (and the
# BASELINE binary, if given), all under `flock /tmp/lucent-bench.lock`, so
# that drifts of this shared machine hit every contender alike. Every result
# is kept as a JSON line in OUT_DIR/results.jsonl; summarize.py prints the
# medians over rounds and the Lucent/Embree ratios.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
ROUNDS=${1:-3}
OUT=${2:-/tmp/lucent-vs-embree}
PEER=${PEER:-/tmp/embree-peer}
REPS=${REPS:-5}
MESHES=${MESHES:-"bun_zipper dragon"}
SETS=${SETS:-"close primary random"}
ASSETS=${ASSETS:-$ROOT/../shared/assets}
declare -A MESH=([bun_zipper]=$ASSETS/stanford-bunny/bun_zipper.ply [dragon]=$ASSETS/stanford-dragon-100k/dragon.ply
  [cornell]=$PEER/out/cornell.ply [cornell_walls]=$PEER/out/cornell_walls.ply
  [cornell_spheres]=$PEER/out/cornell_spheres.ply)
if [[ " $MESHES " == *" cornell"* ]]; then
  # The Cornell box's meshes and rays inside it (SETS=inside), made afresh.
  "$PEER/.venv/bin/python" "$ROOT/xtask/embree/cornell_rays.py" "$PEER/out" >/dev/null
fi
cargo build --release -q -p lucent-bench --manifest-path "$ROOT/Cargo.toml"
LUCENT=$ROOT/target/release/lucent-bench
mkdir -p "$OUT"
RES=$OUT/results.jsonl
# This run's results only: the summary's medians must not mix in an earlier run's.
: >"$RES"
lock() { flock /tmp/lucent-bench.lock "$@"; }
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/load.txt"
for round in $(seq "$ROUNDS"); do
  for n in $MESHES; do
    m=${MESH[$n]}
    for set in $SETS; do
      rays=$PEER/out/$n.$set.rays
      tag="\"round\":$round,\"case\":\"$n.$set\""
      lock "$PEER/.venv/bin/python" "$PEER/embree_rays.py" "$m" --kind file --rays-in "$rays" \
        --threads 1,2 --reps "$REPS" --build-reps 5 --no-empty --json "$OUT/embree.json" >/dev/null
      python3 - "$OUT/embree.json" "$round" "$n.$set" >>"$RES" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
t = d["trace"]
print(json.dumps({"round": int(sys.argv[2]), "case": sys.argv[3], "who": "embree",
  "build_s": d["build_s_median"], "rays": d["rays"],
  **{k + "_mrays_s": v["mrays_s"] for k, v in t.items()}}))
PY
      for threads in 1 2; do
        for who in lucent lucent_packets baseline; do
          bin=$LUCENT cmd=rays extra=()
          if [[ $who == baseline ]]; then
            [[ -n ${BASELINE:-} ]] || continue
            bin=$BASELINE cmd=${BASELINE_CMD:-rays}
          fi
          if [[ $who == lucent_packets ]]; then
            [[ ${PACKETS:-0} == 1 ]] || continue
            extra=(--packets)
          fi
          # shellcheck disable=SC2086 # BASELINE_CMD may be two words
          line=$(lock "$bin" $cmd --mesh "$m" --rays "$rays" --occluded /dev/null \
            --threads "$threads" --reps "$REPS" "${extra[@]}" 2>/dev/null)
          echo "{$tag,\"who\":\"$who\",${line#\{}" >>"$RES"
        done
      done
    done
  done
  echo "round $round done, load $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/load.txt"
done
python3 "$ROOT/xtask/embree/summarize.py" "$RES"
