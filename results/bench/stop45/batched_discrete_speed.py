"""Agent-steps per CPU second of BatchedWorlds with DiscreteMetaAction
(stop 45): 16 HighwayFormation worlds of 20 agents, seeded random meta
actions, 100 steps timed after 20 (the second of two identical runs, as
scripts/bench_trees.py times the batched cases). Run from outside the trees:

    PYTHONPATH=<tree> python batched_discrete_speed.py [--worlds B --vehicles N] [--seed S] [--idle-share P]

``--idle-share``: each agent takes IDLE with probability ``P`` and a random
meta action otherwise (more agents stay alive)."""
import argparse, json, time
import numpy as np
from icv_envs.vector import BatchedWorlds

ap = argparse.ArgumentParser()
ap.add_argument("--worlds", type=int, default=16)
ap.add_argument("--vehicles", type=int, default=20)
ap.add_argument("--seed", type=int, default=0)
ap.add_argument("--idle-share", type=float, default=0.0)
a = ap.parse_args()
B = a.worlds


def actions(rng, K):
    u = rng.integers(0, 5, (B, K))
    return np.where(rng.random((B, K)) < a.idle_share, 1, u) if a.idle_share else u


for timed in (False, True):
    bw = BatchedWorlds(B, config={"vehicles_count": a.vehicles, "initial_position": None,
                                  "action": {"type": "DiscreteMetaAction"}}, seed=a.seed)
    bw.reset()
    rng = np.random.default_rng(a.seed)
    for _ in range(20):
        bw.step(actions(rng, bw.K))
    c0, n = time.process_time(), 0
    for _ in range(100):
        n += int(bw.mask.sum())
        bw.step(actions(rng, bw.K))
    cpu = time.process_time() - c0
print(json.dumps({"agent_steps": n, "cpu": cpu, "agent_steps_per_cpu_s": n / cpu}))
