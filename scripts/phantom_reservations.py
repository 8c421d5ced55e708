"""Share of non-expert vehicle-steps whose lane-change plan is listed in the
controllers' lane index (a phantom reservation), lane-drop, half the agents
off the expert (issue 9).  PYTHONPATH=$PWD python scripts/phantom_reservations.py --seeds 0-9"""

import argparse

import numpy as np

from icv_envs.envs.highway_formation_v0 import parallel_env
from icv_envs.experiments.seeds import parse_seeds

p = argparse.ArgumentParser()
p.add_argument("--seeds", default="0-9")
p.add_argument("--scenario", default="lane-drop")
a = p.parse_args()
off = phantom = 0
for seed in parse_seeds(a.seeds):
    env = parallel_env(scenario=a.scenario)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    while env.agents:
        ex = env.expert_actions()
        acts = {ag: ex[ag] if i % 2 else np.clip(ex[ag] + rng.normal(0, 0.3, 2), -1, 1).astype(np.float32)
                for i, ag in enumerate(env.agents)}
        env.step(acts)
        w = env.core.world
        tr = w.traffic
        w.invalidate()
        idx = w.lane_index(reserved=True)
        pairs = set(zip(idx.rows.tolist(), idx.lanes.tolist()))
        bidx = w.lane_index(reserved=False)
        body = set(zip(bidx.rows.tolist(), bidx.lanes.tolist()))
        for r in range(tr.n):
            if w._expert_vids is not None and int(tr.vid[r]) not in w._expert_vids:
                off += 1
                ln = int(tr.lc_lane[r])
                phantom += ln >= 0 and (r, ln) in pairs and (r, ln) not in body
    env.close()
print(f"non-expert vehicle-steps {off}, with a phantom reservation {phantom} ({100 * phantom / max(off, 1):.1f}%)")
