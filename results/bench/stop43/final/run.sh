#!/usr/bin/env bash
# Stop 43's figures against stop 42's final tree: the intersection bench as it is defined from this stop
# (3 seeds, 500 s after 100 s, bench_intersection_pairs.py: this tree's bench code on each tree), the
# bench_trees cases (batched, batched with the expert, ring, intersection) and the stage timers.
# Usage, from outside the checkout: run.sh REF TEST OUT  (REF: stop 42's final tree 48ce5a6)
set -u
REF=$1; TEST=$2; OUT=$3; D=$(cd "$(dirname "$0")" && pwd); S=$D/../../../../scripts
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for rep in 1 2 3; do
  for t in $REF $TEST; do
    PYTHONPATH=$t python $D/../bench_intersection_pairs.py >> $OUT/bench_intersection_pairs.txt 2>&1
  done
done
for c in batched batched-expert; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 5 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
for c in ring intersection; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 3 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
for t in $REF $TEST; do
  echo "== $t" >> $OUT/stages.txt
  PYTHONPATH=$t python $D/../../stop42/stages.py >> $OUT/stages.txt 2>&1
done
PYTHONPATH=$TEST python -m icv_envs.cli bench intersection > $OUT/bench_intersection.txt 2>&1
