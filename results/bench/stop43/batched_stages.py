"""Stop 43's stage harness of the batched world-step (16 HighwayFormation
worlds of 20 agents, zero actions, 400 steps timed after 100): the world-step
(wall time per world) and, with ``wrap``, the time inside the step's main
stages (the wrappers add about 10 us to a world-step). Run from outside the
checkout: ``PYTHONPATH=<tree> python batched_stages.py [wrap]``."""
import time, numpy as np, collections, sys
from icv_envs.vector import BatchedWorlds
from icv_envs.envs.highway_formation import HighwayFormationEnv as H
import icv_envs.envs.base as base
import icv_envs.sim.world as world
import icv_envs.sim.formations as formations
acc = collections.Counter()
pc = time.perf_counter
def wrap(cls, name, label):
    f = getattr(cls, name)
    def g(*a, **k):
        t = pc(); r = f(*a, **k); acc[label] += pc() - t; return r
    setattr(cls, name, g)
spec = [(base.IcvAgentsEnv, "_ma_advance", "1 _ma_advance"),
        (base.IcvAgentsEnv, "_before_physics", "2 before_physics"), (base.IcvAgentsEnv, "_advance", "3 advance"),
        (world.World, "substeps", "3a substeps"), (world.World, "record_min_gap", "3b record_min_gap"),
        (H, "_react", "4 react"), (formations.FormationManager, "_hold_targets", "4a hold"),
        (H, "_post_rows", "5 post_rows"), (formations.FormationManager, "_refs", "5a refs"),]
if sys.argv[1:] == ["wrap"]:
    for s in spec: wrap(*s)
B = 16
bw = BatchedWorlds(B, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=False)
bw.reset()
a = np.zeros((B, bw.K, 2), dtype=np.float32)
for _ in range(100): bw.step(a)
acc.clear()
t = pc(); N = 400
for _ in range(N): bw.step(a)
tot = pc() - t
W = N * B
print(f"world-step {tot / W * 1e6:.1f} us")
for k in sorted(acc): print(f"  {k:20s} {acc[k] / W * 1e6:6.1f} us")
