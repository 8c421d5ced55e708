"""Deterministic work counts of the intersection's array-path step (stop 47):
Python function calls (cProfile's count, every call including C builtins)
per step over the bench's window of seed 0 (100 s warm-up, then 150 s).
Noise-free, unlike the time: run with PYTHONPATH=<tree>
[METHOD THROUGHPUT SEED] (default multi-vp 2200 0)."""
import cProfile, pstats, sys
from icv_envs.envs.intersection_v0 import parallel_env
method, tp, seed = (sys.argv[1], float(sys.argv[2]), int(sys.argv[3])) if len(sys.argv) > 3 else ("multi-vp", 2200.0, 0)
env = parallel_env(method=method, throughput=tp, duration=260, expert_in_info=False)
env.reset(seed=seed)
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
print(f"{method} {tp:g} veh/h seed {seed}: {n} steps, {agents / n:.1f} agents on average: {st.total_calls / n:.0f} function calls per step "
      f"({st.prim_calls / n:.0f} primitive)")
