cd /work/main
L=results/learned
ev() { icv-envs evaluate --env icv_envs/highway_formation-v0 --policy $1 --episodes 20 --seed $2 --out /tmp/ld_$3 > /tmp/ld_$3.log 2>&1; }
ev $L/ppo_meta_lane-drop_50min_abort_ensemble2 1000008 ens_h &
ev $L/ppo_meta_lane-drop_50min_abort_ensemble2 1000028 ens_f
wait
ev $L/ppo_meta_lane-drop_50min_abort 1000028 s0_f &
ev $L/ppo_meta_lane-drop_50min_abort_seed1_resel 1000028 s1_f
wait
icv-envs evaluate --env icv_envs/highway_formation-v0 --policy expert --episodes 20 --seed 1000028 --config '{"scenario": "lane-drop"}' --out /tmp/ld_expert_f > /tmp/ld_expert_f.log 2>&1
echo done > /tmp/ld_done
