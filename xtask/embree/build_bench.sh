#!/usr/bin/env bash
# Interleaved BVH build times: Lucent's mesh build against Intel Embree's.
#
#   xtask/embree/build_bench.sh [ROUNDS] [OUT_FILE]   (defaults: 5, /tmp/lucent-build-bench.txt)
#   env: PEER=/tmp/embree-peer  BASELINE=path/to/an/older/buildtime (optional)
#        MESHES="bun_zipper dragon"  REPS=9  ASSETS=$ROOT/../shared/assets
#
# Each round, for every mesh: Embree builds its scene REPS times on 2 CPUs
# (embree_rays.py --build-reps, the peer set up by compare.sh), then the
# `buildtime` example (`cargo build --release -p lucent-accel --example
# buildtime`) builds REPS times on 1 and 2 threads, and the BASELINE binary
# (a buildtime from another commit) likewise, each run under
# `flock /tmp/lucent-bench.lock`. One line per run goes to OUT_FILE
# (round, mesh, threads, who, JSON with median_ms and min_ms; the load
# average after each round); the medians over rounds are printed at the end.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
ROUNDS=${1:-5}
OUT=${2:-/tmp/lucent-build-bench.txt}
PEER=${PEER:-/tmp/embree-peer}
REPS=${REPS:-9}
MESHES=${MESHES:-"bun_zipper dragon"}
ASSETS=${ASSETS:-$ROOT/../shared/assets}
declare -A MESH=([bun_zipper]=$ASSETS/stanford-bunny/bun_zipper.ply [dragon]=$ASSETS/stanford-dragon-100k/dragon.ply)
cargo build --release -q -p lucent-accel --example buildtime --manifest-path "$ROOT/Cargo.toml"
LUCENT=$ROOT/target/release/examples/buildtime
lock() { flock /tmp/lucent-bench.lock "$@"; }
echo "load before $(cut -d' ' -f1-3 /proc/loadavg)" | tee "$OUT"
for round in $(seq "$ROUNDS"); do
  for n in $MESHES; do
    m=${MESH[$n]}
    lock "$PEER/.venv/bin/python" "$PEER/embree_rays.py" "$m" --kind random --n 1000 --threads 2 \
      --reps 1 --build-reps "$REPS" --no-occlusion --json "$OUT.embree.json" >/dev/null
    python3 - "$OUT.embree.json" "$round" "$n" >>"$OUT" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
print(sys.argv[2], sys.argv[3], 2, "embree", json.dumps({
    "median_ms": d["build_s_median"] * 1e3, "min_ms": min(d["build_s_all"]) * 1e3}))
PY
    for threads in 1 2; do
      echo "$round $n $threads lucent $(lock "$LUCENT" "$m" "$threads" "$REPS")" >>"$OUT"
      if [[ -n ${BASELINE:-} ]]; then
        echo "$round $n $threads baseline $(lock "$BASELINE" "$m" "$threads" "$REPS")" >>"$OUT"
      fi
    done
  done
  echo "round $round load $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT"
done
python3 - "$OUT" <<'PY'
import collections, json, statistics, sys
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    parts = line.split(" ", 4)
    if len(parts) == 5 and parts[4].startswith("{"):
        runs[(parts[1], parts[2], parts[3])].append(json.loads(parts[4])["median_ms"])
for (mesh, threads, who), ms in sorted(runs.items()):
    print(f"{mesh:12} {threads} thread(s) {who:9} median {statistics.median(ms):7.2f} ms"
          f"  (rounds {min(ms):.2f} to {max(ms):.2f}, n={len(ms)})")
PY
