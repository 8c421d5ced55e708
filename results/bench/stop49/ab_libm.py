"""This tree's join profiles and highway reward (libm's pow and exp inside
the kernels, stop 49) against the code they replaced (NumPy's power and exp
between kernels), twin worlds in one process (stop 49).

Twin R has the replaced code on its instances: its join plans are objects of
the reference tree's ``JoinPlans`` (``sim/join_plans.py`` with its
``formation/_kernels.py``, loaded from ``--old``: a gather kernel,
``np.power``, a second kernel) and its ``_reward_total`` is the replaced
NumPy code (``np.where``, ``np.exp``);
twin T runs this tree as it is. They step alternately (which goes first
alternates); the time of each twin's steps is summed after a warm-up, and
every step's outputs are compared bit for bit (equal where NumPy's power
and exp are libm's: under ``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL"``
on this machine).

    python results/bench/stop49/ab_libm.py --old /tmp/ref49 [--case batched|batched-expert|ring] [--steps N] [--seed S]
"""
import argparse
import hashlib
import importlib.util
import json
import os
import time
import types

import numpy as np


def load_old(tree):
    spec = importlib.util.spec_from_file_location("old_formation_kernels", f"{tree}/icv_envs/formation/_kernels.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def old_join_plans(tree, K):
    """The reference tree's ``JoinPlans`` class, its kernels the reference's (``K``)."""
    src = open(f"{tree}/icv_envs/sim/join_plans.py").read()
    src = src.replace("from icv_envs.formation._kernels import join_search_banded, plan_rows, profile_gather, quintic_rows",
                      "join_search_banded, plan_rows, profile_gather, quintic_rows = (_K.join_search_banded, _K.plan_rows, "
                      "_K.profile_gather, _K.quintic_rows)")
    ns = {"_K": K, "__name__": "old_join_plans"}
    exec(compile(src, f"{tree}/icv_envs/sim/join_plans.py", "exec"), ns)
    return ns["JoinPlans"]


def patch_world(core, K, OldJoinPlans):
    """The replaced code on one world's instances: its join plans become an
    instance of the reference tree's class (the same fields), its reward
    total the NumPy code."""
    plans = core.world.manager._plans
    plans.__class__ = OldJoinPlans
    if not hasattr(plans, "stamp"):  # (this tree's JoinPlans keeps no stamps from stop 49: every plan counts as old)
        plans.stamp = np.zeros(len(plans.slot_gid), dtype=np.int64)
    plans._cache = None

    def _reward_total(self, terms):
        progress, safety, comfort, expo, member, partial = terms
        form = np.where(member, np.exp(expo), 0.0)
        total = partial + self.config["reward"]["formation"] * form
        return total, {"progress": progress, "safety": safety, "comfort": comfort, "formation": form}

    core._reward_total = types.MethodType(_reward_total, core)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--old", required=True)
    p.add_argument("--case", default="batched", choices=["batched", "batched-expert", "ring"])
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--vehicles", type=int, default=20)
    a = p.parse_args()
    K = load_old(a.old)
    OJ = old_join_plans(a.old, K)
    if a.case.startswith("batched"):
        from icv_envs.vector import BatchedWorlds
        expert = a.case == "batched-expert"

        def make():
            bw = BatchedWorlds(a.worlds, config={"vehicles_count": a.vehicles, "initial_position": None}, seed=a.seed,
                               expert=expert)
            bw.reset()
            return bw

        R, T = make(), make()
        for env in R.envs:
            patch_world(env.core, K, OJ)
        zeros = np.zeros((a.worlds, T.K, 2), dtype=np.float32)

        def step(bw):
            return bw.step(bw.expert_actions if expert else zeros)[:5]

        warm = 20
    else:
        from icv_envs.envs.highway_ramps_v0 import parallel_env

        def make():
            env = parallel_env(vgr=1.0 / 3.0, duration=700.0, method="formation")
            env.reset(seed=a.seed)
            return env

        R, T = make(), make()
        patch_world(R.core, K, OJ)
        # (R's reset ran the original code: re-made plans from here on are the patched ones; warm both to 300 s)

        def step(env):
            ex = env.expert_actions()
            obs, rew, term, trunc, info = env.step({k: ex[k] for k in env.agents})
            vids = sorted(obs)
            return (np.array([obs[k] for k in vids]), np.array([rew[k] for k in vids]),
                    env.core.world.traffic.x, env.core.world.traffic.speed)

        warm = 1500
    tR = tT = 0.0
    first = None
    for s in range(warm + a.steps):
        order = (R, T) if s % 2 == 0 else (T, R)
        out = {}
        for w in order:
            t0 = time.perf_counter()
            out[id(w)] = step(w)
            dt = time.perf_counter() - t0
            if s >= warm:
                if w is R:
                    tR += dt
                else:
                    tT += dt
        if first is None and not all(np.array_equal(x, y) for x, y in zip(out[id(R)], out[id(T)])):
            first = s
    per = a.steps * (a.worlds if a.case.startswith("batched") else 1)
    print(json.dumps({"case": a.case, "seed": a.seed, "worlds": a.worlds, "vehicles": a.vehicles, "cap": os.environ.get("NPY_DISABLE_CPU_FEATURES", ""),
                      "steps": a.steps, "replaced_us": round(tR / per * 1e6, 1), "this_tree_us": round(tT / per * 1e6, 1),
                      "speedup": round(tR / tT, 4), "identical": first is None, "first_step_differing": first,
                      "unit": "per world-step" if a.case.startswith("batched") else "per ring step"}))


if __name__ == "__main__":
    main()
