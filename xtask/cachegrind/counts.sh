#!/usr/bin/env bash
# Instructions, cache misses and branch mispredictions per ray and per
# path-traced sample, counted by valgrind's cachegrind (cache and branch
# simulation) on one thread. The counts do not depend on the machine's load,
# which is why they stand in for `perf stat` here: this VM exposes no
# hardware counters (`perf stat -e instructions` reads <not supported>).
#
#   xtask/cachegrind/counts.sh rays [N_RAYS]       (default 100000)
#       `lucent-bench rays` on the first N_RAYS of each ray file of the
#       Embree comparison (bunny and dragon: 1 M random rays, frame-filling
#       primary rays at 1.2 radii), closest hit and any hit. One pass is
#       the difference of two runs, --reps 2 minus --reps 1, so loading and
#       BVH builds cancel; any hit is (--occluded, --reps 2 minus --reps 1)
#       minus the closest-hit pass.
#   xtask/cachegrind/counts.sh samples [SCENES]    (default "cornell,seed,heavy")
#       `lucent render` of each scene at 64x64 path traced: (--spp 6) minus
#       (--spp 2), divided by 4 * 64 * 64 samples (render, film and all);
#       RENDER_ARGS adds arguments to each render (the lane tracer, the
#       default, runs its AVX2 copy under valgrind, which hides AVX-512, and
#       packet queries run in the AVX2 lanes; RENDER_ARGS=--lanes=false
#       counts the scalar tracer).
#
# env: LUCENT=path/to/lucent, LUCENT_BENCH=path/to/lucent-bench (binaries to
#      count instead of this checkout's release builds; give an older build's
#      to count "before")
#      PEER=/tmp/embree-peer (where xtask/embree/compare.sh left its ray files)
#      ASSETS=<repo>/../shared/assets (the shared meshes)
#      OUT=/tmp/lucent-counts (scratch: truncated ray files)
#      LL=SIZE,ASSOC,LINE (cachegrind's simulated last level; by default it
#      copies the host's L3, 32 MiB here, which holds these meshes whole, so
#      LL=2097152,16,64 models this VM's 2 MiB L2 per core instead)
#
# Prints one JSON line per case: instructions (Ir), level-1 data misses
# (D1mr + D1mw), last-level misses (LLmr + LLmw: DLL plus ILL) and branch
# mispredictions (Bcm + Bim), each per ray or per sample. Cachegrind models
# the host's caches as it detects them and runs ~50x slower than native.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
MODE=${1:-rays}
PEER=${PEER:-/tmp/embree-peer}
OUT=${OUT:-/tmp/lucent-counts}
ASSETS=${ASSETS:-$ROOT/../shared/assets}
mkdir -p "$OUT"
if [[ -z ${LUCENT:-} || -z ${LUCENT_BENCH:-} ]]; then
  cargo build --release -q -p lucent -p lucent-bench --manifest-path "$ROOT/Cargo.toml"
fi
LUCENT=${LUCENT:-$ROOT/target/release/lucent}
LUCENT_BENCH=${LUCENT_BENCH:-$ROOT/target/release/lucent-bench}

# counts CMD...: "Ir D1 LL branch-mispredictions" of one run of CMD.
counts() {
  local f
  f=$(mktemp "$OUT/cg.XXXXXX")
  if ! valgrind --tool=cachegrind --cache-sim=yes --branch-sim=yes ${LL:+--LL=$LL} --cachegrind-out-file="$f" "$@" >/dev/null 2>"$f.err"; then
    echo "failed under cachegrind: $*" >&2
    tail -5 "$f.err" >&2
    exit 1
  fi
  rm -f "$f.err"
  # The summary line's events, in the order of the "events:" line.
  python3 - "$f" <<'PY'
import sys
ev = tot = None
for line in open(sys.argv[1]):
    if line.startswith("events:"):
        ev = line.split()[1:]
    elif line.startswith("summary:"):
        tot = [int(x) for x in line.split()[1:]]
c = dict(zip(ev, tot))
print(c["Ir"], c["D1mr"] + c["D1mw"], c["DLmr"] + c["DLmw"] + c["ILmr"], c["Bcm"] + c["Bim"])
PY
  rm -f "$f"
}

