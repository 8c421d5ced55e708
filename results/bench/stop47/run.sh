#!/usr/bin/env bash
# Stop 47: every speed figure of this stop, on this machine (the 2-core AMD EPYC VM of stops 45-46), both trees
# alternately where the code changed (the intersection), this stop's tree alone where it did not (the highway
# paths: ring, batched worlds, dict layer, memory; their files are untouched since stop 46's 2d55680).
# Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd); H=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
python $S/compare_trees.py $REF $TEST > $OUT/compare_trees.txt 2>&1
for t in $REF $TEST; do
  PYTHONPATH=$t python $S/new_seed_hashes.py $t > $OUT/new_seed_hashes_$(basename $t).txt 2>&1
done
# the intersection: the bench's own windows (seeds 0-2, 100 s warm-up, 500 s timed), both trees, array path and dicts
for seed in 0 1 2; do
  for api in rows dicts; do
    python $H/int_pairs.py $REF $TEST --seed $seed --seconds 500 --reps 1 --api $api >> $OUT/bench_windows_$api.txt 2>&1
  done
done
for c in intersection-rows intersection; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 3 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
for t in $REF $TEST; do
  PYTHONPATH=$t python -m icv_envs.cli bench intersection 2>/dev/null | tail -1 > $OUT/bench_intersection_$(basename $t).json
done
for api in rows lean; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench intersection --api $api 2>/dev/null | tail -1 > $OUT/bench_intersection_${api}.json
done
# not first measured on: other methods, demands and seeds (paired, the same states)
python $H/int_pairs.py $REF $TEST --method multi-vp --throughput 3000 --seed 11 --reps 2 > $OUT/unseen.txt 2>&1
python $H/int_pairs.py $REF $TEST --method single-vp --throughput 2000 --seed 12 --reps 2 >> $OUT/unseen.txt 2>&1
python $H/int_pairs.py $REF $TEST --method fcfs --throughput 2500 --seed 13 --reps 2 >> $OUT/unseen.txt 2>&1
python $H/int_pairs.py $REF $TEST --method multi-vp --throughput 1500 --seed 14 --reps 2 >> $OUT/unseen.txt 2>&1
# the highway bars (code unchanged): this tree, and the batched cases paired as a check of the sitting
for c in batched batched-expert; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 2 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
for api in dicts lean rows; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api 2>/dev/null | tail -1 >> $OUT/vs_sumo.jsonl
done
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 > $OUT/dict_layer.txt 2>&1
PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --seconds 600 2>/dev/null | tail -1 > $OUT/bench_highway_ramps_600.json
echo done > $OUT/DONE
