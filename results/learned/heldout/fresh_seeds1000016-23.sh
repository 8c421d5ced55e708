cd /work/main
L=results/learned
run() { icv-envs evaluate --env icv_envs/intersection-v0 --policy $1 --episodes 8 --seed 1000016 --out /tmp/fresh_$2 > /tmp/fresh_$2.log 2>&1; }
run $L/bc_dagger_intersection_leader_30rounds_ensemble3 ens &
run $L/bc_dagger_intersection_leader_30rounds s0
wait
run $L/bc_dagger_intersection_leader_30rounds_seed1 s1 &
run $L/bc_dagger_intersection_leader_30rounds_seed2 s2
wait
icv-envs evaluate --env icv_envs/intersection-v0 --policy expert --episodes 8 --seed 1000016 --config '{"throughput": 1500, "duration": 120, "warmup": 80}' --out /tmp/fresh_expert > /tmp/fresh_expert.log 2>&1
echo done > /tmp/fresh_done
