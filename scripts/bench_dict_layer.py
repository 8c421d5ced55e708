"""Share of the PettingZoo dict layer in a step (issue 10, item 1).

    PYTHONPATH=$PWD python scripts/bench_dict_layer.py [--vehicles 800] [--steps 150]
        [--info-keys speed,rewards] [--no-expert-in-info]

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
figures, across machines. ``--info-keys`` sets the env's ``info_keys``
(comma-separated names; ``""``: none; default: all), ``--no-expert-in-info``
leaves the expert's label out of the infos (``expert_in_info=False``).
"""

from __future__ import annotations

import argparse
import gc
import math
import time

import numpy as np

from icv_envs.envs import base
from icv_envs.envs.highway_formation_v0 import parallel_env


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--vehicles", type=int, default=800)
    p.add_argument("--steps", type=int, default=150)
    p.add_argument("--info-keys", default=None, help="comma-separated info keys ('' for none); default: all")
    p.add_argument("--no-expert-in-info", action="store_true")
    a = p.parse_args()
    info_keys = None if a.info_keys is None else [k for k in a.info_keys.split(",") if k]
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
                       road_length=float(span + 30.0 * duration + 300.0), duration=duration, info_keys=info_keys,
                       expert_in_info=not a.no_expert_in_info)
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
    print(f"info_keys={info_keys}, expert_in_info={not a.no_expert_in_info}")
    print(f"{n} agents: step {tot / a.steps * 1e3:.2f} ms = {tot / vs * 1e6:.2f} us/agent; dict layer "
          f"{acc['dict'] / tot * 100:.1f}% of the step ({acc['dict'] / vs * 1e6:.2f} us/agent); "
          f"garbage collection {acc['gc'] / tot * 100:.1f}%")
    for name, t in sorted(parts.items(), key=lambda kv: -kv[1]):
        print(f"  {name:15s} {t / vs * 1e6:.2f} us/agent ({t / tot * 100:.1f}% of the step)")
    # the floor: the least any implementation of PettingZoo's parallel API
    # does per step for these agents (the actions read from the user's dict
    # into one array, five dicts built from row arrays, an empty info dict
    # per agent), timed on the last step's agents and arrays
    names = list(acts)
    obs_rows = np.zeros((len(names),) + env.observation_space(names[0]).shape, dtype=np.float32)
    rew, term = np.zeros(len(names)), np.zeros(len(names), dtype=bool)
    gc.collect()
    reps = a.steps
    t = time.perf_counter()
    for _ in range(reps):
        np.array([acts[ag] for ag in names])
        dict(zip(names, obs_rows))
        dict(zip(names, rew.tolist()))
        dict(zip(names, term.tolist()))
        dict.fromkeys(names, False)
        {ag: {} for ag in names}
    floor = (time.perf_counter() - t) / (reps * len(names))
    rest = (tot - acc["dict"]) / vs  # the step without its dict layer, per agent
    print(f"floor of the API's dicts: {floor * 1e6:.2f} us/agent; with it the dict layer would be "
          f"{floor / (rest + floor) * 100:.1f}% of a step (the rest of the step {rest * 1e6:.2f} us/agent)")


if __name__ == "__main__":
    main()
