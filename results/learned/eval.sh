#!/usr/bin/env bash
# Evaluate the scripted and the learned policies with the harness, 5 episodes,
# seeds 100-104, on the same scenarios. Run from the repo root after train.sh:
# bash results/learned/eval.sh && python results/learned/make_table.py
set -euo pipefail
OUT=results/learned
E=$OUT/eval
INT='{"throughput": 1500, "duration": 120, "warmup": 80}'
ev() {  # ev DIR ENV POLICY CONFIG
    icv-envs evaluate --env "$2" --policy "$3" --episodes 5 --seed 100 --config "$4" --out "$E/$1" | tail -1 > /dev/null
    echo "$1"
}
# highway formation, every ICV driven by the policy (PettingZoo env), lane-drop and on-ramp
for sc in lane-drop on-ramp; do
    cfg="{\"scenario\": \"$sc\"}"
    for p in expert zero random; do ev "highway_$sc/$p" icv_envs/highway_formation-v0 "$p" "$cfg"; done
    for m in bc_expert_highway ppo_shared_lanedrop ppo_single_lanedrop; do
        ev "highway_$sc/$m" icv_envs/highway_formation-v0 "$OUT/$m" "$cfg"
    done
done
# highway formation, one ego driven by the policy among expert ICVs (Gymnasium id), lane-drop
cfg='{"scenario": "lane-drop"}'
for p in expert zero random; do ev "highway_ego_lane-drop/$p" icv_envs/HighwayFormation-v0 "$p" "$cfg"; done
for m in ppo_single_lanedrop bc_expert_highway ppo_shared_lanedrop; do
    ev "highway_ego_lane-drop/$m" icv_envs/HighwayFormation-v0 "$OUT/$m" "$cfg"
done
# intersection, every vehicle driven by the policy
for p in expert single-vp fcfs zero random; do ev "intersection/$p" icv_envs/intersection-v0 "$p" "$INT"; done
for m in bc_expert_intersection ppo_shared_intersection; do
    ev "intersection/$m" icv_envs/intersection-v0 "$OUT/$m" "$INT"
done
