#!/usr/bin/env bash
# Stop 48: every speed figure of this stop, on this machine (the 2-core AMD EPYC VM of stops 45-47). Only the
# intersection's frame kernel changed: its figures compare this tree with stop 47's alternately (and twin envs in
# one process, ab_frames.py); the highway bars are this tree alone (their code is stop 47's).
# Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; S=$(cd "$(dirname "$0")/../../../scripts" && pwd); H=$(cd "$(dirname "$0")" && pwd)
H47=$(cd "$(dirname "$0")/../stop47" && pwd)
mkdir -p "$OUT" && OUT=$(cd "$OUT" && pwd)
cd /tmp
python $S/compare_trees.py $REF $TEST > $OUT/compare_trees.txt 2>&1
for t in $REF $TEST; do
  PYTHONPATH=$t python $S/new_seed_hashes.py $t > $OUT/new_seed_hashes_$(basename $t).txt 2>&1
done
# twin envs in one process, this tree's frame kernel against the reference's (copies in oldkern)
bash $H/make_oldkern.sh $REF $OUT/oldk
for s in "multi-vp 2200 0" "multi-vp 2200 1" "multi-vp 2200 2" "single-vp 2500 22" "fcfs 2000 23" "multi-vp 2800 24" \
         "multi-vp 3000 11" "single-vp 2000 12" "fcfs 2500 13" "multi-vp 1500 14"; do
  PYTHONPATH=$TEST python $H/ab_frames.py --old $OUT/oldk $s >> $OUT/ab_frames.txt 2>&1
done
# the frame kernel's own time per call on the same captured calls, both trees (replay)
for t in $REF $TEST; do
  PYTHONPATH=$t python $H/replay_intersection.py > $OUT/replay_$(basename $t).txt 2>&1
done
# the bench's own windows (seeds 0-2, 100 s warm-up, 500 s timed), both trees, array path and dicts
for seed in 0 1 2; do
  for api in rows dicts; do
    python $H47/int_pairs.py $REF $TEST --seed $seed --seconds 500 --reps 2 --api $api >> $OUT/bench_windows_$api.txt 2>&1
  done
done
for t in $REF $TEST; do
  for api in rows dicts; do
    PYTHONPATH=$t python -m icv_envs.cli bench intersection --api $api 2>/dev/null | tail -1 > $OUT/bench_intersection_${api}_$(basename $t).json
  done
done
PYTHONPATH=$TEST python -m icv_envs.cli bench intersection --api lean 2>/dev/null | tail -1 > $OUT/bench_intersection_lean.json
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
