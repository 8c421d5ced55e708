"""Agent-steps per CPU second of DiscreteMetaAction agents (stop 45), for
comparing two trees alternately: HighwayFormation, 16 separate PettingZoo
worlds of 20 agents stepped one after the other with seeded random meta
actions through the dicts (what BatchedWorlds does per world with discrete
actions), 100 steps timed after 20. Run from outside the trees:

    PYTHONPATH=<tree> python discrete_speed.py"""
import json, time
import numpy as np
from icv_envs.envs.highway_formation_v0 import parallel_env

envs = [parallel_env(vehicles_count=20, initial_position=None, duration=40.0, expert_in_info=False,
                     expert_driven_check=False, action={"type": "DiscreteMetaAction"}) for _ in range(16)]
for b, e in enumerate(envs):
    e.reset(seed=b)
rng = np.random.default_rng(0)


def step_all():
    n = 0
    for e in envs:
        acts = {a: np.int64(rng.integers(5)) for a in e.agents}
        n += len(acts)
        e.step(acts)
    return n


for _ in range(20):
    step_all()
c0, n = time.process_time(), 0
for _ in range(100):
    n += step_all()
cpu = time.process_time() - c0
print(json.dumps({"agent_steps": n, "cpu": cpu, "agent_steps_per_cpu_s": n / cpu}))
