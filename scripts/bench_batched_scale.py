"""A batched world-step's cost against the agents per world (issue 10's
batched bar): 16 HighwayFormation worlds of K agents, zero actions
(``expert=0``) or the expert's (``expert=1``), the second of two identical
runs timed (50 + 150 batch steps, the last 150 timed); process CPU us per
world-step. Run from outside the checkout:

    PYTHONPATH=<tree> python scripts/bench_batched_scale.py 0|1
"""
import json
import sys
import time

import numpy as np

from icv_envs.vector import BatchedWorlds

expert = sys.argv[1] == "1"
out = {}
for K in (5, 10, 20, 40, 80):
    B = 16
    for _ in range(2):
        bw = BatchedWorlds(B, config={"vehicles_count": K, "initial_position": None}, seed=0, expert=expert)
        bw.reset()
        acts = np.zeros((B, bw.K, 2))
        for _ in range(50):
            bw.step(bw.expert_actions if expert else acts)
        t0, n, agents = time.process_time(), 150, 0
        for _ in range(n):
            agents += int(bw.mask.sum())
            bw.step(bw.expert_actions if expert else acts)
        dt = time.process_time() - t0
    us = dt / (n * B) * 1e6
    out[K] = {"us_per_world_step": us, "agent_steps_per_cpu_s": agents / dt}
    print(f"{K:3d} agents/world: {us:6.1f} us per world-step, {agents / dt:9,.0f} agent-steps per CPU s", flush=True)
print(json.dumps({"expert": expert, "results": out}))
