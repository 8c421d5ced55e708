"""Microseconds of the two intersection expert parts rewritten in stop 22 (issue 10), on one state
(multi-vp, 2200 veh/h, seed 0, after 900 policy steps): the virtual platoon's tree (with its order
repair) and one corridor-index build. Run in two trees to compare them:

    PYTHONPATH=<tree> python scripts/bench_vp_parts.py
"""
import time
from icv_envs.envs.intersection_v0 import parallel_env
env = parallel_env(method="multi-vp", throughput=2200.0, duration=500.0)
obs, infos = env.reset(seed=0)
for _ in range(900):
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
w = env.core.world; ex = env.core.expert; rs = w.route()
def t(f, n=300):
    f(); t0 = time.process_time()
    for _ in range(n): f()
    return (time.process_time() - t0) / n * 1e6
vp = list(ex.vp_order)
def tree():
    ex.vp_order = list(vp); ex.tree(w, rs)
print("nodes", len(ex.nodes), "tree us", round(t(tree)))
from icv_envs.policies.platoon_common import Corridors
import numpy as np
print("corridors us", round(t(lambda: Corridors(w, rs, np.full(w.fleet.n, -1)))))
