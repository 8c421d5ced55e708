#!/usr/bin/env bash
# Stop 51: the figures of this stop, this tree (TEST) against stop 50's (REF, 454fc25), alternately where a figure
# compares trees. Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
PIN="X86_V4 AVX512_ICL"
cd /tmp
python $S/bench_trees.py $REF $TEST --case batched --reps 6 > $OUT/trees_batched.txt 2>&1
NPY_DISABLE_CPU_FEATURES="$PIN" python $S/compare_trees.py $REF $TEST > $OUT/compare_trees_pinned.txt 2>&1
python $S/compare_trees.py $REF $TEST > $OUT/compare_trees_native.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched-expert --reps 4 > $OUT/trees_batched-expert.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 3 --worlds 8 --vehicles 30 --seed 7 > $OUT/trees_batched_8x30_s7.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 3 --worlds 12 --vehicles 25 --seed 21 > $OUT/trees_batched_12x25_s21.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 3 --worlds 10 --vehicles 24 --seed 33 > $OUT/trees_batched_10x24_s33.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched-expert --reps 3 --worlds 10 --vehicles 24 --seed 33 > $OUT/trees_batched-expert_10x24_s33.txt 2>&1
NPY_DISABLE_CPU_FEATURES="$PIN" python $S/bench_trees.py $REF $TEST --case ring --reps 3 > $OUT/trees_ring_pinned.txt 2>&1
PYTHONPATH=$TEST python $S/bench_kernel_boundary.py --case batched --out $OUT/kernel_boundary_batched.json > $OUT/kernel_boundary_batched.txt 2>&1
python $S/bench_sumo_pairs.py $REF $TEST --runs 3 > $OUT/sumo_pairs.txt 2>&1
for t in $REF $TEST; do
  PYTHONPATH=$t python $S/new_seed_hashes.py $t > $OUT/new_seed_hashes_native_$(basename $t).txt 2>&1
done
python $S/bench_trees.py $REF $TEST --case intersection-rows --reps 2 > $OUT/trees_intersection-rows.txt 2>&1
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 > $OUT/dict_layer.txt 2>&1
PYTHONPATH=$TEST python $(dirname "$0")/pieces.py > $OUT/pieces.txt 2>&1
echo done > $OUT/DONE
