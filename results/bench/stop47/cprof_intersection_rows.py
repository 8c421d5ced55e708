"""cProfile (tottime) of the intersection window through step_rows (stop 47)."""
import cProfile, pstats, sys
from icv_envs.envs.intersection_v0 import parallel_env
env = parallel_env(method="multi-vp", throughput=2200.0, duration=260)
env.reset(seed=0)
while env.core.world.time < 100 - 1e-9:
    env.step_rows(env.core.expert_actions())
pr = cProfile.Profile()
pr.enable()
n = 0
while env.core.world.time < 250 - 1e-9:
    env.step_rows(env.core.expert_actions()); n += 1
pr.disable()
print("steps", n)
pstats.Stats(pr).sort_stats("tottime").print_stats(int(sys.argv[1]) if len(sys.argv) > 1 else 45)
