#!/usr/bin/env bash
# Lucent's path tracer against Mitsuba 3: error against a Mitsuba reference
# and speed beside Mitsuba's llvm_ad_rgb variant measured in the same session,
# on the Mitsuba peer's Cornell box (../shared/peers/mitsuba), the seed scene
# path traced (res/scenes/seed-mitsuba.toml, Mitsuba's twin by seed.py) and
# the heavy scene (res/scenes/heavy.toml, 2.16 M instanced triangles,
# Mitsuba's twin by heavy.py).
#
#   xtask/mitsuba/compare.sh bench [ROUNDS] [SCENES]
#       issue 14's table: for each round (default 5), for each scene of SCENES
#       (default "cornell,seed,heavy"), Lucent then Mitsuba render it at the
#       scene's spp with the round's seed, each timed under the bench lock;
#       then every render's RMSE against the scene's Mitsuba reference (the
#       peer's 8192-spp render for the Cornell box; for the others REF_SPP spp
#       rendered once under nice and cached in OUT, keyed by the scene's files
#       and Mitsuba's version). Prints a JSON line per render (OUT/bench.jsonl),
#       one per scene (OUT/bench_summary.jsonl: median s/spp of each, the
#       median of the per-round time ratios, each one's RMSE averaged over the
#       rounds' seeds, image means) and a markdown table. Its last column is
#       the time ratio at equal error: the ratio times (Mitsuba's RMSE /
#       Lucent's)^2, since an unbiased render's MSE falls as 1/spp.
#       Spp per scene: SPP_CORNELL=64 SPP_SEED=16 SPP_HEAVY=16 (SPP sets all three)
#       BASELINE=path/to/an/older/lucent also renders each scene with that
#       binary in every round, between Lucent's render and Mitsuba's, so a
#       change is measured against Mitsuba and against the build before it in
#       the same rounds (the VM's speed drifts between runs by more than a
#       small change); the summary and the table then give its figures too.
#   xtask/mitsuba/compare.sh heavy [ROUNDS] [SPP]     the same for the heavy scene alone
#                                                      (default 5 rounds of 16 spp)
#   xtask/mitsuba/compare.sh errors [SPPS] [SEED]     RMSE/FLIP of Lucent's Cornell box at each
#                                                      spp (default "16,64,256", seed 0)
#   xtask/mitsuba/compare.sh converge CHUNKS SPP      CHUNKS Cornell renders of SPP samples, seeds
#                                                      1000, 1001, ..., averaged, then compared
#                                                      (chunks already in OUT are reused; under nice)
#   xtask/mitsuba/compare.sh seeds [SPP] [SEEDS]      Cornell: Lucent (seed s) and Mitsuba (seed
#                                                      1000 s) at SPP for each seed, alternately;
#                                                      both compared (default 64 spp, seeds "11,12,13,14")
#   xtask/mitsuba/compare.sh error-seeds SCENE [SPP] [FIRST] [LAST]
#                                                      equal error, measured apart from time: SCENE
#                                                      (cornell, seed or heavy) at SPP (the bench's
#                                                      default) by both renderers, Lucent seed s and
#                                                      Mitsuba seed 1000 s for s in FIRST..LAST
#                                                      (default 1..40), untimed under nice, kept in
#                                                      OUT/errors_SCENE_SPP and reused; prints each
#                                                      one's mean MSE against the reference, their
#                                                      ratio with a bootstrap 90 % interval, the
#                                                      per-seed ratios' median and the means' bias
#   xtask/mitsuba/compare.sh blocks STEM              bias check: 8x8-block means of STEM.exr
#                                                      against the Cornell reference's
#
# env: OUT=/tmp/lucent-vs-mitsuba  PEER=<repo>/../shared/peers/mitsuba (the peer's folder)
#      PY=/tmp/mts/bin/python (a venv with the peer's
#      requirements.txt: python3 -m venv /tmp/mts && /tmp/mts/bin/pip install -r
#      ../shared/peers/mitsuba/requirements.txt; llvm_ad_rgb also needs libllvm19)
#      THREADS=0 (Lucent worker threads; 0 = one per CPU; Mitsuba uses every CPU)
#      LUCENT=path/to/lucent (a binary to time instead of building target/release/lucent)
#      REF_SPP=2048 (spp of the cached references of the seed and heavy scenes)
#      RENDER_ARGS="" (more arguments for Lucent's renders: the lane tracer is
#      the default; RENDER_ARGS=--lanes=false times the scalar tracer)
#
# Lucent renders each scene file as it stands (the Cornell box: 256x256, max
# depth 16; seed: 640x360, depth 8; heavy: 256x256, depth 8), writing linear
# EXR + PNG; its time is the render's ("rendered in", without loading and BVH
# build), Mitsuba's is its renders' after a 1-spp warm-up that compiles its
# kernels (without loading). Every timed run holds `flock
# /tmp/lucent-bench.lock`, and the load average is logged with each. Nothing
# is written inside the peer's folder.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PEER=${PEER:-$ROOT/../shared/peers/mitsuba}
if [[ ! -f $PEER/cornell.py ]]; then
  echo "no Mitsuba peer at $PEER (its cornell.py and out/ref.exr): set PEER=.../shared/peers/mitsuba" >&2
  exit 2
