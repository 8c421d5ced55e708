"""Agent-steps per CPU second of DiscreteMetaAction agents (stop 45), for
comparing two trees alternately: HighwayFormation, 16 separate PettingZoo
worlds of 20 agents stepped one after the other with seeded random meta
actions through the dicts (what BatchedWorlds does per world with discrete
actions), 100 steps timed after 20. Run from outside the trees:

    PYTHONPATH=<tree> python discrete_speed.py [--env intersection] [--seed S]

``--env intersection``: 16 intersection worlds at 2500 veh/h instead (a
setting the figures were not first measured on); ``--seed``: world ``b``
resets with ``seed + b`` and the actions' generator takes ``seed``."""
import argparse, importlib, json, time
import numpy as np

ap = argparse.ArgumentParser()
ap.add_argument("--env", default="highway_formation", choices=["highway_formation", "intersection"])
ap.add_argument("--seed", type=int, default=0)
a = ap.parse_args()
mod = importlib.import_module(f"icv_envs.envs.{a.env}_v0")
cfg = ({"vehicles_count": 20, "initial_position": None} if a.env == "highway_formation" else {"throughput": 2500.0})
envs = [mod.parallel_env(duration=40.0, expert_in_info=False, expert_driven_check=False,
                         action={"type": "DiscreteMetaAction"}, **cfg) for _ in range(16)]
for b, e in enumerate(envs):
    e.reset(seed=a.seed + b)
rng = np.random.default_rng(a.seed)


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
