"""Benchmarks: wall time per simulated second, as ratios against a reference
measured in the same run (machines are noisy; never assert wall times).

``bench_highway_formation`` runs, at each vehicle count, this package's
HighwayFormation env with the formation expert acting (every vehicle an
agent, expert actions computed every step, observations and rewards for all
agents) and stock highway-env ``highway-v0`` with the same number of IDM
vehicles, and reports the ratio of their wall time per simulated second.
"""

from __future__ import annotations

import math
import time

import numpy as np

from icv_envs._args import check_float, check_int, check_int_list
from icv_envs._jit_clock import JitClock, jit_note, rss_note

__all__ = ["bench_highway_formation", "time_icv", "time_highway_v0", "APIS"]

#: how a bench's agents are stepped (``--api`` of ``bench highway-ramps
#: --vs-sumo`` and ``bench intersection``), as the env's keyword arguments:
#: PettingZoo's dicts with every info key (the default), PettingZoo's dicts
#: without per-step info keys (``info_keys=[]``, ``expert_in_info=False``:
#: the loop reads the expert itself), or the array path
#: (:meth:`~icv_envs.envs.parallel.CoreParallelEnv.step_rows`)
APIS = {"dicts": {}, "lean": {"info_keys": [], "expert_in_info": False}, "rows": {"expert_in_info": False}}


def time_icv(n: int, seconds: float = 10.0, seed: int = 0, warmup: float = 1.0) -> dict:
    """Wall time per simulated second of HighwayFormation with ``n`` agents
    under the expert, over ``seconds`` after ``warmup`` untimed simulated
    seconds (the first steps of a process load the compiled kernels from
    their cache: about 1 ms each, which at 50 vehicles doubled the figure);
    time numba spends in its compiler inside the window is excluded and
    reported (:mod:`icv_envs._jit_clock`, from stop 54)."""
    from icv_envs.envs.highway_formation_v0 import parallel_env

    n, seed = check_int("n", n, 1), check_int("seed", seed, 0)
    seconds, warmup = check_float("seconds", seconds, 0), check_float("warmup", warmup, 0, strict=False)
    # formations of 12 with 60 m between them, on a road long enough to drive
    # ``warmup + seconds`` at 30 m/s
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    total = float(seconds + warmup)
    env = parallel_env(
        vehicles_count=n, formation_size=12, initial_position=None,
        road_length=float(span + 30.0 * total + 300.0), duration=total,
    )
    obs, infos = env.reset(seed=seed)
    while env.agents and env.core.world.time < warmup - 1e-9:
        ex = env.expert_actions()
        obs, rew, term, trunc, infos = env.step({a: ex[a] for a in env.agents})
    t_warm = env.core.world.time
    steps = 0
    with JitClock() as jit:  # the window, numba's compiler excluded (icv_envs/_jit_clock.py)
        while env.agents:
            ex = env.expert_actions()
            obs, rew, term, trunc, infos = env.step({a: ex[a] for a in env.agents})
            steps += 1
    wall = jit.wall
    sim = env.core.world.time - t_warm
    m = env.metrics()
    env.close()
    return {"wall_per_sim_s": wall / sim, "sim_seconds": sim, "collisions": m["collisions"], "vehicles": n,
            "simulation_frequency": env.core.config["simulation_frequency"], **jit.as_dict()}


def time_highway_v0(n: int, seconds: float = 1.0, seed: int = 0) -> dict:
    import gymnasium as gym
    import highway_env  # noqa: F401  (registers highway-v0)

    n, seed, seconds = check_int("n", n, 1), check_int("seed", seed, 0), check_float("seconds", seconds, 0)
    env = gym.make("highway-v0", config={"vehicles_count": n, "duration": 10_000})
    env.reset(seed=seed)
    cfg = env.unwrapped.config
    steps_wanted = max(1, int(round(seconds * cfg["policy_frequency"])))
    t0 = time.perf_counter()
    steps = 0
    for _ in range(steps_wanted):
        _, _, term, trunc, _ = env.step(1)  # IDLE
        steps += 1
        if term or trunc:
            break
    wall = time.perf_counter() - t0
    sim = steps / cfg["policy_frequency"]
    n_vehicles = len(env.unwrapped.road.vehicles)
    env.close()
    return {"wall_per_sim_s": wall / sim, "sim_seconds": sim, "vehicles": n_vehicles,
            "simulation_frequency": cfg["simulation_frequency"]}