# per A B N: (A - B) / N for each of the four counts, as JSON fields.
per() {
  python3 - "$1" "$2" "$3" <<'PY'
import sys
a, b, n = [int(x) for x in sys.argv[1].split()], [int(x) for x in sys.argv[2].split()], float(sys.argv[3])
d = [(x - y) / n for x, y in zip(a, b)]
print('"instructions":%.1f,"d1_misses":%.3f,"ll_misses":%.4f,"branch_mispredictions":%.3f' % tuple(d))
PY
}

case $MODE in
  rays)
    N=${2:-100000}
    declare -A MESH=([bun_zipper]=$ASSETS/stanford-bunny/bun_zipper.ply [dragon]=$ASSETS/stanford-dragon-100k/dragon.ply)
    for n in bun_zipper dragon; do
      for set in random close; do
        src=$PEER/out/$n.$set.rays
        [[ -f $src ]] || { echo "no $src: run xtask/embree/compare.sh first" >&2; exit 2; }
        rays=$OUT/$n.$set.$N.rays
        [[ -f $rays ]] || head -c $((N * 24)) "$src" >"$rays"
        run=("$LUCENT_BENCH" rays --mesh "${MESH[$n]}" --rays "$rays" --threads 1)
        one=$(counts "${run[@]}" --reps 1)
        two=$(counts "${run[@]}" --reps 2)
        occ_one=$(counts "${run[@]}" --occluded "$OUT/occ" --reps 1)
        occ_two=$(counts "${run[@]}" --occluded "$OUT/occ" --reps 2)
        echo "{\"case\":\"$n.$set\",\"query\":\"closest\",\"rays\":$N,$(per "$two" "$one" "$N")}"
        # Any hit: the --occluded runs' extra pass minus the closest-hit pass.
        anyhit=$(python3 -c 'import sys; a,b,c,d=[[int(x) for x in s.split()] for s in sys.argv[1:]]; print(" ".join(str(w-x-(y-z)) for w,x,y,z in zip(a,b,c,d)))' \
          "$occ_two" "$occ_one" "$two" "$one")
        echo "{\"case\":\"$n.$set\",\"query\":\"any\",\"rays\":$N,$(per "$anyhit" "0 0 0 0" "$N")}"
      done
    done
    ;;
  samples)
    SCENES=${2:-cornell,seed,heavy}
    for scene in ${SCENES//,/ }; do
      case $scene in
        cornell) toml=$ROOT/res/scenes/cornell-mitsuba.toml ;;
        seed) toml=$ROOT/res/scenes/seed-mitsuba.toml ;;
        heavy) toml=$ROOT/res/scenes/heavy.toml ;;
        *) echo "unknown scene '$scene' (cornell, seed, heavy)" >&2; exit 2 ;;
      esac
      # shellcheck disable=SC2206 # RENDER_ARGS is split into arguments on purpose
      run=("$LUCENT" -q render "$toml" --integrator path --size 64x64 --threads 1 --seed 1 -o "$OUT/counts.png" ${RENDER_ARGS:-})
      two=$(counts "${run[@]}" --spp 2)
      six=$(counts "${run[@]}" --spp 6)
      echo "{\"scene\":\"$scene\",\"args\":\"${RENDER_ARGS:-}\",\"size\":\"64x64\",\"samples\":$((4 * 64 * 64)),$(per "$six" "$two" $((4 * 64 * 64)))}"
    done
    ;;
  *)
    echo "usage: $0 rays [N_RAYS] | samples [SCENES]" >&2
    exit 2
    ;;
esac
