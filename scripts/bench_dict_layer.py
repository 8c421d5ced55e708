"""Share of the PettingZoo dict layer in a step (issue 10, item 1).

    PYTHONPATH=$PWD python scripts/bench_dict_layer.py [--vehicles 800] [--steps 150]

HighwayFormation with ``--vehicles`` agents, formation expert through the
PettingZoo parallel API. The dict layer is the time inside the functions
that only convert between arrays and the per-agent dicts (the batched
action check, the observation/reward/termination dicts, the info dicts and
their expert labels,
re-aligning actions to rows; from stop 31 the step's agents get their labels
inside ``_info_dicts``, as a column, and ``_label_rest`` labels the agents
that left or arrived late), garbage collections included where they fall;
it is reported as a share of ``env.step`` and per agent, then per function
(a function called inside another, ``_realign_rows`` in ``_label_infos``,
is counted in both). Times are
``time.perf_counter`` inside one process; compare shares, not absolute
figures, across machines.
"""

from __future__ import annotations

import argparse
import gc
import math
import time

from icv_envs.envs import base
from icv_envs.envs.highway_formation_v0 import parallel_env


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--vehicles", type=int, default=800)
    p.add_argument("--steps", type=int, default=150)
    a = p.parse_args()
    acc = {"dict": 0.0, "gc": 0.0}
    parts: dict[str, float] = {}
    depth = [0]  # only the outermost timed call counts (``_label_infos`` calls ``_realign_rows``)

    def wrap(name, static):
        f = getattr(base.IcvAgentsEnv, name)

        def g(*args, **kw):
            depth[0] += 1
            t = time.perf_counter()
            try:
                return f(*args, **kw)
            finally:
                depth[0] -= 1
                dt = time.perf_counter() - t
                parts[name] = parts.get(name, 0.0) + dt  # each function's own calls, nested ones too
                if depth[0] == 0:
                    acc["dict"] += dt

        setattr(base.IcvAgentsEnv, name, staticmethod(g) if static else g)

    for name in ("_agent_dicts", "_info_dicts", "_label_infos", "_label_rest", "_realign_rows"):
        if hasattr(base.IcvAgentsEnv, name):  # (_label_rest: from stop 31; _label_infos: before it, and for resets)
            wrap(name, True)
    wrap("_check_actions", False)
    t_gc = [0.0]
    gc.callbacks.append(lambda ph, info: t_gc.__setitem__(0, time.perf_counter()) if ph == "start"
                        else acc.__setitem__("gc", acc["gc"] + time.perf_counter() - t_gc[0]))
    n = a.vehicles
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    duration = (a.steps + 10) / 5.0
    env = parallel_env(vehicles_count=n, formation_size=12, initial_position=None,
                       road_length=float(span + 30.0 * duration + 300.0), duration=duration)
    env.reset(seed=0)
    for _ in range(5):
        ex = env.expert_actions()
        env.step({ag: ex[ag] for ag in env.agents})
    acc.update(dict=0.0, gc=0.0)
    parts.clear()
    tot, vs = 0.0, 0
    for _ in range(a.steps):
        ex = env.expert_actions()
        acts = {ag: ex[ag] for ag in env.agents}
        vs += len(acts)
        t = time.perf_counter()
        env.step(acts)
        tot += time.perf_counter() - t
    print(f"{n} agents: step {tot / a.steps * 1e3:.2f} ms = {tot / vs * 1e6:.2f} us/agent; dict layer "
          f"{acc['dict'] / tot * 100:.1f}% of the step ({acc['dict'] / vs * 1e6:.2f} us/agent); "
          f"garbage collection {acc['gc'] / tot * 100:.1f}%")
    for name, t in sorted(parts.items(), key=lambda kv: -kv[1]):
        print(f"  {name:15s} {t / vs * 1e6:.2f} us/agent ({t / tot * 100:.1f}% of the step)")


if __name__ == "__main__":
    main()
