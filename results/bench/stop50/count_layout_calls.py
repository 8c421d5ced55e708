"""How often the intersection bench's step (multi-vp 2200 veh/h, seed 0, the array path) calls the
layout's route_points, project and arc_project (stop 50: 0.05, 0 and 0 a step over 600 steps)."""
import numpy as np, time, collections
from icv_envs.envs.intersection_v0 import parallel_env
import icv_envs.sim.intersection_layout as IL
cnt = collections.Counter()
for name in ("route_points", "arc_project", "project"):
    f = getattr(IL.IntersectionLayout, name)
    def w(*a, __f=f, __n=name, **k):
        cnt[__n] += 1
        return __f(*a, **k)
    setattr(IL.IntersectionLayout, name, w)
env = parallel_env(method="multi-vp", throughput=2200.0, expert_in_info=False)
env.reset(seed=0)
N = 600
for _ in range(N):
    ex = env.core.expert_actions()
    env.step_rows(ex)
print({k: v / N for k, v in cnt.items()})
