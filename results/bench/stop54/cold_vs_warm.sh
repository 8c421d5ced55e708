#!/usr/bin/env bash
# Stop 54: a first run (numba's cache emptied: `git clean -xfd` of a worktree) against the next run of the same tree,
# for the benches whose windows a first run reaches: the ramps bench's real-time factor and peak memory, the
# intersection bench with a short warm-up, the single-agent env. Usage: cold_vs_warm.sh TREE OUT
set -u
T=$1; OUT=$2
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for k in 1 2; do
  (cd $T && git clean -xfdq -- icv_envs)
  for run in first next; do
    PYTHONPATH=$T /usr/bin/time -v python -m icv_envs.cli bench highway-ramps --seconds 600 > $OUT/ramps_${run}_$k.log 2>&1
  done
  (cd $T && git clean -xfdq -- icv_envs)
  for run in first next; do
    PYTHONPATH=$T python -m icv_envs.cli bench intersection --seconds 100 --warmup 50 --seeds 1 > $OUT/intersection_${run}_$k.log 2>&1
  done
done
