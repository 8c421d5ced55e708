"""Collisions by fault at the intersection with a share of agents driving at
random (uniform normalised acceleration, the expert's steering), issue 11
item 5.  PYTHONPATH=$PWD python scripts/intersection_faults.py --share 0.3 --seeds 0-2"""

import argparse
import json

import numpy as np

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.experiments.seeds import parse_seeds

p = argparse.ArgumentParser()
p.add_argument("--methods", default="multi-vp,single-vp,fcfs")
p.add_argument("--throughput", type=float, default=1500.0)
p.add_argument("--seconds", type=float, default=300.0)
p.add_argument("--share", type=float, default=0.3)
p.add_argument("--seeds", default="0-2")
a = p.parse_args()
for method in a.methods.split(","):
    tot = {}
    coll = n_random = 0
    for seed in parse_seeds(a.seeds):
        env = parallel_env(method=method, throughput=a.throughput, duration=a.seconds)
        env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        random_agents, seen = set(), set()
        while not env.episode_over:
            ex = env.expert_actions()
            for ag in env.agents:  # each agent is drawn once, when it appears
                if ag not in seen:
                    seen.add(ag)
                    if rng.random() < a.share:
                        random_agents.add(ag)
            acts = {ag: (np.array([rng.uniform(-1, 1), ex[ag][1]], dtype=np.float32) if ag in random_agents else ex[ag])
                    for ag in env.agents}
            env.step(acts)
        m = env.metrics()
        coll += m["collisions"]
        n_random += len(random_agents)
        for k, v in m["collisions_by_fault"].items():
            for d, n in v.items():
                tot[(k, d)] = tot.get((k, d), 0) + n
        env.close()
    print(json.dumps({"method": method, "seeds": a.seeds, "share": a.share, "collided_vehicles": coll,
                      "random_agents": n_random,
                      "pairs_by_fault": {f"{k}/{d}": n for (k, d), n in sorted(tot.items())}}))
