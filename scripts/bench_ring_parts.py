"""Where a step of the paper's ring goes, part by part, for comparing two
trees on a noisy machine (issue 10): HighwayRamps at VGR 1/3 under the
formation expert through the PettingZoo API, ``--warmup`` simulated seconds
(300: about 460 vehicles), then ``--steps`` policy steps; process CPU time
per step, and ``time.perf_counter`` totals of the main parts (wrapped
methods; a part nested in another is counted in both).

    PYTHONPATH=<tree> python scripts/bench_ring_parts.py [--warmup 300] [--steps 250]
    PYTHONPATH=<tree> python scripts/bench_ring_parts.py --case ring-rows [--steps 250]
    PYTHONPATH=<tree> python scripts/bench_ring_parts.py --case batched [--steps 300]

``--case ring-rows``: the same ring through the array API
(``step_rows``, the expert's action array fed back, ``expert_in_info``
off; what ``icv-envs bench highway-ramps --vs-sumo --api rows`` times),
with the parts of the core it reaches (part names ``Class.method``).

``--case batched``: :class:`icv_envs.vector.BatchedWorlds`, 16
HighwayFormation worlds of 20 agents, zero actions, no expert (the
``batched`` case of ``scripts/bench_trees.py``), 50 steps of warm-up; the
parts per world-step in microseconds.

Run it for both trees, alternately, more than once: the total moves by 10%
or more between runs on a shared machine; the parts' ratios are steadier.
"""

from __future__ import annotations

import argparse
import functools
import time

