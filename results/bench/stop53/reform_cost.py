"""CPU time of one re-forming (``FormationManager._reform``, paper Sec. 3.2-3.3: targets on the drivable lanes,
Hungarian assignment, join plans) per call, as a run makes them (stop 53):

* ``noisy``: 16 batched HighwayFormation worlds of 20 agents, seed 0, 300 steps of N(0, 0.3) actions after 100
  (vehicles leave the road, their formations re-form);
* ``ring``: HighwayRamps at VGR 1/3 under the formation expert, 300 policy steps after 1200 (about three
  re-formings a step: vehicles join from the on-ramps and leave at the exits).

The calls are timed with ``time.perf_counter`` around each (the wrapper's own cost is in every figure, the same on
both trees). Run it for two trees alternately:

    PYTHONPATH=<tree> python results/bench/stop53/reform_cost.py noisy|ring
"""
import sys
import time

import numpy as np

from icv_envs.sim.formations import FormationManager

acc = {"t": 0.0, "n": 0}
real = FormationManager._reform


def timed(self, *a, **k):
    t = time.perf_counter()
    try:
        return real(self, *a, **k)
    finally:
        acc["t"] += time.perf_counter() - t
        acc["n"] += 1


FormationManager._reform = timed
case = sys.argv[1]
if case == "noisy":
    from icv_envs.vector import BatchedWorlds

    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
    bw.reset()
    rng = np.random.default_rng(0)
    shape = (16, bw.K, 2)
    acts = [np.clip(rng.normal(0.0, 0.3, shape), -1.0, 1.0).astype(np.float32) for _ in range(400)]
    for k in range(100):
        bw.step(acts[k])
    acc.update(t=0.0, n=0)
    for k in range(100, 400):
        bw.step(acts[k])
elif case == "ring":
    from icv_envs.envs import highway_ramps_v0

    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=400.0)
    env.reset(seed=0)
    for k in range(1500):
        if k == 1200:
            acc.update(t=0.0, n=0)
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
else:
    raise SystemExit(f"case {case!r}; allowed: noisy, ring")
print(f"{case}: {acc['n']} re-formings, {acc['t'] / acc['n'] * 1e6:.1f} us each (wrapper included)")
