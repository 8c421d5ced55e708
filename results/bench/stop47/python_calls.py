"""Deterministic work counts of the intersection's array-path step (stop 47):
Python function calls (cProfile's count, every call including C builtins)
per step over the bench's window of seed 0 (100 s warm-up, then 150 s).
Noise-free, unlike the time: run with PYTHONPATH=<tree>."""
import cProfile, pstats
from icv_envs.envs.intersection_v0 import parallel_env
env = parallel_env(method="multi-vp", throughput=2200.0, duration=260, expert_in_info=False)
env.reset(seed=0)
core = env.core
while core.world.time < 100 - 1e-9:
    env.step_rows(core.expert_actions())
pr = cProfile.Profile()
n = agents = 0
pr.enable()
while core.world.time < 250 - 1e-9:
    agents += env.num_agents
    env.step_rows(core.expert_actions())
    n += 1
pr.disable()
st = pstats.Stats(pr)
print(f"{n} steps, {agents / n:.1f} agents on average: {st.total_calls / n:.0f} function calls per step "
      f"({st.prim_calls / n:.0f} primitive)")
