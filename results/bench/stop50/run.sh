#!/usr/bin/env bash
# Stop 50: the bars on this tree, on this machine (the 2-core AMD EPYC VM of stops 45-49), with stop 49's tree
# (REF) beside it where a figure compares trees. The highway trajectories differ natively between the trees on this
# AVX-512 machine (the join search's start, cbrt, is libm's inside plan_pass, NumPy's SIMD one before); pinned at
# X86_V3 they are the same (compare_trees_pinned.txt). The batched pairs are in ../final/ (bench_trees.py).
# Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
PIN="X86_V4 AVX512_ICL"
cd /tmp
NPY_DISABLE_CPU_FEATURES="$PIN" python $S/compare_trees.py $REF $TEST > $OUT/compare_trees_pinned.txt 2>&1
python $S/compare_trees.py $REF $TEST > $OUT/compare_trees_native.txt 2>&1
for t in $REF $TEST; do
  NPY_DISABLE_CPU_FEATURES="$PIN" PYTHONPATH=$t python $S/new_seed_hashes.py $t > $OUT/new_seed_hashes_pinned_$(basename $t).txt 2>&1
done
for t in $REF $TEST; do
  for api in rows dicts; do
    PYTHONPATH=$t python -m icv_envs.cli bench intersection --api $api 2>/dev/null | tail -1 > $OUT/bench_intersection_${api}_$(basename $t).json
  done
done
for api in dicts lean rows; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api 2>/dev/null | tail -1 >> $OUT/vs_sumo.jsonl
done
PYTHONPATH=$REF python -m icv_envs.cli bench highway-ramps --vs-sumo --api dicts 2>/dev/null | tail -1 > $OUT/vs_sumo_ref_dicts.json
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 > $OUT/dict_layer.txt 2>&1
PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --seconds 600 2>/dev/null | tail -1 > $OUT/bench_highway_ramps_600.json
echo done > $OUT/DONE