fi
PEER=$(cd "$PEER" && pwd)
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
if [[ -n ${BASELINE:-} && ! -x $BASELINE ]]; then
  echo "BASELINE=$BASELINE: no such executable (an older build of lucent to time beside this one)" >&2
  exit 2
fi
lock() { flock /tmp/lucent-bench.lock "$@"; }
load() { cut -d' ' -f1-3 /proc/loadavg; }
thread_args=()
[[ $THREADS != 0 ]] && thread_args=(--threads "$THREADS")
# More arguments for every Lucent render, split at spaces (RENDER_ARGS=--lanes
# times the lane tracer).
read -r -a render_args <<<"${RENDER_ARGS:-}"

# render [PREFIX...] -- STEM SPP SEED: Lucent's render of the Cornell box, EXR + PNG,
# run under PREFIX (e.g. `lock` or `nice`).
render() {
  local prefix=()
  while [[ $1 != -- ]]; do prefix+=("$1"); shift; done
  shift
  "${prefix[@]}" "$LUCENT" render "$SCENE" --size 256x256 --max-depth 16 --integrator path \
    --spp "$2" --seed "$3" --exr "$1.exr" -o "$1.png" "${thread_args[@]}" "${render_args[@]}"
}
compare() { (cd "$PEER" && "$PY" cornell.py compare --ref "$PEER/out/ref" "$@"); }

