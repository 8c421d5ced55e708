#!/usr/bin/env bash
# Stop 46: every speed figure of this stop, on this machine (the 2-core AMD EPYC VM of stop 45), both trees
# alternately: stop 45's final tree (9d843e9) and this stop's. Stop 45's round (its run.sh, the same cases), then
# the batched cases with the expert of stop 46 (pairs.sh).
# Usage, from outside the checkout: run.sh REF TEST OUT
set -u
REF=$1; TEST=$2; OUT=$3; H=$(cd "$(dirname "$0")" && pwd)
bash $H/../stop45/run.sh $REF $TEST $OUT
sh $H/pairs.sh $REF $TEST 3 > $OUT/batched_expert_pairs.txt 2>&1
sh $H/pairs.sh $REF $TEST 2 --config '{"scenario": "lane-drop"}' --worlds 8 --seed 7 > $OUT/unseen_lane_drop.txt 2>&1
sh $H/pairs.sh $REF $TEST 2 --config '{"scenario": "off-ramp"}' --worlds 16 --seed 11 > $OUT/unseen_off_ramp.txt 2>&1
sh $H/pairs.sh $REF $TEST 2 --env highway_ramps --config '{"vgr": 0.5, "duration": 200.0}' --worlds 4 --seed 5 > $OUT/unseen_ring.txt 2>&1
