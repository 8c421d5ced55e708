#!/usr/bin/env bash
# Stop 42's figures: the intersection (the path this stop changed), its other settings, the bench,
# and the batched and ring cases as a check that their paths did not move.
# Usage, from outside the checkout: run.sh REF TEST OUT  (REF: stop 41's final tree b40d6e3)
set -u
REF=$1; TEST=$2; OUT=$3; D=$(cd "$(dirname "$0")" && pwd); S=$D/../../../../scripts
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
python $S/bench_trees.py $REF $TEST --case intersection --reps 5 --out $OUT/trees_intersection.json > $OUT/trees_intersection.txt 2>&1
for setting in "multi-vp 3000 5" "single-vp 2200 2" "fcfs 2200 1"; do
  for rep in 1 2; do
    for t in $REF $TEST; do
      echo "$(basename $t) $(PYTHONPATH=$t python $D/../../stop40/other/intersection_settings.py $setting)" >> $OUT/intersection_settings.txt
    done
  done
done
PYTHONPATH=$TEST python -m icv_envs.cli bench intersection > $OUT/bench_intersection.txt 2>&1
for c in batched ring; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 2 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
