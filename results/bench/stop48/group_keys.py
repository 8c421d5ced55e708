"""The grouping of compute_many's worlds, this tree's (an int tag per key)
against the reference's (the key tuple hashed and compared every step),
on the same 16 HighwayFormation worlds of 20 agents: the loop of
``compute_many`` that asks each world's key and groups it, microseconds a
step, best of 5 x 1000 (stop 48).

    PYTHONPATH=<tree> python results/bench/stop48/group_keys.py REF/icv_envs/policies/formation_expert_many.py"""
import importlib.util, sys, time
import numpy as np
import icv_envs.policies.formation_expert_many as fm
from icv_envs.vector import BatchedWorlds

spec = importlib.util.spec_from_file_location("old_formation_expert_many", sys.argv[1])
old = importlib.util.module_from_spec(spec)
spec.loader.exec_module(old)
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=True)
bw.reset()
acts = np.zeros((16, bw.K, 2), dtype=np.float32)
for _ in range(5):
    bw.step(acts)
cores = [e.core for e in bw.envs]
def loop(mod, reps=1000):
    t = time.perf_counter()
    for _ in range(reps):
        groups = {}
        for i, c in enumerate(cores):
            key = mod._group_key(c.expert, c.world)
            groups.setdefault(("alone", i) if key is None else key, []).append(i)
    return (time.perf_counter() - t) / reps * 1e6, len(groups)
res = {"this tree": [], "reference": []}
for _ in range(5):
    for name, mod in (("this tree", fm), ("reference", old)):
        for c in cores:  # (each module keeps its own key on the expert: made once per road, then read)
            c.expert.__dict__.pop("_many_key", None)
        mod._group_key(cores[0].expert, cores[0].world)
        res[name].append(loop(mod))
for name, v in res.items():
    print(f"{name}: {min(x[0] for x in v):.1f} us a step for 16 worlds ({v[0][1]} group)")
