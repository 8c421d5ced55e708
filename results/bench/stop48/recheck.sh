#!/usr/bin/env bash
# Stop 48's recheck on the final code (the ring's collision order added after the round): the whole-run
# comparison and the ring's in-process A/B against stop 47's tree, then the bars again on this tree.
# Usage, from outside the checkout: recheck.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd); H=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
PYTHONPATH=$TEST python -c "
from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.envs import highway_ramps_v0
e = parallel_env(duration=30); e.reset(seed=0)
for _ in range(100): e.step_rows(e.core.expert_actions())
h = highway_ramps_v0.parallel_env(vgr=1/3, duration=20); h.reset(seed=0)
for _ in range(20): h.step_rows(h.core.expert_actions())" > /dev/null 2>&1
python $S/compare_trees.py $REF $TEST > $OUT/compare_trees.txt 2>&1
PYTHONPATH=$TEST python $S/new_seed_hashes.py $TEST > $OUT/new_seed_hashes_final.txt 2>&1
bash $H/make_oldkern.sh $REF $OUT/oldk
for s in 0 1 2 3; do
  PYTHONPATH=$TEST python $H/ab_ring.py --old $OUT/oldk $s >> $OUT/ab_ring.txt 2>&1
done
for s in "multi-vp 2200 0" "fcfs 2000 23"; do
  PYTHONPATH=$TEST python $H/ab_frames.py --old $OUT/oldk $s >> $OUT/ab_frames.txt 2>&1
done
for api in dicts lean rows; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench highway-ramps --vs-sumo --api $api 2>/dev/null | tail -1 >> $OUT/vs_sumo.jsonl
done
for c in batched batched-expert; do
  python $S/bench_trees.py $REF $TEST --case $c --reps 3 --out $OUT/trees_$c.json > $OUT/trees_$c.txt 2>&1
done
for api in rows dicts; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench intersection --api $api 2>/dev/null | tail -1 > $OUT/bench_intersection_$api.json
done
echo done > $OUT/DONE
# then, the host being quiet: the batched case with the expert again, and the intersection's array path twice more
python $S/bench_trees.py $REF $TEST --case batched-expert --reps 3 --out $OUT/trees_batched-expert_again.json > $OUT/trees_batched-expert_again.txt 2>&1
for i in 1 2; do
  PYTHONPATH=$TEST python -m icv_envs.cli bench intersection --api rows 2>/dev/null | tail -1 >> $OUT/bench_intersection_rows_again.jsonl
done
echo done > $OUT/DONE2
