"""Batched worlds on a setting the benchmarks' figures are not measured on
(README "Speed": issue 10's batched bars): 8 worlds of 30 agents, seed 7, uniform random actions in [-0.3, 0.3]
(``0``) or the expert's (``1``), 100 batch steps; the same run made twice
and the second timed (its own loop, so that trees before stop 38, whose
``batched_sps`` timed the first run, are measured the same way). Run from
outside the checkout, alternately per tree:

    PYTHONPATH=<tree> python scripts/bench_batched_settings.py 0|1
"""
import json
import sys
import time

import numpy as np

from icv_envs.vector import BatchedWorlds

expert = sys.argv[1] == "1"
B, K, steps = 8, 30, 100
for _ in range(2):
    bw = BatchedWorlds(B, config={"vehicles_count": K, "initial_position": None}, seed=7, expert=expert)
    bw.reset()
    rng = np.random.default_rng(7)
    n, c0 = 0, time.process_time()
    for _ in range(steps):
        acts = bw.expert_actions if expert else rng.uniform(-0.3, 0.3, size=(B, bw.K, 2)).astype(np.float32)
        n += int(bw.mask.sum())
        bw.step(acts)
    cpu = time.process_time() - c0
print(json.dumps({"expert": expert, "agent_steps": n, "agent_steps_per_cpu_s": n / cpu}))
