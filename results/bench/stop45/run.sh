#!/usr/bin/env bash
# Stop 45: every speed figure of this stop, on this machine (a 2-core AMD EPYC VM; stop 44's figures were measured
# on an Intel one), both trees alternately: stop 44's final tree (f111f1a) and this stop's.
# Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for c in batched batched-expert intersection; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 3 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
python $S/bench_trees.py $REF $TEST --case ring --reps 2 --out $OUT/trees_ring.json > $OUT/trees_ring.txt 2>&1
for t in $REF $TEST; do
  n=$(basename $t)
  PYTHONPATH=$t python -m icv_envs.cli bench intersection 2>/dev/null | tail -1 > $OUT/bench_intersection_$n.json
  for api in dicts lean rows; do
    PYTHONPATH=$t python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api 2>/dev/null | tail -1 >> $OUT/vs_sumo_$n.jsonl
  done
  PYTHONPATH=$t python $S/bench_dict_layer.py --vehicles 800 > $OUT/dict_layer_$n.txt 2>&1
  PYTHONPATH=$t python $S/new_seed_hashes.py $t > $OUT/new_seed_hashes_$n.txt 2>&1
done
python $S/compare_trees.py $REF $TEST > $OUT/compare_trees.txt 2>&1
