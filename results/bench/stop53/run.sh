#!/usr/bin/env bash
# Stop 53: the figures of this stop. This tree (TEST) against stop 52's (REF, daeeb79), the pairs' order alternating
# (bench_trees.py); then this tree alone: the ring against SUMO through each API, its peak memory without SUMO,
# the scaling curve. Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd); H=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
PIN="X86_V4 AVX512_ICL"
cd /tmp
NPY_DISABLE_CPU_FEATURES="$PIN" python $S/compare_trees.py $REF $TEST > $OUT/compare_pinned_a.txt 2>&1
python $S/compare_trees.py $REF $TEST > $OUT/compare_native_a.txt 2>&1
python $S/bench_trees.py $REF $TEST --case batched-noisy --reps 6 --out $OUT/trees_batched-noisy_abba.txt \
  > $OUT/trees_batched-noisy_abba.log 2>&1
python $S/bench_trees.py $REF $TEST --case batched-noisy --reps 4 --worlds 10 --vehicles 24 --seed 33 \
  --out $OUT/trees_batched-noisy_10x24_s33.txt > $OUT/trees_batched-noisy_10x24_s33.log 2>&1
python $S/bench_trees.py $REF $TEST --case batched-uniform --reps 4 --out $OUT/trees_batched-uniform.txt \
  > $OUT/trees_batched-uniform.log 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 4 --out $OUT/trees_batched.txt > $OUT/trees_batched.log 2>&1
for t in $REF $TEST $REF $TEST; do echo "$t $(PYTHONPATH=$t python $H/reform_cost.py noisy)" >> $OUT/reform_cost_noisy.txt; done
for t in $REF $TEST $TEST $REF; do echo "$t $(PYTHONPATH=$t python $H/reform_cost.py ring)" >> $OUT/reform_cost_ring.txt; done
python $S/bench_trees.py $REF $TEST --case batched-noisy --reps 8 --steps 300 --out $OUT/trees_batched-noisy_300_c.txt > $OUT/trees_batched-noisy_300_c.log 2>&1
python $S/bench_trees.py $REF $TEST --case batched-uniform --reps 8 --steps 300 --worlds 12 --vehicles 25 --seed 21 --out $OUT/trees_batched-uniform_12x25_s21_300_c.txt > /dev/null 2>&1
python $S/bench_trees.py $REF $TEST --case batched --reps 6 --steps 300 --out $OUT/trees_batched_300_c.txt > /dev/null 2>&1
python $H/instr_count.py $REF $TEST > $OUT/instr_count.txt 2>&1
python $H/instr_count.py $TEST $TEST --kinds noisy > $OUT/instr_count_same_tree.txt 2>&1
python $H/instr_count.py $REF $TEST --kinds noisy,uniform --worlds 10 --vehicles 24 --seed 33 > $OUT/instr_count_10x24_s33.txt 2>&1
python $H/instr_count.py $REF $TEST --kinds ring --warm 2500 --steps 50 > $OUT/instr_count_ring.txt 2>&1
python $H/instr_count.py $REF $TEST --kinds intersection --steps 200 > $OUT/instr_count_intersection.txt 2>&1
python $H/instr_split.py $TEST --kind zero > $OUT/instr_split_zero.txt 2>&1
for t in $REF $TEST; do python $H/instr_split.py $t --kind noisy > $OUT/instr_split_noisy_$(basename $t).txt 2>&1; done
PYTHONPATH=$REF python $H/event_kinds.py > $OUT/event_kinds_stop52.txt 2>&1
PYTHONPATH=$TEST python $H/event_kinds.py > $OUT/event_kinds_stop53.txt 2>&1
PYTHONPATH=$REF python $S/new_seed_hashes.py $REF > $OUT/new_seed_hashes_native_stop52.txt 2>&1
PYTHONPATH=$TEST python $S/new_seed_hashes.py $TEST > $OUT/new_seed_hashes_native_stop53.txt 2>&1
# this tree alone (the bench extra: eclipse-sumo, libsumo)
mkdir -p $OUT/current
for api in lean rows dicts; do
  PYTHONPATH=$TEST icv-envs bench highway-ramps --vs-sumo --api $api --out $OUT/current/ring_$api > $OUT/current/ring_$api.log 2>&1
done
PYTHONPATH=$TEST python -m icv_envs.experiments.sumo_bench scaling --out $OUT/current/scaling > $OUT/current/scaling.log 2>&1
PYTHONPATH=$TEST icv-envs bench highway-ramps --seconds 600 --out $OUT/current/ring_memory > $OUT/current/ring_memory.log 2>&1
echo done > $OUT/DONE
