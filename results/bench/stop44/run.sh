#!/usr/bin/env bash
# Stop 44: every figure the README states for this stop, from a fresh run on the final code against stop 43's final tree
# (214216e), alternately; plus the kernel-boundary analysis (scripts/bench_kernel_boundary.py) on both trees.
# Usage, from outside the checkout: run.sh REF TEST OUT  (REF: stop 43's final tree 214216e)
set -u
REF=$1; TEST=$2; OUT=$3; D=$(cd "$(dirname "$0")" && pwd)/../stop43/fresh; S=$D/../../../../scripts
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for c in batched batched-expert intersection; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 3 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
python $S/bench_trees.py $REF $TEST --case ring --reps 2 --out $OUT/trees_ring.json > $OUT/trees_ring.txt 2>&1
for t in $REF $TEST; do
  PYTHONPATH=$t python $D/../bench_intersection_pairs.py >> $OUT/bench_intersection_pairs.txt 2>&1
  echo "== $t" >> $OUT/batched_actions.txt; PYTHONPATH=$t python $D/../batched_actions.py >> $OUT/batched_actions.txt 2>&1
done
# settings and seeds not used for any stop-43 figure
for setting in "multi-vp 2400 17" "single-vp 2000 21" "fcfs 2600 23"; do
  for t in $REF $TEST; do
    echo "$(basename $t) $setting $(PYTHONPATH=$t python $D/../../stop40/other/intersection_settings.py $setting)" >> $OUT/unseen_intersection.txt
  done
done
for e in 0 1; do
  for t in $REF $TEST; do
    echo "$(basename $t) expert=$e $(PYTHONPATH=$t python $S/bench_batched_settings.py $e)" >> $OUT/unseen_batched.txt
  done
done
PYTHONPATH=$TEST python $S/new_seed_hashes.py $TEST > $OUT/new_seed_hashes_test.txt 2>&1
PYTHONPATH=$REF python $S/new_seed_hashes.py $REF > $OUT/new_seed_hashes_ref.txt 2>&1
PYTHONPATH=$TEST python -m icv_envs.cli bench intersection > $OUT/bench_intersection.txt 2>&1
for api in dicts lean rows; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api 2>/dev/null | tail -1 >> $OUT/vs_sumo.jsonl
done
PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --seconds 600 2>/dev/null | tail -1 > $OUT/bench_highway_ramps_600.json
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 > $OUT/dict_layer.txt 2>&1
for t in $REF $TEST; do
  echo "== $t" >> $OUT/kernel_boundary.txt
  PYTHONPATH=$t python $S/bench_kernel_boundary.py --out $OUT/kernel_boundary_$(basename $t).json >> $OUT/kernel_boundary.txt 2>&1
done
