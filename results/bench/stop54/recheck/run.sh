#!/usr/bin/env bash
# Stop 54, after the review: the README's figures of this stop from fresh runs of their commands, and the
# stop's claims on settings nothing was looked at on. Usage: run.sh TREE OUT
set -u
T=$1; OUT=$2; H=$(cd "$(dirname "$0")/.." && pwd); S=$(cd "$H/../../../scripts" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
# a first run on an empty cache, another setting: 3000 veh/h, 40 s of warm-up, seeds 0-1
(cd $T && git clean -xfdq -- icv_envs)
for run in first next; do
  PYTHONPATH=$T python -m icv_envs.cli bench intersection --throughput 3000 --warmup 40 --seconds 60 --seeds 2 > $OUT/intersection_3000_$run.log 2>&1
done
for run in first next; do
  PYTHONPATH=$T /usr/bin/time -v python -m icv_envs.cli bench highway-ramps --seconds 600 > $OUT/ramps_$run.log 2>&1
done
# the collector on other seeds
for s in 5 11; do
  PYTHONPATH=$T python $H/gc_scale.py 3200 200 $s >> $OUT/gc_scale_seeds.txt 2>&1
  FREEZE=1 PYTHONPATH=$T python $H/gc_scale.py 3200 200 $s | sed 's/^/gc.freeze() /' >> $OUT/gc_scale_seeds.txt 2>&1
done
PYTHONPATH=$T python $S/bench_dict_layer.py --vehicles 800 --steps 100 > $OUT/dict_layer.txt 2>&1
PYTHONPATH=$T python -m icv_envs.cli bench intersection --api rows --out $OUT/intersection_rows > $OUT/intersection_rows.log 2>&1
PYTHONPATH=$T python -m icv_envs.cli bench intersection --out $OUT/intersection_dicts > $OUT/intersection_dicts.log 2>&1
PYTHONPATH=$T python -m icv_envs.cli bench highway-ramps --vs-sumo --out $OUT/ring_dicts > $OUT/ring_dicts.log 2>&1
PYTHONPATH=$T python -m icv_envs.experiments.sumo_bench scaling --out $OUT/scaling > $OUT/scaling.log 2>&1
echo done > $OUT/DONE
