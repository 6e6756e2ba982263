#!/bin/bash
# What splitting a render costs: one `lucent render` against the sum of its
# N shares (`--part K/N`, run one after the other), then `lucent merge`:
# wall time, CPU time (user + system) and peak memory from /usr/bin/time,
# and a cmp of the merged files against the single render's.
#
#   xtask/farm/split-cost.sh [N] [ROUNDS] [lucent render flags...]
#
# defaults: 4 shares, 1 round, the seed scene path traced at 1920x1080,
# 4 spp, max depth 8. Uses target/release/lucent (build it first) and the
# bench lock, as every timing here does.
set -euo pipefail
cd "$(dirname "$0")/../.."
n=${1:-4} rounds=${2:-1}
shift $(( $# < 2 ? $# : 2 ))
flags=("$@")
[ ${#flags[@]} -gt 0 ] || flags=(res/scenes/seed.toml --size 1920x1080 --spp 4 --integrator path --max-depth 8)
lucent=$PWD/target/release/lucent
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
t() { /usr/bin/time -f "%e %M %U %S" -o "$d/t" "$@" > "$d/out" 2>/dev/null; cat "$d/t"; }
exec 9>/tmp/lucent-bench.lock
flock 9
uptime
for round in $(seq 1 "$rounds"); do
  read -r wall rss user sys < <(t "$lucent" render "${flags[@]}" -o "$d/one.png" --exr "$d/one.exr")
  echo "round $round: one render: wall $wall s, cpu $(echo "$user + $sys" | bc) s, peak $((rss / 1024)) MiB"
  sum=0 cpu=0
  for k in $(seq 1 "$n"); do
    read -r wall rss user sys < <(t "$lucent" render "${flags[@]}" --part "$k/$n" --partial "$d/p.$k.lpart")
    sum=$(echo "$sum + $wall" | bc) cpu=$(echo "$cpu + $user + $sys" | bc)
  done
  echo "round $round: $n parts: wall $sum s, cpu $cpu s, $(stat -c %s "$d/p.1.lpart") bytes each"
  read -r wall rss user sys < <(t "$lucent" merge "$d"/p.*.lpart -o "$d/m.png" --exr "$d/m.exr")
  echo "round $round: merge: wall $wall s, cpu $(echo "$user + $sys" | bc) s, peak $((rss / 1024)) MiB"
  cmp "$d/m.png" "$d/one.png" && cmp "$d/m.exr" "$d/one.exr" && echo "round $round: merged PNG and EXR identical"
  rm -f "$d"/p.*.lpart
done
uptime
