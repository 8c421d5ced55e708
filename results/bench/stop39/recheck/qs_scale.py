"""What batching worlds could save in one stage: the compiled physics
substeps (quiet_substeps, 5 frames) timed on one 20-vehicle world's state
and on one 320-vehicle world's (16 x 20 vehicles), each call repeated on
the arguments captured from a BatchedWorlds step. Run from outside the
checkout: PYTHONPATH=<tree> python qs_scale.py"""
import numpy as np, timeit
import icv_envs.sim.world as W
from icv_envs.vector import BatchedWorlds
cap = {}
orig = W.quiet_substeps
def wrap(*a):
    cap.setdefault(len(a[1]), a)
    return orig(*a)
W.quiet_substeps = wrap
for K in (20, 320):
    bw = BatchedWorlds(1, config={"vehicles_count": K, "initial_position": None, "road_length": 20000.0}, seed=0, expert=True)
    bw.reset()
    for _ in range(40): bw.step(bw.expert_actions)
    cap.clear(); bw.step(bw.expert_actions)
    a = cap[min(cap)] if K == 20 else cap[max(cap)]
    n = len(a[1])
    t = min(timeit.repeat(lambda: orig(*a), number=2000, repeat=5)) / 2000
    print(f"quiet_substeps, {n} vehicles, {a[0]} frames: {t*1e6:.1f} us = {t*1e6/n:.2f} us per vehicle")
