"""Stop 46: the formation expert of 16 batched worlds (20 vehicles each, 50 steps into their episodes) asked one world
at a time (FormationExpert.compute) against all in one pass (compute_many), per world, process CPU time over 300
repetitions on the same states; and the cost of 24 16-way concatenations of the worlds' state arrays (what the pass
gathers). Run from outside the trees: PYTHONPATH=<tree> python expert_pass_cost.py"""
import time
import numpy as np
from icv_envs.vector import BatchedWorlds
from icv_envs.policies.formation_expert_many import compute_many

bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=True)
bw.reset()
for _ in range(50):
    bw.step(bw.expert_actions)
cores = [e.core for e in bw.envs]
experts, worlds = [c.expert for c in cores], [c.world for c in cores]
N = 300
for rep in range(2):
    t = time.process_time()
    for _ in range(N):
        for e, w in zip(experts, worlds):
            e.compute(w)
    one = (time.process_time() - t) / N / 16 * 1e6
    t = time.process_time()
    for _ in range(N):
        compute_many(experts, worlds)
    many = (time.process_time() - t) / N / 16 * 1e6
    t = time.process_time()
    for _ in range(N):
        for k in range(24):
            np.concatenate([w.traffic.x for w in worlds])
    gather = (time.process_time() - t) / N / 16 * 1e6
print(f"one world at a time {one:.1f} us per world; all in one pass {many:.1f} us per world; "
      f"24 concatenations {gather:.1f} us per world")
