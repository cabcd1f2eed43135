#!/usr/bin/env bash
# Submits a sharded `penumbra map` to Slurm: an array job of N shards and a merge job that runs
# when every shard has succeeded (docs/SCALING.md).
#
#   tools/slurm/submit.sh N OUT MAP_ARGS...
#
# Partials go to OUT.parts/shard-I (logs in OUT.parts/logs); the merged maps to OUT. MAP_ARGS are
# `penumbra map`'s arguments without --shard/--out-dir (an epoch range, --engine auto or
# horizons). Environment: PENUMBRA (the binary; default `penumbra` on PATH), SUBMIT_WAIT=1 to
# wait for the merge and exit with its status; sbatch's own SBATCH_* variables (SBATCH_PARTITION,
# SBATCH_TIMELIMIT, SBATCH_ACCOUNT …) apply to both jobs. Prints the two job ids.
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n '2,13p' "$0" >&2
  exit 2
fi
n=$1 out=$2
shift 2
case "$n" in
'' | *[!0-9]* | 0) echo "submit.sh: N must be a positive integer, not '$n'" >&2; exit 2 ;;
esac
here=$(cd "$(dirname "$0")" && pwd)
parts="$out.parts"
mkdir -p "$parts/logs"
export PARTS="$parts" SHARDS="$n" OUT="$out" PENUMBRA="${PENUMBRA:-penumbra}"
array=$(sbatch --parsable --array="0-$((n - 1))" --export=ALL \
  --output="$parts/logs/shard-%a.out" "$here/penumbra-shard.sbatch" "$@")
array=${array%%;*}
wait_flag=()
if [ "${SUBMIT_WAIT:-0}" = 1 ]; then
  wait_flag=(--wait)
fi
echo "array job $array: $n shards -> $parts"
set +e
merge=$(sbatch --parsable "${wait_flag[@]}" --dependency="afterok:$array" --kill-on-invalid-dep=yes \
  --export=ALL --output="$parts/logs/merge.out" "$here/penumbra-merge.sbatch")
status=$?
set -e
echo "merge job ${merge%%;*} -> $out (after $array)"
exit $status
