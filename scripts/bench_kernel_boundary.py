"""What the Python <-> numba boundary costs in a step (issue 10, stop 44).

    PYTHONPATH=$PWD python scripts/bench_kernel_boundary.py [--case intersection|batched|ring|both] [--expert]
        [--seed 0] [--top 8] [--out FILE]

Every compiled kernel call pays for its dispatch (a fixed part, then each
argument unboxed: an array costs more than a number) and for every array it
returns (boxed into a new ``ndarray``). This script

1. measures those unit costs in this run, on this machine, with trivial
   kernels (one array argument; twenty arrays; twenty floats; one and five
   returned arrays): the reference the estimate below is built from;
2. times the case's step with nothing wrapped (process CPU time, the
   second of two windows: the first loads any kernel the warm-up did not);
3. runs the case again with every kernel reachable from a Python module of
   the package (module attributes that are numba dispatchers, outside
   ``rl`` and ``experiments``) wrapped by a counter of its calls, of its
   array and other arguments and of the arrays it returns (tuples looked
   into), after a warm-up that loaded every kernel the case uses;
4. prints the counts per step (in all, and per kernel: the ``--top``
   largest estimates; stop 40's ``results/bench/stop40/final/count_kernel_calls.py``
   counted the batched case so) and the estimate ``calls x fixed + arrays x
   per-array + others x per-number + returned x per-returned-array``, in us
   and as a share of the step;
5. replays the counted window's kernel calls back to back (copies of their
   arguments, taken before each call), with nothing between them but a
   loop: what the step would cost if every line of Python around the
   kernels took no time (kernels and their boundary; the rest of the step
   is that Python).

Each kernel's calls are also replayed on their own (the same copies) and
timed per kernel: the listing's ``replayed`` column (from stop 52; stop
49's ``results/bench/stop49/replay_per_kernel.py`` did this for the
batched case alone). Replayed copies are read from memory the step had in
cache: read a kernel's figure as an upper bound of its share.

Cases (``--seed``, default 0): ``ring`` (from stop 52): the paper's ring,
HighwayRamps at VGR 1/3 under the formation expert through PettingZoo's
dicts, 300 s of warm-up then 100 policy steps; ``intersection``: multi-vp at 2200 veh/h, every vehicle an
agent with the expert's action from the infos, 100 s of warm-up then 150 s
(as ``icv-envs bench intersection``); ``batched``: 16 HighwayFormation
worlds of 20 agents with zero actions (``--expert``: the expert's action
for every agent, computed every step), 100 steps of warm-up then 200 (as
``scripts/bench_trees.py --case batched``), per world-step. Kernels called
from inside other kernels are compiled calls and not counted (they cost no
boundary). The estimate is a model (unit costs from trivial kernels), not a
measurement of the step: read it as the size of what batching calls
together could save, not as a figure to the microsecond.
"""

from __future__ import annotations

import argparse
import collections
import importlib
import json
import pkgutil
import time

import numpy as np
from numba import njit
from numba.core.registry import CPUDispatcher

import icv_envs


def _unit_costs(n: int = 200_000) -> dict:
    """Per-call costs (us) of trivial kernels, timed here."""

    @njit
    def one(a):
        return a[0]

    @njit
    def twenty(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, b0, b1, b2, b3, b4, b5, b6, b7, b8, b9):
        return a0[0]

    @njit
    def twenty_f(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, b0, b1, b2, b3, b4, b5, b6, b7, b8, b9):
        return a0

    @njit
    def ret1(a):
        return a.copy()

    @njit
    def ret5(a):
        return a.copy(), a.copy(), a.copy(), a.copy(), a.copy()

    x = np.zeros(10)
    arrays = [np.zeros(10) for _ in range(20)]
    floats = [1.5] * 20

    def per_call(fn, *args):
        fn(*args)
        t = time.perf_counter()
        for _ in range(n):
            fn(*args)
        return (time.perf_counter() - t) / n * 1e6

    t1, t20, t20f, r1, r5 = (per_call(one, x), per_call(twenty, *arrays), per_call(twenty_f, *floats),
                             per_call(ret1, x), per_call(ret5, x))
    per_array = (t20 - t1) / 19
    return {"fixed": t1 - per_array, "per_array": per_array, "per_number": (t20f - t1 + per_array) / 20,
            "per_returned_array": (r5 - r1) / 4}