REF_SPP=${REF_SPP:-2048}
# scene_info NAME: sets toml, spp, ref, mts (Mitsuba's render command,
# which takes --spp N --seed S --out STEM) and seed_scale (the peer's
# passes of 64 spp are seeded from --seed up, so its rounds' seeds lie
# 1000 apart; twin.py spaces them itself).
declare -A REF_KEY=()
scene_info() {
  seed_scale=1
  case $1 in
    cornell)
      toml=$ROOT/res/scenes/cornell-mitsuba.toml spp=${SPP_CORNELL:-${SPP:-64}} ref=$PEER/out/ref.exr
      mts=(env -C "$PEER" "$PY" cornell.py render --variant llvm_ad_rgb) seed_scale=1000 ;;
    seed | heavy)
      toml=$ROOT/res/scenes/$1.toml
      [[ $1 == seed ]] && toml=$ROOT/res/scenes/seed-mitsuba.toml
      if [[ $1 == seed ]]; then spp=${SPP_SEED:-${SPP:-16}}; else spp=${SPP_HEAVY:-${SPP:-16}}; fi
      mts=("$PY" "$ROOT/xtask/mitsuba/$1.py" render)
      # The reference is keyed by every file that shapes the scene
      # (worked out once per run).
      [[ -n ${REF_KEY[$1]:-} ]] || REF_KEY[$1]=$( (cat "$toml" "$ROOT"/xtask/mitsuba/{twin,"$1"}.py; sed -n 's/^mesh = "\(.*\)"/\1/p; s/^texture = "\(.*\)"/\1/p' "$toml" |
        sort -u | (cd "$(dirname "$toml")" && xargs cat); "$PY" -c 'import mitsuba; print(mitsuba.__version__)') |
        sha256sum | cut -c1-12)
      ref=$OUT/ref_$1_${REF_KEY[$1]}_$REF_SPP.exr ;;
    *) echo "unknown scene '$1' (cornell, seed, heavy)" >&2; exit 2 ;;
  esac
}
# ensure_ref: renders the reference of the scene scene_info last named, once
# (under nice, outside the lock).
ensure_ref() {
  if [[ ! -f $ref ]]; then
    echo "rendering the $scene reference ($REF_SPP spp, once) into $ref"
    nice -n 19 "${mts[@]}" --spp "$REF_SPP" --seed 99999 --out "${ref%.exr}" >/dev/null
  fi
}

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
  error-seeds)
    # Untimed renders of seeds FIRST..LAST by both renderers (Lucent seed s,
    # Mitsuba seed 1000 s, as `seeds` pairs them), under nice, kept in OUT
    # and reused; then the error study of tools.py seeds_error.
    scene=${2:?scene (cornell, seed or heavy)}
    scene_info "$scene"
    spp=${3:-$spp}
    FIRST=${4:-1}
    LAST=${5:-40}
    ensure_ref
    dir=$OUT/errors_${scene}_$spp
    mkdir -p "$dir"
    for s in $(seq "$FIRST" "$LAST"); do
      [[ -f $dir/lucent_$s.exr ]] || nice "$LUCENT" -q render "$toml" --spp "$spp" --seed "$s" \
        --exr "$dir/lucent_$s.exr" -o "$dir/lucent_$s.png" "${thread_args[@]}" "${render_args[@]}" >/dev/null
      [[ -f $dir/mitsuba_$s.exr ]] || nice "${mts[@]}" --spp "$spp" --seed $((s * 1000)) --out "$dir/mitsuba_$s" >/dev/null 2>&1
    done
    "$PY" "$HELP" seeds_error "$ref" "$dir" "$FIRST" "$LAST"
    ;;
  bench | heavy)
    ROUNDS=${2:-5}
    if [[ $cmd == heavy ]]; then
      SCENES=heavy
      SPP_HEAVY=${3:-${SPP:-16}}
    else
      SCENES=${3:-cornell,seed,heavy}
    fi
    RES=$OUT/bench.jsonl
    mkdir -p "$OUT/bench"
    : >"$RES"
    # References first, so no timed round waits on one.
    for scene in ${SCENES//,/ }; do
      scene_info "$scene"
      ensure_ref
    done
    echo "lucent: $LUCENT ${RENDER_ARGS:-} ($(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo '?')), $(nproc) CPUs: $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1)"
    [[ -n ${BASELINE:-} ]] && echo "baseline: $BASELINE"
    # lucent_round WHO BIN: BIN renders the round's scene at its seed under
    # the lock; one JSON line for WHO (lucent, or the baseline).
    lucent_round() {
      local stem=$OUT/bench/${scene}_$1_$round before line s
      before=$(load)
      line=$(lock "$2" -q render "$toml" --spp "$spp" --seed "$round" --exr "$stem.exr" -o "$stem.png" "${thread_args[@]}" "${render_args[@]}")
      s=$(sed -n 's/.*rendered in \([0-9.]*\) s.*/\1/p' <<<"$line")
      echo "{\"scene\":\"$scene\",\"round\":$round,\"who\":\"$1\",\"spp\":$spp,\"seed\":$round,\"render_s\":$s,\"load\":\"$before\",\"exr\":\"$stem.exr\",\"ref\":\"$ref\"}" | tee -a "$RES"
    }
    for round in $(seq "$ROUNDS"); do
      for scene in ${SCENES//,/ }; do
        scene_info "$scene"
        lucent_round lucent "$LUCENT"
        [[ -n ${BASELINE:-} ]] && lucent_round baseline "$BASELINE"
        stem=$OUT/bench/${scene}_mitsuba_$round
        before=$(load)
        json=$(lock "${mts[@]}" --spp "$spp" --seed $((round * seed_scale)) --out "$stem" 2>/dev/null | tail -1)
        s=$("$PY" -c 'import json,sys; print(json.loads(sys.argv[1])["render_s"])' "$json")
        echo "{\"scene\":\"$scene\",\"round\":$round,\"who\":\"mitsuba\",\"spp\":$spp,\"seed\":$((round * seed_scale)),\"render_s\":$s,\"load\":\"$before\",\"exr\":\"$stem.exr\",\"ref\":\"$ref\"}" | tee -a "$RES"
      done
    done
    echo "load after: $(load)"
    "$PY" "$HELP" table "$RES" "$OUT/bench_summary.jsonl"
    ;;
  *)
    echo "usage: $0 bench|heavy|errors|converge|seeds|error-seeds|blocks ..." >&2
    exit 2
    ;;
esac