def bench_highway_formation(sizes=(50, 200, 800), seconds: float = 10.0, stock_seconds: float = 1.0,
                            echo=print) -> dict:
    sizes = check_int_list("sizes", sizes, 1, "vehicle counts")
    check_float("seconds", seconds, 0)
    check_float("stock_seconds", stock_seconds, 0)
    rows = []
    for n in sizes:
        ours = time_icv(n, seconds)
        stock = time_highway_v0(n, stock_seconds)
        ratio = stock["wall_per_sim_s"] / ours["wall_per_sim_s"]
        row = {
            "vehicles": n,
            "icv_envs_wall_per_sim_s": ours["wall_per_sim_s"],
            "highway_v0_wall_per_sim_s": stock["wall_per_sim_s"],
            "speedup": ratio,
            "icv_envs_real_time_factor": 1.0 / ours["wall_per_sim_s"],
            "icv_envs_collisions": ours["collisions"],
            "icv_envs_hz": ours["simulation_frequency"],
            "highway_v0_hz": stock["simulation_frequency"],
            "jit_seconds_excluded": ours["jit_seconds_excluded"], "jit_compiles": ours["jit_compiles"],
        }
        rows.append(row)
        echo(
            f"{n:5d} vehicles: icv_envs {ours['wall_per_sim_s'] * 1e3:9.2f} ms/sim-s ({ours['simulation_frequency']} Hz)  "
            f"highway-v0 {stock['wall_per_sim_s'] * 1e3:10.1f} ms/sim-s ({stock['simulation_frequency']} Hz)  "
            f"speedup x{ratio:8.1f}"
        )
        if ours["jit_seconds_excluded"] > 0:
            echo("        " + jit_note(ours["jit_seconds_excluded"], ours["jit_compiles"]))
    at200 = [r["speedup"] for r in rows if r["vehicles"] == 200]
    return {"bench": "highway-formation", "results": rows, "speedup_at_200": at200[0] if at200 else None,
            "python": _platform()}


def _platform() -> str:
    import platform

    return f"{platform.python_implementation()} {platform.python_version()} numpy {np.__version__}"


def bench_highway_ramps(seconds: float = 600.0, vgr: float = 1.0 / 3.0, seed: int = 0, echo=print) -> dict:
    """600 simulated seconds of HighwayRamps at VGR 1/3 under the formation
    expert, in this process (one core): real-time factor, vehicles on the road
    at the end, vehicle-steps per wall second and peak resident memory
    (the time numba spends in its compiler inside the run excluded and
    reported, from stop 54; the peak memory cannot exclude the compiler's,
    ``peak_rss_includes_compiler`` says when a first run's compilation is
    in it: 643 MB against 326 MB on the next run at stop 54,
    ``results/bench/stop54/cold_vs_warm/``)."""
    import resource

    from icv_envs.experiments._checks import check_vgr
    from icv_envs.experiments.compare import run_ramps

    seconds = check_float("seconds", seconds, 0)
    vgr = check_vgr(vgr)
    jit = JitClock()  # numba's compiler inside the run's loop, excluded (icv_envs/_jit_clock.py)
    m = run_ramps("formation", vgr, seed, seconds, jit=jit)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    steps = m["vehicle_steps"] if "vehicle_steps" in m else None
    res = {
        "bench": "highway-ramps",
        "method": "formation",
        "vgr": vgr,
        "sim_seconds": seconds,
        "wall_seconds": m["wall_seconds"],
        "real_time_factor": m["real_time_factor"],
        "vehicles": m["remaining"],
        "vehicle_steps_per_s": (steps / m["wall_seconds"]) if steps else None,
        "peak_rss_mb": peak_mb,
        "collisions": m["collisions"],
        "lost": m["lost"],
        **jit.as_dict(),
        "peak_rss_includes_compiler": jit.compiles > 0,
    }
    echo(f"highway-ramps: {seconds:g} s at VGR {vgr:.3g} in {m['wall_seconds']:.1f} s wall "
         f"(x{res['real_time_factor']:.1f} real time), {res['vehicles']} vehicles at the end, peak RSS {peak_mb:.0f} MB")
    if jit.seconds > 0:
        echo("  " + jit.note("the run"))
    if jit.compiles:
        echo("  " + rss_note(jit.compiles))
    return res