def _intersection(seed: int = 0):
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method="multi-vp", throughput=2200.0, duration=450.0)
    state = {"infos": env.reset(seed=seed)[1]}

    def step():
        infos = state["infos"]
        state["infos"] = env.step({a: infos[a]["expert_action"] for a in env.agents})[4]

    while env.core.world.time < 100 - 1e-9:
        step()

    def window():
        steps = 0
        t0 = env.core.world.time
        while env.core.world.time < t0 + 150 - 1e-9:
            step()
            steps += 1
        return steps

    return window


def _ring(seed: int = 0):
    from icv_envs.envs import highway_ramps_v0

    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=400.0)
    env.reset(seed=seed)

    def step():
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})

    for _ in range(1500):  # 300 s: about 440 vehicles
        step()

    def window():
        for _ in range(100):
            step()
        return 100

    return window


def _batched(expert: bool = False, seed: int = 0):
    from icv_envs.vector import BatchedWorlds

    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=seed, expert=expert)
    bw.reset()
    zeros = np.zeros((16, bw.K, 2), dtype=np.float32)
    for _ in range(100):
        bw.step(bw.expert_actions if expert else zeros)

    def window():
        for _ in range(200):
            bw.step(bw.expert_actions if expert else zeros)
        return 200 * 16  # world-steps

    return window


def _wrap_kernels(counts: collections.Counter, per: dict, calls: list) -> list:
    """Every numba dispatcher bound in a Python module of the package,
    replaced by a counting wrapper; returns what to restore."""
    undo = []
    wrappers = {}
    for info in pkgutil.walk_packages(icv_envs.__path__, "icv_envs."):
        parts = info.name.split(".")
        if "rl" in parts or "experiments" in parts or "_kernels" in parts or parts[-1] == "_kernels":
            continue
        try:
            mod = importlib.import_module(info.name)
        except Exception:  # optional extras (sumo, torch) not installed
            continue
        for name, obj in list(vars(mod).items()):
            if not isinstance(obj, CPUDispatcher):
                continue
            if id(obj) not in wrappers:
                wrappers[id(obj)] = _counter(obj, counts, per[obj.py_func.__name__], calls)
            undo.append((mod, name, obj))
            setattr(mod, name, wrappers[id(obj)])
    return undo


def _returned(r) -> int:
    if isinstance(r, np.ndarray):
        return 1
    if isinstance(r, tuple):
        return sum(_returned(x) for x in r)
    return 0


def _clone(x):
    """A copy of a kernel argument for the replay (arrays copied, read-only
    ones kept read-only; tuples looked into; numbers as they are)."""
    if isinstance(x, np.ndarray):
        c = x.copy()
        if not x.flags.writeable:
            c.setflags(write=False)
        return c
    if isinstance(x, tuple):
        return tuple(_clone(v) for v in x)
    return x


def _counter(kernel, counts, own, calls):
    """``kernel`` counted into the totals ``counts`` and its own ``own``,
    its calls recorded for the replay."""
    def counted(*args):
        arrays = sum(isinstance(x, np.ndarray) for x in args)
        calls.append((kernel, _clone(args), _clone(args)))  # (copies before the call: some kernels write into them)
        out = kernel(*args)
        for c in (counts, own):
            c["calls"] += 1
            c["arrays"] += arrays
            c["others"] += len(args) - arrays
            c["returned_arrays"] += _returned(out)
        return out

    return counted


def _replay_by_kernel(calls: list) -> dict:
    """:func:`_replay` of each kernel's calls alone: CPU seconds by kernel name."""
    by = collections.defaultdict(list)
    for call in calls:
        by[call[0].py_func.__name__].append(call)
    return {name: _replay(cl) for name, cl in by.items()}


def _replay(calls: list) -> float:
    """The recorded kernel calls again, back to back with no Python in
    between but the loop: CPU seconds of the second of two passes (the
    first loads any specialisation the copies need, and writes into its own
    copies; the second runs on the other, untouched copies)."""
    for kernel, args, _ in calls:
        kernel(*args)
    c0 = time.process_time()
    for kernel, _, args in calls:
        kernel(*args)
    return time.process_time() - c0


def _estimate(c: dict, n: int, unit: dict) -> dict:
    """The boundary's parts in us per step from the counts ``c`` of ``n``
    steps and the unit costs."""
    return {"fixed": c["calls"] / n * unit["fixed"], "arrays": c["arrays"] / n * unit["per_array"],
            "others": c["others"] / n * unit["per_number"],
            "returned": c["returned_arrays"] / n * unit["per_returned_array"]}


