"""Which events send a batched world's physics frames back to Python, and how often (stop 53):
16 HighwayFormation worlds of 20 agents, seed 0, 400 steps of a stochastic policy's actions
(N(0, 0.3) clipped, drawn from seed 0, as ``scripts/bench_trees.py --case batched-noisy``).
Counts the calls of ``World._substep_events`` (the Python handler of a frame's events) by what the
frame held (colliding pairs, vehicles off the road, vehicles at the road's end), and, on a tree
that has it (stop 53 on), the vehicles the compiled frames crashed off the road themselves
(``World._road_crashes``).

    PYTHONPATH=<tree> python results/bench/stop53/event_kinds.py
"""
import collections

import numpy as np

from icv_envs.sim import world as W
from icv_envs.vector import BatchedWorlds

cnt = collections.Counter()
handler = W.World._substep_events


def counted(self, events, cx, cy, cx_before, i, j, lane, off, at_end, n_off, n_end):
    cnt[(len(i) > 0, int(n_off) > 0, int(n_end) > 0)] += 1
    return handler(self, events, cx, cy, cx_before, i, j, lane, off, at_end, n_off, n_end)


W.World._substep_events = counted
inside = collections.Counter()
road = getattr(W.World, "_road_crashes", None)
if road is not None:
    def counted_road(self, events, rows):
        inside["calls"] += 1
        inside["vehicles"] += len(rows)
        return road(self, events, rows)

    W.World._road_crashes = counted_road
B, N, steps = 16, 20, 400
bw = BatchedWorlds(B, config={"vehicles_count": N, "initial_position": None}, seed=0)
bw.reset()
rng = np.random.default_rng(0)
z = np.zeros((B, bw.K, 2), dtype=np.float32)
for _ in range(steps):
    bw.step(np.clip(rng.normal(0.0, 0.3, z.shape), -1.0, 1.0).astype(np.float32))
ws = steps * B
print(f"{ws} world-steps; frames handed to Python, by what they held (pairs, off the road, road's end):")
for k, v in cnt.most_common():
    print(f"  {k}: {v} ({v / ws:.3f} per world-step)")
print(f"  in all: {sum(cnt.values())} ({sum(cnt.values()) / ws:.3f} per world-step)")
if road is None:
    print("vehicles crashed off the road inside the frames: (not on this tree)")
else:
    print(f"vehicles crashed off the road inside the frames: {inside['vehicles']} in {inside['calls']} calls "
          f"({inside['vehicles'] / ws:.3f} per world-step)")
