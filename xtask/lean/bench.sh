#!/usr/bin/env bash
# What specialising on a scene's features saves: the same binary rendering
# specialised and with `--all-features` (and an older build, if given), the
# seed scene with and without its glass sphere and the Mitsuba Cornell box,
# Whitted and path traced.
#
#   xtask/lean/bench.sh time [ROUNDS] [OUT_DIR]    (defaults: 3, /tmp/lucent-lean)
#   xtask/lean/bench.sh instructions [OUT_DIR]
#   env: LUCENT=path/to/lucent (default: this checkout's release build)
#        BASELINE=path/to/an/older/lucent (optional; it must not be given
#        --all-features or --without, so it runs the full scenes only)
#
# `time`: interleaved rounds (the order of the contenders rotates each
# round), each `lucent bench render ... --reps 5` under
# `flock /tmp/lucent-bench.lock`, its CPU time taken by `perf stat -e
# task-clock`; JSON lines in OUT_DIR/time.jsonl.
# `instructions`: instructions executed per render, counted by valgrind's
# cachegrind on one thread at a reduced size: Ir(--reps 3) - Ir(--reps 1) is
# two renders, so loading, extract and BVH builds cancel out. It does not
# depend on the machine's load. JSON lines in OUT_DIR/instructions.jsonl.
# summarize.py OUT_DIR prints medians and ratios.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
MODE=${1:-time}
if [[ $MODE == time ]]; then ROUNDS=${2:-3}; OUT=${3:-/tmp/lucent-lean}; else OUT=${2:-/tmp/lucent-lean}; fi
if [[ -z ${LUCENT:-} ]]; then
  cargo build --release -q -p lucent --manifest-path "$ROOT/Cargo.toml"
  LUCENT=$ROOT/target/release/lucent
fi
BASELINE=${BASELINE:-}
mkdir -p "$OUT"
cd "$ROOT"
lock() { flock /tmp/lucent-bench.lock "$@"; }

# name | arguments | added for `time` (full size) | added for `instructions`
CONFIGS=(
  "seed-whitted|res/scenes/seed.toml --integrator whitted||--size 160x90"
  "seed-path|res/scenes/seed.toml --integrator path --spp 4||--size 160x90"
  "seed-nosphere-whitted|res/scenes/seed.toml --integrator whitted --without sphere||--size 160x90"
  "seed-nosphere-path|res/scenes/seed.toml --integrator path --spp 4 --without sphere||--size 160x90"
  "cornell-whitted|res/scenes/cornell-mitsuba.toml --integrator whitted|--spp 8|--spp 4 --size 64x64"
  "cornell-path|res/scenes/cornell-mitsuba.toml --integrator path|--spp 16|--spp 8 --size 64x64"
)

# The command of one contender: lean (specialised), all (--all-features), base.
contender() {
  case $1 in
    lean) echo "$LUCENT bench render $2";;
    all) echo "$LUCENT bench render $2 --all-features";;
    base) echo "$BASELINE bench render $2";;
  esac
}

contenders() {
  local v=(lean all)
  [[ -n $BASELINE && $1 != *--without* ]] && v+=(base)
  echo "${v[@]}"
}

if [[ $MODE == time ]]; then
  for r in $(seq 1 "$ROUNDS"); do
    for c in "${CONFIGS[@]}"; do
      IFS='|' read -r name args big _ <<<"$c"
      args="$args $big"
      read -r -a vs <<<"$(contenders "$args")"
      k=$(( (r - 1) % ${#vs[@]} ))
      for v in "${vs[@]:k}" "${vs[@]:0:k}"; do
        load=$(cut -d' ' -f1 /proc/loadavg)
        # shellcheck disable=SC2046
        json=$(lock perf stat -x, -e task-clock -o "$OUT/perf.txt" $(contender "$v" "$args --reps 5") 2>/dev/null)
        cpu=$(grep task-clock "$OUT/perf.txt" | cut -d, -f1)
        echo "{\"round\":$r,\"config\":\"$name\",\"variant\":\"$v\",\"load\":$load,\"cpu_ms\":$cpu,\"out\":$json}" >>"$OUT/time.jsonl"
      done
    done
  done
elif [[ $MODE == instructions ]]; then
  ir() {
    # shellcheck disable=SC2046
    lock valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null $(contender "$1" "$2") 2>&1 >/dev/null \
      | sed -n 's/.*I *refs: *//p' | tr -d ','
  }
  for c in "${CONFIGS[@]}"; do
    IFS='|' read -r name args _ small <<<"$c"
    for v in $(contenders "$args"); do
      a=$(ir "$v" "$args $small --threads 1 --reps 1")
      b=$(ir "$v" "$args $small --threads 1 --reps 3")
      if [[ -z $a || -z $b ]]; then
        echo "$name $v: no instruction count (does '$args $small' run?)" >&2
        exit 1
      fi
      echo "{\"config\":\"$name\",\"variant\":\"$v\",\"ir_per_render\":$(( (b - a) / 2 ))}" >>"$OUT/instructions.jsonl"
    done
  done
else
  echo "usage: $0 time [ROUNDS] [OUT_DIR] | instructions [OUT_DIR]" >&2
  exit 2
fi