def run_case(case: str, unit: dict, expert: bool = False, seed: int = 0) -> dict:
    make = {"intersection": lambda: _intersection(seed), "ring": lambda: _ring(seed),
            "batched": lambda: _batched(expert, seed)}[case]
    window = make()
    window()  # (the first window loads what the warm-up did not: the second is timed)
    c0 = time.process_time()
    n = window()
    step_us = (time.process_time() - c0) / n * 1e6
    window = make()  # a fresh run of the same steps (same seed), the timed window counted
    window()
    counts = collections.Counter()
    per_kernel = collections.defaultdict(collections.Counter)
    calls = []
    undo = _wrap_kernels(counts, per_kernel, calls)
    try:
        n2 = window()
    finally:
        for mod, name, obj in undo:
            setattr(mod, name, obj)
    replay_us = _replay(calls) / n2 * 1e6
    replayed = {k: v / n2 * 1e6 for k, v in _replay_by_kernel(calls).items()}
    per = {k: counts[k] / n2 for k in ("calls", "arrays", "others", "returned_arrays")}
    parts = _estimate(counts, n2, unit)
    est = sum(parts.values())
    kernels = sorted(({"kernel": k, **{f: c[f] / n2 for f in per}, "estimate_us": sum(_estimate(c, n2, unit).values()),
                       "replayed_us": replayed.get(k, 0.0)}
                      for k, c in per_kernel.items()), key=lambda r: -r["estimate_us"])
    return {"case": case, "expert": bool(expert), "seed": int(seed), "step_us": step_us, "per_step": per, "estimate_us": est,
            "estimate_parts_us": parts, "share_of_step": est / step_us, "replay_us": replay_us,
            "replay_share_of_step": replay_us / step_us, "kernels": kernels}


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--case", choices=("intersection", "batched", "ring", "both"), default="both")
    p.add_argument("--expert", action="store_true", help="batched case: the expert's action for every agent")
    p.add_argument("--seed", type=int, default=0, help="the run's seed (both cases)")
    p.add_argument("--top", type=int, default=8, help="kernels listed per case (largest estimate first)")
    p.add_argument("--out")
    a = p.parse_args()
    if a.expert and a.case == "intersection":
        p.error("--expert applies to the batched case (the intersection's agents always act by the expert); "
                "allowed with --case batched or both")
    if a.top < 0:
        p.error(f"--top {a.top}; allowed: an integer >= 0")
    unit = _unit_costs()
    print("unit costs here (us): " + ", ".join(f"{k} {v:.3f}" for k, v in unit.items()))
    res = {"unit_costs_us": unit, "cases": []}
    for case in (("intersection", "batched") if a.case == "both" else (a.case,)):
        r = run_case(case, unit, expert=a.expert and case == "batched", seed=a.seed)
        res["cases"].append(r)
        ps = r["per_step"]
        what = "world-step" if case == "batched" else "step"
        print(f"{case}: {r['step_us']:.0f} us per {what}; {ps['calls']:.1f} kernel calls, {ps['arrays']:.0f} array "
              f"arguments, {ps['others']:.0f} other arguments, {ps['returned_arrays']:.1f} returned arrays; "
              f"boundary about {r['estimate_us']:.1f} us = {100 * r['share_of_step']:.0f}% of the {what} ("
              + ", ".join(f"{k} {v:.1f}" for k, v in r["estimate_parts_us"].items()) + ")")
        print(f"  the same kernel calls replayed back to back: {r['replay_us']:.1f} us per {what} = "
              f"{100 * r['replay_share_of_step']:.0f}% of it (kernels and their boundary); the rest, "
              f"{r['step_us'] - r['replay_us']:.0f} us, is the Python around them")
        for k in r["kernels"][:a.top]:
            print(f"    {k['kernel']:30s} {k['calls']:5.2f} calls, {k['arrays']:5.1f} arrays, {k['others']:5.1f} others, "
                  f"{k['returned_arrays']:4.1f} returned: about {k['estimate_us']:.2f} us; replayed "
                  f"{k['replayed_us']:.2f} us")
    line = json.dumps(res)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(line + "\n")
    print(line)


if __name__ == "__main__":
    main()
