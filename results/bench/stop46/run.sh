#!/usr/bin/env bash
# Stop 46: every speed figure of this stop, on this machine (the 2-core AMD EPYC VM of stop 45), both trees
# alternately: stop 45's final tree (9d843e9) and this stop's; with the batched expert cases of stop 46 (pairs.sh).
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
H=$(cd "$(dirname "$0")" && pwd)
sh $H/pairs.sh $REF $TEST 3 > $OUT/batched_expert_pairs.txt 2>&1
sh $H/pairs.sh $REF $TEST 2 --config '{"scenario": "lane-drop"}' --worlds 8 --seed 7 > $OUT/unseen_lane_drop.txt 2>&1
sh $H/pairs.sh $REF $TEST 2 --config '{"scenario": "off-ramp"}' --worlds 16 --seed 11 > $OUT/unseen_off_ramp.txt 2>&1
sh $H/pairs.sh $REF $TEST 2 --env highway_ramps --config '{"vgr": 0.5, "duration": 200.0}' --worlds 4 --seed 5 > $OUT/unseen_ring.txt 2>&1
