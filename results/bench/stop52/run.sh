#!/usr/bin/env bash
# Stop 52: the figures of this stop, this tree (TEST) against stop 51's (REF, 4765a18), alternately where a figure
# compares trees. Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd); H=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
PIN="X86_V4 AVX512_ICL"
cd /tmp
python $S/bench_trees.py $REF $TEST --case batched --reps 6 > $OUT/trees_batched.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched-noisy --reps 6 > $OUT/trees_batched-noisy.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched-expert --reps 4 > $OUT/trees_batched-expert.txt 2>&1
NPY_DISABLE_CPU_FEATURES="$PIN" python $S/bench_trees.py $REF $TEST --case ring --reps 4 > $OUT/trees_ring_pinned.txt 2>&1
python $S/bench_sumo_pairs.py $REF $TEST --runs 3 > $OUT/sumo_pairs.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 3 --worlds 8 --vehicles 30 --seed 7 > $OUT/trees_batched_8x30_s7.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched-noisy --reps 3 --worlds 12 --vehicles 25 --seed 21 > $OUT/trees_batched-noisy_12x25_s21.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 3 --worlds 10 --vehicles 24 --seed 33 > $OUT/trees_batched_10x24_s33.txt 2>&1
python $S/bench_trees.py $REF $TEST --case intersection-rows --reps 2 > $OUT/trees_intersection-rows.txt 2>&1
python $S/bench_trees.py $REF $TEST --case intersection --reps 2 > $OUT/trees_intersection.txt 2>&1
for t in $REF $TEST $REF $TEST; do
  echo "$t: $(PYTHONPATH=$t python $H/reset_cost.py)" >> $OUT/reset_cost.txt 2>&1
done
for t in $REF $TEST; do
  PYTHONPATH=$t python $S/new_seed_hashes.py $t > $OUT/new_seed_hashes_native_$(basename $t).txt 2>&1
done
echo done > $OUT/DONE
