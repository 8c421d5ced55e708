import sys, time
sys.path.insert(0, "/work/main/scripts")
from bench_ring_parts import wrap_parts
PARTS = [("icv_envs.envs.base", "IcvAgentsEnv", "_ma_advance"), ("icv_envs.envs.base", "IcvAgentsEnv", "_advance"),
         ("icv_envs.envs.base", "IcvAgentsEnv", "_controls"), ("icv_envs.envs.base", "IcvAgentsEnv", "_before_physics"),
         ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_departed"),
         ("icv_envs.envs.base", "IcvAgentsEnv", "_last_obs_of"),
         ("icv_envs.envs.highway_ramps", "HighwayRampsEnv", "_spawn_due"),
         ("icv_envs.sim.world", "World", "substeps"), ("icv_envs.sim.world", "World", "record_min_gap"),
         ("icv_envs.sim.formations", "FormationManager", "update"), ("icv_envs.sim.formations", "FormationManager", "_reform"),
         ("icv_envs.policies.formation_expert", "FormationExpert", "compute"),
         ("icv_envs.envs.base", "IcvAgentsEnv", "_observe_rows"), ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_features"),
         ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_rewards_rows"),
         ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_neighbours"),
         ("icv_envs.sim.world", "World", "lane_index"), ("icv_envs.envs.base", "IcvAgentsEnv", "expert_actions"),
         ("icv_envs.envs.parallel", "CoreParallelEnv", "step_rows"), ("icv_envs.envs.base", "IcvAgentsEnv", "ma_step_rows")]
acc = {}
wrap_parts(PARTS, acc, qualified=True)
from icv_envs.envs import highway_ramps_v0
env = highway_ramps_v0.parallel_env(vgr=1/3, duration=700, method="formation", expert_in_info=False)
env.reset(seed=0); core = env.core
for _ in range(2500): env.step_rows(core.expert_actions())
acc.clear(); N = 500
c = time.process_time()
for _ in range(N): env.step_rows(core.expert_actions())
dt = time.process_time() - c
print(f"step {dt/N*1e3:.3f} ms")
for k, v in sorted(acc.items(), key=lambda kv: -kv[1]): print(f"  {k:40s} {v/N*1e6:8.1f} us")
