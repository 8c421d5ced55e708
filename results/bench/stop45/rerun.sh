#!/usr/bin/env bash
# Stop 45, after the review: every figure README states for this stop, again from a fresh run on the final code,
# and the discrete-agent figures on settings and seeds they were not first measured on.
# Usage, from outside the checkout: rerun.sh REF PREROWS TEST OUT
#   REF: stop 44's tree (f111f1a); PREROWS: this stop's 4179427 (the batch's discrete actions through the dicts)
set -u
REF=$1; PRE=$2; TEST=$3; OUT=$4; D=$(cd "$(dirname "$0")" && pwd); S=$D/../../../scripts
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for args in "" "--env intersection --seed 11"; do
  for i in 1 2; do for t in $REF $TEST; do
    echo "$(basename $t) [$args] $(PYTHONPATH=$t python $D/discrete_speed.py $args)" >> $OUT/discrete_speed.txt
  done; done
done
for args in "" "--worlds 8 --vehicles 30 --seed 5 --idle-share 0.8"; do
  for i in 1 2; do for t in $PRE $TEST; do
    echo "$(basename $t) [$args] $(PYTHONPATH=$t python $D/batched_discrete_speed.py $args)" >> $OUT/batched_discrete_speed.txt
  done; done
done
for c in batched batched-expert intersection; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 2 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
PYTHONPATH=$TEST python -m icv_envs.cli bench intersection 2>/dev/null | tail -1 > $OUT/bench_intersection.json
for api in dicts lean rows; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api 2>/dev/null | tail -1 >> $OUT/vs_sumo.jsonl
done
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 > $OUT/dict_layer.txt 2>&1
