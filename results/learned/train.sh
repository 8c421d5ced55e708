#!/usr/bin/env bash
# The training runs behind results/learned/README_table.md. Run from the repo
# root: bash results/learned/train.sh (then bash results/learned/eval.sh).
# Each run uses one torch thread; they run one after another. Wall seconds
# per run go to results/learned/logs/wall.txt, each run's output to logs/NAME.log.
set -euo pipefail
OUT=results/learned
INT='{"throughput": 1500, "duration": 120, "warmup": 80}'
mkdir -p "$OUT/logs"
: > "$OUT/logs/wall.txt"
t() {
    local name=$1; shift
    local t0; t0=$(date +%s)
    "$@" > "$OUT/logs/$name.log" 2>&1
    echo "$name $(( $(date +%s) - t0 )) s" | tee -a "$OUT/logs/wall.txt"
}

# 1. behaviour cloning + DAgger of the formation expert on all five highway scenarios (default settings:
#    6000 expert env steps, 6 DAgger iterations x 3000 env steps, 10 epochs per fit, MLP 256-256)
t bc_expert_highway python baselines/bc_expert.py --seed 0 --out "$OUT/bc_expert_highway"
# 2. one PPO policy shared by all 8 ICVs, highway lane-drop, 500k agent-steps (slot-steps)
t ppo_shared_lanedrop python baselines/ppo_shared.py --config '{"scenario": "lane-drop"}' \
    --total-timesteps 500000 --seed 0 --out "$OUT/ppo_shared_lanedrop"
# 3. PPO on the Gymnasium highway id (one learned ego among expert ICVs), lane-drop, 100k env steps
t ppo_single_lanedrop python baselines/ppo_single.py --env-id icv_envs/HighwayFormation-v0 \
    --config '{"scenario": "lane-drop"}' --total-timesteps 100000 --seed 0 --out "$OUT/ppo_single_lanedrop"
# 4. behaviour cloning + DAgger of the multi-vp expert on the intersection (1500 veh/h, 120 s after an 80 s
#    expert warm-up): 3000 expert env steps, 6 DAgger iterations x 1800 env steps, 5 epochs per fit
t bc_expert_intersection python baselines/bc_expert.py --env intersection_v0 --config "$INT" \
    --expert-steps 3000 --dagger-iters 6 --dagger-steps 1800 --epochs 5 --seed 0 --out "$OUT/bc_expert_intersection"
# 5. shared PPO on the intersection, 2M slot-steps (262 slots, one per possible arrival: mostly placeholders)
t ppo_shared_intersection python baselines/ppo_shared.py --env intersection_v0 --config "$INT" \
    --total-timesteps 2000000 --n-steps 256 --batch-size 1024 --seed 0 --out "$OUT/ppo_shared_intersection"
