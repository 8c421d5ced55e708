#!/usr/bin/env bash
# Stop 54: every bar of issue 10 re-measured in one sitting on this session's machine (a new VM). TEST = this
# stop's tree, REF = stop 53's (c0ef7e4): their stepping code is the same (this stop changes how the benches
# time, not what they step), so the paired ratios are this host's noise floor. Usage, from outside the
# checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
# numba's cache of both trees filled first (not timed)
for t in $REF $TEST; do
  PYTHONPATH=$t python -m icv_envs.cli bench intersection --seconds 10 --warmup 60 --seeds 1 > /dev/null 2>&1
  PYTHONPATH=$t python -m icv_envs.rl.bench --env-steps 200 --ppo-steps 512 --no-reference > /dev/null 2>&1
  PYTHONPATH=$t python -m icv_envs.cli bench highway-ramps --vs-sumo --seconds 60 > /dev/null 2>&1
done
for c in batched batched-expert intersection intersection-rows; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 4 --out $OUT/trees_$c.txt > $OUT/trees_$c.log 2>&1
done
python $S/bench_trees.py $REF $TEST --case batched --reps 6 --steps 300 --out $OUT/trees_batched_300.txt > $OUT/trees_batched_300.log 2>&1
for i in 1 2 3; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api dicts --out $OUT/ring_dicts_$i > $OUT/ring_dicts_$i.log 2>&1
done
for api in lean rows; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api --out $OUT/ring_$api > $OUT/ring_$api.log 2>&1
done
for i in 1 2; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench intersection --out $OUT/intersection_dicts_$i > $OUT/intersection_dicts_$i.log 2>&1
  PYTHONPATH=$TEST python -m icv_envs.cli bench intersection --api rows --out $OUT/intersection_rows_$i > $OUT/intersection_rows_$i.log 2>&1
  PYTHONPATH=$TEST python -m icv_envs.rl.bench --out $OUT/train_$i > $OUT/train_$i.log 2>&1
done
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 --steps 100 > $OUT/dict_layer.txt 2>&1
PYTHONPATH=$TEST python $S/bench_dict_layer.py --vehicles 800 --steps 100 --info-keys= > $OUT/dict_layer_nokeys.txt 2>&1
PYTHONPATH=$TEST /usr/bin/time -v python -m icv_envs.cli bench highway-ramps --seconds 600 > $OUT/ring_memory.log 2>&1
PYTHONPATH=$TEST python -m icv_envs.experiments.sumo_bench scaling --out $OUT/scaling > $OUT/scaling.log 2>&1
echo done > $OUT/DONE
