"""Agent-steps per CPU second of BatchedWorlds with the expert's action
computed for every agent and driven (stop 46): ``--worlds`` worlds of the
``--env`` PettingZoo env with ``--config`` (JSON), 100 steps timed after 20
(the second of two identical runs, as scripts/bench_trees.py times the
batched cases; the first loads the kernels from numba's cache). Run from
outside the trees:

    PYTHONPATH=<tree> python batched_expert_speed.py [--env highway_formation] [--config JSON]
        [--worlds 16] [--seed 0] [--steps 100]

Also prints a SHA-256 of every output of the timed run (observations,
rewards, terminations, truncations, masks, expert actions): two trees that
simulate the same print the same hash."""
import argparse, hashlib, json, time
import numpy as np
from icv_envs.vector import BatchedWorlds

ap = argparse.ArgumentParser()
ap.add_argument("--env", default="highway_formation")
ap.add_argument("--config", default='{"vehicles_count": 20, "initial_position": null}')
ap.add_argument("--worlds", type=int, default=16)
ap.add_argument("--seed", type=int, default=0)
ap.add_argument("--steps", type=int, default=100)
a = ap.parse_args()
cfg = json.loads(a.config)

for timed in (False, True):
    bw = BatchedWorlds(a.worlds, env=a.env, config=cfg, seed=a.seed, expert=True)
    bw.reset()
    for _ in range(20):
        bw.step(bw.expert_actions)
    h = hashlib.sha256()
    c0, n = time.process_time(), 0
    for _ in range(a.steps):
        n += int(bw.mask.sum())
        out = bw.step(bw.expert_actions)
        for x in out[:5]:
            h.update(np.ascontiguousarray(x).tobytes())
        h.update(bw.expert_actions.tobytes())
    cpu = time.process_time() - c0
print(json.dumps({"env": a.env, "config": cfg, "worlds": a.worlds, "seed": a.seed, "agent_steps": n, "cpu": cpu,
                  "agent_steps_per_cpu_s": n / cpu, "sha256": h.hexdigest()[:16]}))
