"""Time spent in each compiled kernel per policy step (issue 10).

    PYTHONPATH=$PWD python scripts/bench_kernels.py [--case ring|intersection] [--steps N]

Every numba dispatcher that a non-kernel module of :mod:`icv_envs` holds is
wrapped with a ``time.perf_counter`` timer (calls from one kernel to another
stay compiled and count in the caller), then ``--steps`` policy steps run:

* ``ring`` (default 250 steps): HighwayRamps at VGR 1/3 under the formation
  expert through the PettingZoo API, after 300 s of warm-up (about 440
  vehicles);
* ``intersection`` (default 600 steps): multi-vp at 2200 veh/h, the zones
  filled to 60 vehicles first, the expert's action from the infos.

Prints the process CPU time per step, the kernels' total, and per kernel its
time per step, calls per step and time per call (the call's dispatch from
Python included). Compare two trees by running it in each, alternately:
single figures move by 20-30% on a shared machine.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import time


def wrap_kernels(acc: dict) -> None:
    """Wrap the numba dispatchers held by :mod:`icv_envs`'s non-kernel
    modules so that each call's time adds to ``acc[name] = [seconds, calls]``."""
    from numba.core.registry import CPUDispatcher

    import icv_envs

    wrapped: dict[int, object] = {}

    def wrap(name, d):
        if id(d) not in wrapped:
            def timed(*args, **kwargs):
                t = time.perf_counter()
                try:
                    return d(*args, **kwargs)
                finally:
                    v = acc.setdefault(name, [0.0, 0])
                    v[0] += time.perf_counter() - t
                    v[1] += 1
            wrapped[id(d)] = timed
        return wrapped[id(d)]

    skip = ("icv_envs.rl", "icv_envs.cli", "icv_envs.experiments")
    for info in pkgutil.walk_packages(icv_envs.__path__, "icv_envs."):
        if info.name.startswith(skip) or "_kernels" in info.name:
            continue
        try:
            mod = importlib.import_module(info.name)
        except ImportError:  # an optional extra's module
            continue
        for k, v in list(vars(mod).items()):
            if isinstance(v, CPUDispatcher):
                setattr(mod, k, wrap(k, v))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--case", choices=["ring", "intersection"], default="ring")
    p.add_argument("--steps", type=int, default=None)
    a = p.parse_args()
    acc: dict[str, list] = {}
    wrap_kernels(acc)
    if a.case == "ring":
        from icv_envs.envs import highway_ramps_v0

        n = a.steps or 250
        env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=300.0 + n / 5.0 + 10.0)
        env.reset(seed=0)
        for _ in range(1500):
            ex = env.expert_actions()
            env.step({ag: ex[ag] for ag in env.agents})

        def step():
            ex = env.expert_actions()
            env.step({ag: ex[ag] for ag in env.agents})
    else:
        from icv_envs.envs.intersection_v0 import parallel_env

        n = a.steps or 600
        env = parallel_env(method="multi-vp", throughput=2200.0, duration=300.0 + n / 5.0 + 10.0)
        _, infos = env.reset(seed=0)
        box = [infos]
        while len(env.agents) < 60 and env.core.world.time < 300:
            box[0] = env.step({ag: box[0][ag]["expert_action"] for ag in env.agents})[4]

        def step():
            box[0] = env.step({ag: box[0][ag]["expert_action"] for ag in env.agents})[4]
    acc.clear()
    t = time.process_time()
    for _ in range(n):
        step()
    total = time.process_time() - t
    print(f"{a.case}: step {total / n * 1e3:.3f} ms CPU; compiled kernels {sum(v[0] for v in acc.values()) / n * 1e3:.3f} ms")
    for k, (sec, calls) in sorted(acc.items(), key=lambda kv: -kv[1][0]):
        print(f"  {k:28s} {sec / n * 1e6:8.1f} us/step  {calls / n:5.2f} calls/step  {sec / calls * 1e6:8.1f} us/call")


if __name__ == "__main__":
    main()
