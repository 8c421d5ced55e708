"""Agent-steps per CPU second of BatchedWorlds with DiscreteMetaAction
(stop 45): 16 HighwayFormation worlds of 20 agents, seeded random meta
actions, 100 steps timed after 20 (the second of two identical runs, as
scripts/bench_trees.py times the batched cases). Run from outside the trees:

    PYTHONPATH=<tree> python batched_discrete_speed.py"""
import json, time
import numpy as np
from icv_envs.vector import BatchedWorlds

for timed in (False, True):
    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None,
                                   "action": {"type": "DiscreteMetaAction"}}, seed=0)
    bw.reset()
    rng = np.random.default_rng(0)
    for _ in range(20):
        bw.step(rng.integers(0, 5, (16, bw.K)))
    c0, n = time.process_time(), 0
    for _ in range(100):
        n += int(bw.mask.sum())
        bw.step(rng.integers(0, 5, (16, bw.K)))
    cpu = time.process_time() - c0
print(json.dumps({"agent_steps": n, "cpu": cpu, "agent_steps_per_cpu_s": n / cpu}))
