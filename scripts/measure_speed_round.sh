#!/usr/bin/env bash
# One round of the README's Speed figures (issue 10's bars), run from outside the checkout: REF = the
# reference tree (the previous stop's final tree), TEST = the tree measured; both trees alternately where
# paired, every file into OUT. Usage: scripts/measure_speed_round.sh REF TEST OUT
# (stops 38 and 39: results/bench/stop38/final*, results/bench/stop39/{final,rerun})
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for c in ring batched batched-expert intersection; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 3 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
python $S/bench_sumo_pairs.py $REF $TEST --runs 3 --out $OUT/sumo_pairs > $OUT/sumo_pairs.txt 2>&1
for api in rows lean; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api --out $OUT/vs_sumo_$api.json > $OUT/vs_sumo_$api.txt 2>&1
done
for t in $REF $TEST; do
  n=$(basename $t)
  PYTHONPATH=$t python $S/bench_dict_layer.py --vehicles 800 --steps 100 > $OUT/dict_layer_$n.txt 2>&1
  PYTHONPATH=$t python $S/bench_dict_layer.py --vehicles 800 --steps 100 --info-keys= > $OUT/dict_layer_nokeys_$n.txt 2>&1
  PYTHONPATH=$t python -m icv_envs.experiments.sumo_bench scaling --out $OUT/scaling_$n > $OUT/scaling_$n.txt 2>&1
done
PYTHONPATH=$TEST /usr/bin/time -v python -m icv_envs.cli bench highway-ramps --seconds 600 > $OUT/rss_600.txt 2>&1
PYTHONPATH=$TEST python -m icv_envs.cli bench highway-formation > $OUT/bench_highway_formation.txt 2>&1
PYTHONPATH=$TEST python -m icv_envs.cli bench intersection > $OUT/bench_intersection.txt 2>&1

