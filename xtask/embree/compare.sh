#!/usr/bin/env bash
# Lucent's traversal core against Intel Embree, ray for ray.
#
#   xtask/embree/compare.sh [PEER_DIR]      (default /tmp/embree-peer)
#
# 1. Sets up the Embree peer in a scratch copy (as its README says) unless
#    PEER_DIR/.venv exists, and generates, for the bunny and the dragon, the
#    ray sets (1280x720 primary at the default camera and at 1.2 radii, 1M
#    random rays) with Embree's closest hits and occlusion results.
# 2. Traces the same rays with `lucent-bench rays` and compares: hit/miss,
#    primitive id, t (relative), occlusion; every disagreement is classified
#    from the mesh in f64 (see crates/lucent-bench/src/rays.rs, `compare`).
#    Prints one JSON line per case; "unexplained" must be 0.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PEER=${1:-/tmp/embree-peer}
ASSETS=$ROOT/../shared/assets
if [[ ! -x $PEER/.venv/bin/python ]]; then
  rm -rf "$PEER"
  cp -r "$ROOT/../shared/peers/embree" "$PEER"
  python3 -m venv "$PEER/.venv"
  "$PEER/.venv/bin/pip" install -q embreex numpy
fi
mkdir -p "$PEER/out"
cargo build --release -q -p lucent-bench --manifest-path "$ROOT/Cargo.toml"
LUCENT=$ROOT/target/release/lucent-bench
for m in "$ASSETS/stanford-bunny/bun_zipper.ply" "$ASSETS/stanford-dragon-100k/dragon.ply"; do
  n=$(basename "${m%.*}")
  for set in primary close random; do
    case $set in
      primary) gen=(--kind primary) ;;
      close) gen=(--kind primary --distance-factor 1.2) ;;
      random) gen=(--kind random --n 1000000 --seed 1) ;;
    esac
    o=$PEER/out/$n.$set
    if [[ ! -f $o.hits ]]; then
      "$PEER/.venv/bin/python" "$PEER/embree_rays.py" "$m" "${gen[@]}" --rays-out "$o.rays" \
        --hits-out "$o.hits" --occ-out "$o.occ" --threads 1 --reps 1 --build-reps 1 --no-empty >/dev/null
    fi
    echo "== $n $set"
    "$LUCENT" rays --mesh "$m" --rays "$o.rays" --reps 1 \
      --hits "$o.lucent.hits" --occluded "$o.lucent.occ" \
      --compare-hits "$o.hits" --compare-occluded "$o.occ" 2>&1 | grep -v 'not used by any triangle'
  done
done
