"""In-process A/B of batched world-steps with the expert (stop 48): two
twin ``BatchedWorlds`` (16 HighwayFormation worlds of 20 agents, zero
actions, the expert's action computed for every agent; same seed, their
outputs checked equal every step), one grouping the worlds' experts with
this tree's ``compute_many`` (a world's group key an int tag), the other
with the reference tree's (``--old FILE``: its
``icv_envs/policies/formation_expert_many.py``, loaded as a module of its
own). Each step is timed on both, in alternating order.

    PYTHONPATH=<tree> python results/bench/stop48/ab_batched_expert.py --old REF/icv_envs/policies/formation_expert_many.py [SEED]"""
import argparse, importlib.util, time
import numpy as np
import icv_envs.envs.base as base
import icv_envs.policies.formation_expert_many as fm
from icv_envs.vector import BatchedWorlds

ap = argparse.ArgumentParser()
ap.add_argument("seed", nargs="?", type=int, default=0)
ap.add_argument("--old", required=True)
ap.add_argument("--steps", type=int, default=400)
a = ap.parse_args()
spec = importlib.util.spec_from_file_location("old_formation_expert_many", a.old)
old = importlib.util.module_from_spec(spec)
spec.loader.exec_module(old)
B = 16
bws = [BatchedWorlds(B, config={"vehicles_count": 20, "initial_position": None}, seed=a.seed, expert=True)
       for _ in range(2)]
impl = (fm.compute_many, old.compute_many)
src = base.__dict__.get("compute_many")
def step(k, acts):
    # IcvAgentsEnv.expert_actions_many reaches compute_many through the module that defines it
    fm.compute_many = impl[k]
    if src is not None:
        base.compute_many = impl[k]
    out = bws[k].step(acts)
    fm.compute_many = impl[0]
    if src is not None:
        base.compute_many = impl[0]
    return out
for bw in bws:
    bw.reset()
acts = np.zeros((B, bws[0].K, 2), dtype=np.float32)
for _ in range(100):
    step(0, acts); step(1, acts)
t = [0, 0]
for n in range(a.steps):
    outs = [None, None]
    for k in ((0, 1) if n % 2 else (1, 0)):
        c0 = time.perf_counter_ns()
        outs[k] = step(k, acts)
        t[k] += time.perf_counter_ns() - c0
    assert outs[0][0].tobytes() == outs[1][0].tobytes() and \
        outs[0][5]["expert_actions"].tobytes() == outs[1][5]["expert_actions"].tobytes(), "the twins diverged"
W = a.steps * B
print(f"batched with the expert, seed {a.seed}: {a.steps} steps of {B} worlds; world-step with this tree's grouping "
      f"{t[0] / W / 1e3:.1f} us, with the reference's {t[1] / W / 1e3:.1f} us, ratio {t[1] / t[0]:.3f}")
