#!/usr/bin/env bash
# Stop 55: the bars again on this session's machine, one sitting: the ring against SUMO through each API
# (alternating dicts, lean, rows, three rounds), the batched worlds (icv-envs bench train's batched part, twice),
# the intersection through each API (twice more; the first pair is round/intersection_*_1), the dict layer.
# Usage: run.sh TREE OUT
set -u
T=$1; OUT=$2; S=$(cd "$(dirname "$0")/../../../scripts" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
for i in 1 2 3; do
  for api in dicts lean rows; do
    PYTHONPATH=$T python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api --out $OUT/ring_${api}_$i > $OUT/ring_${api}_$i.log 2>&1
  done
done
for i in 1 2; do
  PYTHONPATH=$T python -m icv_envs.rl.bench --env-steps 2000 --ppo-steps 2048 --no-reference --out $OUT/train_$i > $OUT/train_$i.log 2>&1
done
for i in 2 3; do
  PYTHONPATH=$T python -m icv_envs.cli bench intersection --out $OUT/intersection_dicts_$i > $OUT/intersection_dicts_$i.log 2>&1
  PYTHONPATH=$T python -m icv_envs.cli bench intersection --api rows --out $OUT/intersection_rows_$i > $OUT/intersection_rows_$i.log 2>&1
done
PYTHONPATH=$T python $S/bench_dict_layer.py --vehicles 800 --steps 100 > $OUT/dict_layer.txt 2>&1
echo done > $OUT/DONE