PARTS = [
    ("icv_envs.envs.base", "IcvAgentsEnv", "_ma_advance"),
    ("icv_envs.sim.formations", "FormationManager", "update"),
    ("icv_envs.policies.formation_expert", "FormationExpert", "compute"),
    ("icv_envs.sim.world", "World", "substeps"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_observe_rows"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_features"),
    ("icv_envs.sim.world", "World", "record_min_gap"),
    ("icv_envs.sim.formations", "FormationManager", "_references"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_rewards_rows"),
]

# the batched worlds' parts (--case batched); ``FormationManager._reform``
# is left out: the trees before stop 35 call it from the same place
BATCHED_PARTS = [
    ("icv_envs.vector", "BatchedWorlds", "step"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_ma_advance"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_advance"),
    ("icv_envs.sim.world", "World", "substeps"),
    ("icv_envs.sim.world", "World", "record_min_gap"),
    ("icv_envs.sim.formations", "FormationManager", "update"),
    ("icv_envs.sim.formations", "FormationManager", "_hold_targets"),  # (until stop 49; inside update from stop 50)
    ("icv_envs.sim.join_plans", "JoinPlans", "profile"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_features"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_observe_rows"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_rewards_rows"),
]


# the ring's parts through the array API (--case ring-rows)
RING_ROWS_PARTS = [
    ("icv_envs.envs.base", "IcvAgentsEnv", "_ma_advance"), ("icv_envs.envs.base", "IcvAgentsEnv", "_advance"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_controls"), ("icv_envs.envs.base", "IcvAgentsEnv", "_before_physics"),
    ("icv_envs.envs.highway_ramps", "HighwayRampsEnv", "_spawn_due"),
    ("icv_envs.sim.world", "World", "substeps"), ("icv_envs.sim.world", "World", "record_min_gap"),
    ("icv_envs.sim.formations", "FormationManager", "update"),
    ("icv_envs.sim.formations", "FormationManager", "_reform"),
    ("icv_envs.policies.formation_expert", "FormationExpert", "compute"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_observe_rows"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_features"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_rewards_rows"),
    ("icv_envs.envs.highway_formation", "HighwayFormationEnv", "_neighbours"),
    ("icv_envs.sim.world", "World", "lane_index"),
]


def wrap_parts(parts, acc: dict, qualified: bool = False) -> None:
    """Wrap each ``(module, class, method)`` of ``parts`` so that its
    ``time.perf_counter`` total accumulates in ``acc`` under the method's
    name (``Class.method`` with ``qualified``)."""
    import importlib

    for module, cls_name, name in parts:
        cls = getattr(importlib.import_module(module), cls_name)
        f = getattr(cls, name, None)
        if f is None:  # (a part the tree measured does not have: not wrapped, not reported)
            continue
        key = f"{cls.__name__}.{name}" if qualified else name

        def g(*args, __f=f, __key=key, **kw):
            t = time.perf_counter()
            try:
                return __f(*args, **kw)
            finally:
                acc[__key] = acc.get(__key, 0.0) + time.perf_counter() - t

        setattr(cls, name, functools.wraps(f)(g))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--warmup", type=float, default=300.0, help="simulated seconds before timing")
    p.add_argument("--steps", type=int, default=250, help="policy steps timed")
    p.add_argument("--case", choices=("ring", "ring-rows", "batched"), default="ring")
    a = p.parse_args()
    acc: dict[str, float] = {}
    if a.case == "batched":
        return batched(a.steps, acc)
    if a.case == "ring-rows":
        return ring_rows(a.warmup, a.steps, acc)
    wrap_parts(PARTS, acc)
    from icv_envs.envs import highway_ramps_v0

    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=a.warmup + a.steps / 5.0 + 10.0)
    env.reset(seed=0)
    for _ in range(int(a.warmup * 5)):
        ex = env.expert_actions()
        env.step({ag: ex[ag] for ag in env.agents})
    acc.clear()
    t0 = time.process_time()
    for _ in range(a.steps):
        ex = env.expert_actions()
        env.step({ag: ex[ag] for ag in env.agents})
    total = time.process_time() - t0
    print(f"step {total * 1e3 / a.steps:.2f} ms CPU ({len(env.agents)} vehicles at the end)")
    for k, v in sorted(acc.items(), key=lambda kv: -kv[1]):
        print(f"  {k:16s} {v * 1e3 / a.steps:7.3f} ms")


def ring_rows(warmup: float, steps: int, acc: dict) -> None:
    """``--case ring-rows`` (module docstring)."""
    wrap_parts(RING_ROWS_PARTS, acc, qualified=True)
    from icv_envs.envs import highway_ramps_v0

    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=warmup + steps / 5.0 + 10.0, expert_in_info=False)
    env.reset(seed=0)
    core = env.core
    for _ in range(int(warmup * 5)):
        env.step_rows(core.expert_actions())
    acc.clear()
    t0 = time.process_time()
    for _ in range(steps):
        env.step_rows(core.expert_actions())
    total = time.process_time() - t0
    print(f"step {total * 1e3 / steps:.3f} ms CPU ({core.world.traffic.n} vehicles at the end)")
    for k, v in sorted(acc.items(), key=lambda kv: -kv[1]):
        print(f"  {k:36s} {v * 1e3 / steps:7.3f} ms")


def batched(steps: int, acc: dict) -> None:
    """``--case batched`` (module docstring)."""
    import numpy as np

    wrap_parts(BATCHED_PARTS, acc, qualified=True)
    from icv_envs.vector import BatchedWorlds

    B = 16
    for _ in range(2):  # the same run twice, the second timed (the first loads the kernels from numba's cache)
        bw = BatchedWorlds(B, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=False)
        bw.reset()
        acts = np.zeros((B, bw.K, 2))
        for _ in range(50):
            bw.step(acts)
        acc.clear()
        t0 = time.process_time()
        for _ in range(steps):
            bw.step(acts)
        total = time.process_time() - t0
    per = 1e6 / (steps * B)
    print(f"world-step {total * per:.1f} us CPU ({B * bw.K * steps / total:,.0f} agent-steps per CPU s)")
    for k, v in sorted(acc.items(), key=lambda kv: -kv[1]):
        print(f"  {k:34s} {v * per:7.1f} us")


if __name__ == "__main__":
    main()
