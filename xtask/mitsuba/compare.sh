#!/usr/bin/env bash
# Lucent's path tracer against the Mitsuba 3 peer's Cornell box
# (../shared/peers/mitsuba): error against its 8192-spp reference, and speed
# beside Mitsuba's llvm_ad_rgb variant measured in the same session.
#
#   xtask/mitsuba/compare.sh errors [SPPS] [SEED]     RMSE/FLIP of Lucent renders at each spp
#                                                      (default "16,64,256", seed 0)
#   xtask/mitsuba/compare.sh converge CHUNKS SPP      CHUNKS renders of SPP samples, seeds
#                                                      1000, 1001, ..., averaged, then compared
#                                                      (chunks already in OUT are reused; under nice)
#   xtask/mitsuba/compare.sh bench [ROUNDS] [SPP]     interleaved timings, Lucent then Mitsuba
#                                                      per round (default 5 rounds of 64 spp)
#   xtask/mitsuba/compare.sh seeds [SPP] [SEEDS]      Lucent (seed s) and Mitsuba (seed 1000 s) at SPP
#                                                      for each seed, alternately; both compared
#                                                      (default 64 spp, seeds "11,12,13,14")
#   xtask/mitsuba/compare.sh blocks STEM              bias check: 8x8-block means of STEM.exr
#                                                      against the reference's
#   xtask/mitsuba/compare.sh heavy [ROUNDS] [SPP]     interleaved timings of the heavy scene
#                                                      (res/scenes/heavy.toml, 2.16 M instanced
#                                                      triangles; Mitsuba's twin by heavy.py),
#                                                      default 5 rounds of 16 spp, then both renders'
#                                                      RMSE against a 1024-spp Mitsuba reference
#                                                      (rendered once into OUT)
#
# env: OUT=/tmp/lucent-vs-mitsuba  PY=/tmp/mts/bin/python (a venv with the peer's
#      requirements.txt: python3 -m venv /tmp/mts && /tmp/mts/bin/pip install -r
#      ../shared/peers/mitsuba/requirements.txt; llvm_ad_rgb also needs libllvm19)
#      THREADS=0 (Lucent worker threads; 0 = one per CPU)
#      LUCENT=path/to/lucent (a binary to use instead of building target/release/lucent)
#
# Lucent renders res/scenes/cornell-mitsuba.toml at 256x256 with max depth 16
# (Mitsuba's meaning), writing linear EXR + PNG; the peer's `cornell.py
# compare` reads them. Every timed run holds `flock /tmp/lucent-bench.lock`;
# the load average is logged before and after each round. Nothing is written
# inside the peer's folder.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PEER=$(cd "$ROOT/../shared/peers/mitsuba" && pwd)
OUT=${OUT:-/tmp/lucent-vs-mitsuba}
PY=${PY:-/tmp/mts/bin/python}
THREADS=${THREADS:-0}
SCENE=$ROOT/res/scenes/cornell-mitsuba.toml
HELP="$ROOT/xtask/mitsuba/tools.py"
mkdir -p "$OUT"
if [[ -z ${LUCENT:-} ]]; then
  cargo build --release -q -p lucent --manifest-path "$ROOT/Cargo.toml"
  LUCENT=$ROOT/target/release/lucent
fi
lock() { flock /tmp/lucent-bench.lock "$@"; }
load() { cut -d' ' -f1-3 /proc/loadavg; }
thread_args=()
[[ $THREADS != 0 ]] && thread_args=(--threads "$THREADS")

# render [PREFIX...] -- STEM SPP SEED: Lucent's render of the Cornell box, EXR + PNG,
# run under PREFIX (e.g. `lock` or `nice`).
render() {
  local prefix=()
  while [[ $1 != -- ]]; do prefix+=("$1"); shift; done
  shift
  "${prefix[@]}" "$LUCENT" render "$SCENE" --size 256x256 --max-depth 16 --integrator path \
    --spp "$2" --seed "$3" --exr "$1.exr" -o "$1.png" "${thread_args[@]}"
}
compare() { (cd "$PEER" && "$PY" cornell.py compare --ref "$PEER/out/ref" "$@"); }

