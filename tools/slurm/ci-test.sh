#!/usr/bin/env bash
# CI test of the Slurm scripts on a real single-node Slurm (issue 19): starts munged, slurmctld
# and slurmd on localhost (local-cluster.sh), submits a 4-shard map of a tiny synthetic DEM and
# its merge (submit.sh), byte-compares the merged maps with a single `penumbra map` run, then
# deletes one shard, re-runs only that array task and merges again: the same bytes.
# Skips with a printed reason when Slurm cannot be started (not root, packages missing).
# Usage: tools/slurm/ci-test.sh [PENUMBRA_BINARY]   (default target/release/penumbra)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=$(realpath "${1:-$root/target/release/penumbra}")
here="$root/tools/slurm"
for tool in sbatch slurmctld slurmd munged; do
  if ! command -v "$tool" >/dev/null; then
    echo "slurm test: SKIPPED ($tool not installed: apt-get install slurm-wlm munge)"
    exit 0
  fi
done
if [ "$(id -u)" != 0 ]; then
  echo "slurm test: SKIPPED (starting slurmctld/slurmd here needs root)"
  exit 0
fi
work=$(mktemp -d /tmp/penumbra-slurm.XXXXXX)
state="$work/state"
cleanup() {
  local status=$?
  "$here/local-cluster.sh" stop "$state" || true
  if [ "$status" -ne 0 ]; then
    tail -n 5 "$work"/maps.parts/logs/*.out "$state"/log/*.log 2>/dev/null >&2 || true
    echo "slurm test: FAILED (exit $status; files kept in $work)"
  elif [ "${KEEP:-0}" != 1 ]; then
    # A daemon still finishing its state files must not turn a passed test into a failure.
    rm -rf "$work" 2>/dev/null || { sleep 2; rm -rf "$work" 2>/dev/null; } ||
      echo "slurm test: note: could not remove $work" >&2
  fi
}
trap cleanup EXIT
eval "$("$here/local-cluster.sh" start "$state")"
export SLURM_CONF PENUMBRA="$bin"
cd "$work"

"$bin" --quiet dem synth --size 96 --px-m 200 --seed 5 --out dem.tif
args=(--dem "$work/dem.tif" --start 2025-01-01 --stop 2025-03-01 --step 6h --engine horizons
  --azimuths 90 --kernels "$root/kernels")
t0=$(date +%s%N)
"$bin" --quiet map "${args[@]}" --out-dir single
t1=$(date +%s%N)
SUBMIT_WAIT=1 "$here/submit.sh" 4 "$work/maps" "${args[@]}"
t2=$(date +%s%N)

compare() {
  local n=0
  for f in single/*; do
    name=$(basename "$f")
    [ "$name" = run.json ] && continue
    if ! cmp -s "$f" "maps/$name"; then
      echo "slurm test: FAILED: $name differs from the single run" >&2
      exit 1
    fi
    n=$((n + 1))
  done
  [ "$n" -ge 20 ] || { echo "slurm test: FAILED: only $n map files" >&2; exit 1; }
  echo "$n files identical"
}
secs() { printf "%d.%01d" $(($1 / 1000000000)) $(($1 % 1000000000 / 100000000)); }
echo "slurm test: single run $(secs $((t1 - t0))) s; 4 shards + merge through Slurm $(secs $((t2 - t1))) s; $(compare)"

# A shard that died: its folder gone; re-run only that array task, merge again.
rm -rf maps.parts/shard-2 maps
if "$bin" --quiet merge --out-dir maps maps.parts/shard-{0,1,2,3} 2>merge-refused.txt; then
  echo "slurm test: FAILED: a merge with a missing shard succeeded" >&2
  exit 1
fi
grep -q "no such folder" merge-refused.txt
sbatch --parsable --wait --array=2 --export=ALL,PARTS=maps.parts,SHARDS=4 \
  --output=maps.parts/logs/rerun-%a.out "$here/penumbra-shard.sbatch" "${args[@]}" >/dev/null
sbatch --parsable --wait --export=ALL,PARTS=maps.parts,SHARDS=4,OUT=maps \
  --output=maps.parts/logs/merge2.out "$here/penumbra-merge.sbatch" >/dev/null
echo "slurm test: shard 2 re-run alone, merged again: $(compare)"
echo "slurm test: PASSED"
