"""Stop 43: the batched worlds' throughput under three kinds of external
("learned") actions. ``scripts/bench_trees.py --case batched`` (the bar's
figure) feeds zero actions: every vehicle coasts straight, nothing
crashes, the worlds stay full. An untrained policy's actions are closer to
random: vehicles crash or leave the road, are removed, and a world runs on
with fewer agents until its episode ends. 16 HighwayFormation worlds of 20
agents (``initial_position=None``), 100 steps untimed, then 300 timed (the
same pre-drawn actions for every tree); prints one JSON line per action
kind: agent-steps per CPU s (live agents only, as the bar counts them),
world-steps per CPU s, live agents per world on average, episode resets.
Run from outside the checkout: ``PYTHONPATH=<tree> python batched_actions.py``."""
import json
import time

import numpy as np

from icv_envs.vector import BatchedWorlds

B = 16
for kind in ("zero", "uniform", "gauss0.3"):
    bw = BatchedWorlds(B, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=False)
    bw.reset()
    rng = np.random.default_rng(0)
    shape = (400, B, bw.K, 2)
    if kind == "zero":
        acts = np.zeros(shape, dtype=np.float32)
    elif kind == "uniform":
        acts = rng.uniform(-1.0, 1.0, shape).astype(np.float32)
    else:
        acts = np.clip(rng.normal(0.0, 0.3, shape), -1.0, 1.0).astype(np.float32)
    for i in range(100):
        bw.step(acts[i])
    e0 = int(bw._episode.sum())
    n = 0
    c0 = time.process_time()
    for i in range(100, 400):
        n += int(bw.mask.sum())
        bw.step(acts[i])
    cpu = time.process_time() - c0
    print(json.dumps({"actions": kind, "agent_steps_per_cpu_s": n / cpu, "world_steps_per_cpu_s": 300 * B / cpu,
                      "live_agents_per_world": n / (300 * B), "resets": int(bw._episode.sum()) - e0}))