cmd=${1:-errors}
case $cmd in
  errors)
    SPPS=${2:-16,64,256}
    SEED=${3:-0}
    for spp in ${SPPS//,/ }; do
      stem=$OUT/lucent_spp$(printf %05d "$spp")
      echo "load $(load)"
      render flock /tmp/lucent-bench.lock -- "$stem" "$spp" "$SEED"
      compare "$stem"
    done
    ;;
  converge)
    CHUNKS=${2:?chunks}
    SPP=${3:?spp per chunk}
    stems=()
    for i in $(seq 0 $((CHUNKS - 1))); do
      stem=$OUT/chunk_${SPP}_$i
      stems+=("$stem.exr")
      [[ -f $stem.exr ]] && continue
      render nice -n 19 -- "$stem" "$SPP" $((1000 + i))
    done
    total=$((CHUNKS * SPP))
    avg=$OUT/lucent_converged_$total
    "$PY" "$HELP" average "$avg" "${stems[@]}"
    compare "$avg"
    "$PY" "$HELP" blocks "$PEER/out/ref.exr" "$avg.exr"
    CHUNK_SPP=$SPP "$PY" "$HELP" noise "$PEER/out/ref.exr" 8192 "${stems[@]}"
    ;;
  seeds)
    SPP=${2:-64}
    SEEDS=${3:-11,12,13,14}
    stems=()
    for s in ${SEEDS//,/ }; do
      render flock /tmp/lucent-bench.lock -- "$OUT/seed_lucent_$s" "$SPP" "$s" >/dev/null
      (cd "$PEER" && lock "$PY" cornell.py render --variant llvm_ad_rgb --spp "$SPP" --seed $((s * 1000)) \
        --out "$OUT/seed_mitsuba_$s" >/dev/null 2>&1)
      stems+=("$OUT/seed_lucent_$s" "$OUT/seed_mitsuba_$s")
    done
    compare "${stems[@]}"
    ;;
  blocks)
    "$PY" "$HELP" blocks "$PEER/out/ref.exr" "${2:?stem}.exr"
    ;;
  bench)
    ROUNDS=${2:-5}
    SPP=${3:-64}
    RES=$OUT/bench.jsonl
    : >"$RES"
    for round in $(seq "$ROUNDS"); do
      before=$(load)
      line=$(render flock /tmp/lucent-bench.lock -- "$OUT/bench_lucent" "$SPP" "$round")
      s=$(sed -n 's/.*rendered in \([0-9.]*\) s.*/\1/p' <<<"$line")
      echo "{\"round\":$round,\"who\":\"lucent\",\"spp\":$SPP,\"render_s\":$s,\"load\":\"$before\"}" | tee -a "$RES"
      before=$(load)
      json=$(cd "$PEER" && lock "$PY" cornell.py render --variant llvm_ad_rgb --spp "$SPP" --seed "$round" \
        --out "$OUT/bench_mitsuba" 2>/dev/null | tail -1)
      s=$("$PY" -c 'import json,sys; print(json.loads(sys.argv[1])["render_s"])' "$json")
      echo "{\"round\":$round,\"who\":\"mitsuba\",\"spp\":$SPP,\"render_s\":$s,\"load\":\"$before\"}" | tee -a "$RES"
    done
    echo "load after: $(load)"
    "$PY" "$HELP" summarize "$RES"
    compare "$OUT/bench_lucent" "$OUT/bench_mitsuba"
    ;;
  heavy)
    ROUNDS=${2:-5}
    SPP=${3:-16}
    HEAVY=$ROOT/res/scenes/heavy.toml
    RES=$OUT/heavy.jsonl
    : >"$RES"
    for round in $(seq "$ROUNDS"); do
      before=$(load)
      line=$(lock "$LUCENT" render "$HEAVY" --spp "$SPP" --seed "$round" --exr "$OUT/heavy_lucent.exr" \
        -o "$OUT/heavy_lucent.png" "${thread_args[@]}")
      s=$(sed -n 's/.*rendered in \([0-9.]*\) s.*/\1/p' <<<"$line")
      echo "{\"round\":$round,\"who\":\"lucent\",\"spp\":$SPP,\"render_s\":$s,\"load\":\"$before\"}" | tee -a "$RES"
      before=$(load)
      json=$(lock "$PY" "$ROOT/xtask/mitsuba/heavy.py" render --spp "$SPP" --seed "$round" \
        --out "$OUT/heavy_mitsuba" 2>/dev/null | tail -1)
      s=$("$PY" -c 'import json,sys; print(json.loads(sys.argv[1])["render_s"])' "$json")
      echo "{\"round\":$round,\"who\":\"mitsuba\",\"spp\":$SPP,\"render_s\":$s,\"load\":\"$before\"}" | tee -a "$RES"
    done
    echo "load after: $(load)"
    "$PY" "$HELP" summarize "$RES"
    # The last round's renders against Mitsuba's reference of the heavy
    # scene, made once (1024 spp, under nice) and kept in OUT.
    if [[ ! -f $OUT/heavy_ref.exr ]]; then
      nice -n 19 "$PY" "$ROOT/xtask/mitsuba/heavy.py" render --spp 1024 --seed 99999 --out "$OUT/heavy_ref" >/dev/null
    fi
    echo "mean radiance and RMSE against Mitsuba's 1024-spp reference (a: Lucent, b: Mitsuba):"
    "$PY" "$HELP" pair "$OUT/heavy_lucent.exr" "$OUT/heavy_mitsuba.exr" "$OUT/heavy_ref.exr"
    ;;
  *)
    echo "usage: $0 errors|converge|bench|seeds|blocks|heavy ..." >&2
    exit 2
    ;;
esac
