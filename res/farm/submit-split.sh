#!/bin/bash
# Submits a split render to Slurm: an array job of N shares, then a merge
# job that runs once all of them succeeded. Prints the two job ids.
#
#   res/farm/submit-split.sh N SCENE OUTDIR [lucent render flags...]
#
# e.g. res/farm/submit-split.sh 8 res/scenes/seed.toml out --preset reference
# Extra sbatch options (partition, time, account) go in $SBATCH_OPTS.
set -euo pipefail
n=$1 scene=$2 outdir=$3
shift 3
here=$(dirname "$0")
# shellcheck disable=SC2086
array=$(sbatch --parsable ${SBATCH_OPTS:-} --array="1-$n" "$here/split.sbatch" "$scene" "$outdir" "$@")
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_OPTS:-} --dependency="afterok:$array" "$here/merge.sbatch" "$outdir")
echo "$array $merge"
