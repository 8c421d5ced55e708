"""A batched world-step and its parts (timers on the methods; they add their own cost),
16 HighwayFormation worlds of 20 agents, seed 0, 300 steps after 100: zero actions or a
stochastic policy's (N(0, 0.3) clipped, drawn from seed 0) (stop 52).

    PYTHONPATH=<tree> python results/bench/stop52/parts_noisy.py zero|noisy
"""
import sys, time, functools, collections
import numpy as np
from icv_envs.vector import BatchedWorlds
from icv_envs.envs import agents_step, highway_formation, highway_rows
from icv_envs.sim import world as W, formations as FM
from icv_envs import vector as V
acc = collections.Counter(); cnt = collections.Counter()
def wrap(cls, name, label):
    f = getattr(cls, name)
    @functools.wraps(f)
    def g(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            acc[label] += time.perf_counter() - t; cnt[label] += 1
    setattr(cls, name, g)
wrap(agents_step.AgentsStep, "_advance", "physics (_advance)")
wrap(W.World, "_substep_events", "  events (_substep_events)")
wrap(W.World, "substep", "  single substeps")
wrap(W.World, "record_min_gap", "  record_min_gap")
wrap(highway_formation.HighwayFormationEnv, "_react", "formation layer (_react)")
wrap(FM.FormationManager, "_reform", "  re-forming (_reform)")
wrap(highway_rows.HighwayRows, "_post_rows", "features/rewards/obs (_post_rows)")
wrap(V.BatchedWorlds, "_reset_world", "resets (_reset_world)")
wrap(agents_step.AgentsStep, "_ma_advance", "whole _ma_advance")
B, N = 16, 20
mode = sys.argv[1]
bw = BatchedWorlds(B, config={"vehicles_count": N, "initial_position": None}, seed=0)
bw.reset()
rng = np.random.default_rng(0)
z = np.zeros((B, bw.K, 2), dtype=np.float32)
acts = [np.clip(rng.normal(0.0, 0.3, z.shape), -1.0, 1.0).astype(np.float32) if mode == "noisy" else z for _ in range(400)]
for k in range(100): bw.step(acts[k])
acc.clear(); cnt.clear()
n = 0
t0 = time.perf_counter()
for k in range(100, 400):
    n += int(bw.mask.sum()); bw.step(acts[k])
T = time.perf_counter() - t0
ws = 300 * B
print(f"{mode}: {n / T:,.0f} agent-steps/s, {n / ws:.1f} agents per world, world-step {T / ws * 1e6:.0f} us (timers included)")
for k, v in acc.items():
    print(f"  {k:40s} {v / ws * 1e6:7.1f} us per world-step  ({cnt[k] / ws:.2f} calls)")
