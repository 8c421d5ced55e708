cd /work/main
L=results/learned
icv-envs evaluate --env icv_envs/intersection-v0 --policy $L/bc_dagger_intersection_leader_30rounds_ensemble3 --episodes 16 --seed 1000024 --out /tmp/set4_int_ens > /tmp/set4_int_ens.log 2>&1
icv-envs evaluate --env icv_envs/intersection-v0 --policy expert --episodes 16 --seed 1000024 --config '{"throughput": 1500, "duration": 120, "warmup": 80}' --out /tmp/set4_int_expert > /tmp/set4_int_expert.log 2>&1
icv-envs evaluate --env icv_envs/highway_formation-v0 --policy $L/ppo_meta_lane-drop_50min_abort_ensemble2 --episodes 40 --seed 1000048 --out /tmp/set4_ld_ens > /tmp/set4_ld_ens.log 2>&1
icv-envs evaluate --env icv_envs/highway_formation-v0 --policy expert --episodes 40 --seed 1000048 --config '{"scenario": "lane-drop"}' --out /tmp/set4_ld_expert > /tmp/set4_ld_expert.log 2>&1
echo done > /tmp/set4_done
cd /work/main
while [ ! -f /tmp/set4_done ]; do sleep 5; done
icv-envs evaluate --env icv_envs/highway_formation-v0 --policy results/learned/bc_expert_highway --config '{"scenario": "lane-drop"}' --episodes 20 --seed 1000008 --out /tmp/bcld_h > /tmp/bcld_h.log 2>&1 &
icv-envs evaluate --env icv_envs/highway_formation-v0 --policy results/learned/bc_expert_highway --config '{"scenario": "lane-drop"}' --episodes 20 --seed 1000028 --out /tmp/bcld_f > /tmp/bcld_f.log 2>&1
wait
echo done > /tmp/bcld_done
