"""pyinstrument profile of the intersection window through step_rows (stop 47)."""
import sys
from pyinstrument import Profiler
from icv_envs.envs.intersection_v0 import parallel_env
env = parallel_env(method="multi-vp", throughput=2200.0, duration=260)
env.reset(seed=0)
while env.core.world.time < 100 - 1e-9:
    env.step_rows(env.core.expert_actions())
p = Profiler(interval=0.0001)
p.start()
while env.core.world.time < 250 - 1e-9:
    env.step_rows(env.core.expert_actions())
p.stop()
print(p.output_text(unicode=False, show_all=False, color=False))
