"""This package against SUMO on the same road, in one process (issue 10).

``ramps_vs_sumo`` -- ``icv-envs bench highway-ramps --vs-sumo``: the paper's
ring (HighwayRamps, VGR 1/3, formation method, every vehicle an agent of the
PettingZoo parallel API, the formation expert's action read and fed back
every step) is run to ``seconds - measure`` (not timed); then SUMO starts on
the same 10 km four-lane ring (:mod:`icv_envs.experiments.sumo_ring`) with
as many vehicles as the ring holds at that moment, warms up ``sumo_warmup``
simulated seconds, and the last ``measure`` seconds are timed in
``chunks`` alternating slices, ours then SUMO's, so both see the same
machine load. Vehicle-steps are physics steps of one vehicle (25 Hz both:
ours steps the policy at 5 Hz with 5 physics sub-steps). ``api`` (``--api``)
says how the agents are stepped: ``dicts`` (PettingZoo's dicts with every
info key, the default and the issue's bar), ``lean`` (PettingZoo's dicts,
``info_keys=[]``, no expert label in the infos) or ``rows`` (the array path,
``step_rows``, no dicts); the three drive the same trajectory.

Time base: process CPU time (libsumo runs in this process and thread, so
both are charged the same way; on a shared machine wall time also counts
the other processes' time slices). Wall time is reported too, and each
pair of slices' own ratio (``ratio_cpu_chunks``, from stop 54: how much
the run's ratio could move on this host at the slices' scale). Time numba
spends in its compiler inside our timed slices (a first run on a machine)
is excluded from both and reported (:mod:`icv_envs._jit_clock`, stop 54).

``scaling`` -- ms of CPU per simulated second against the vehicle count,
HighwayFormation (straight road, formations of 12, expert, PettingZoo API)
beside SUMO's ring with the same count; CSV + PNG (``python -m
icv_envs.experiments.sumo_bench scaling --out results/bench``).
"""

from __future__ import annotations

import argparse
import collections
import csv
import json
import math
import platform
import resource
import sys
from pathlib import Path

import numpy as np

from icv_envs._args import check_float, check_int, check_int_list
from icv_envs._gc_clock import GcClock
from icv_envs._jit_clock import JitClock, jit_note, rss_note
from icv_envs.experiments._checks import check_vgr
from icv_envs.experiments.bench import APIS  # (how the ring's agents are stepped, ``--api``)

__all__ = ["ramps_vs_sumo", "scaling", "plot_scaling", "time_icv_formation", "time_sumo"]


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _vehicle_steps(env) -> int:
    """Vehicle-steps (one vehicle, one physics step) the env's world has simulated so far."""
    w = env.core.world
    motion = getattr(w, "motion", None)  # the highway worlds count them in their motion statistics
    return int(motion.vehicle_steps) if motion is not None else int(w.stats["vehicle_steps"])




def _icv_steps(env, policy_steps: int, api: str = "dicts") -> None:
    """``policy_steps`` steps of the formation expert driving every agent, through ``api``."""
    if api == "rows":
        core = env.core
        for _ in range(policy_steps):
            env.step_rows(core.expert_actions())
        return
    for _ in range(policy_steps):
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})


def _icv_chunk(env, policy_steps: int, api: str = "dicts") -> dict:
    """``policy_steps`` timed steps: CPU and wall seconds without the time
    numba spent in its compiler (:mod:`icv_envs._jit_clock`), which is
    reported as ``jit_seconds_excluded`` / ``jit_compiles``; the garbage
    collector's time inside them, included, as ``gc_seconds`` /
    ``gc_full_collections`` (:mod:`icv_envs._gc_clock`, from stop 54)."""
    vs0 = _vehicle_steps(env)
    with GcClock() as gcc, JitClock() as jit:
        _icv_steps(env, policy_steps, api)
    return {"cpu": jit.cpu, "wall": jit.wall, "vehicle_steps": _vehicle_steps(env) - vs0, **jit.as_dict(), **gcc.as_dict()}


def ramps_vs_sumo(seconds: float = 600.0, measure: float = 100.0, vgr: float = 1.0 / 3.0, seed: int = 0,
                  chunks: int = 10, sumo_warmup: float = 20.0, api: str = "dicts", echo=print) -> dict:
    from tqdm import tqdm

    from icv_envs.envs.highway_ramps_v0 import parallel_env
    from icv_envs.experiments.sumo_ring import SumoRing, sumo_available

    seconds, measure = check_float("seconds", seconds, 0), check_float("measure", measure, 0)
    vgr = check_vgr(vgr)
    seed, chunks = check_int("seed", seed, 0), check_int("chunks", chunks, 1)
    sumo_warmup = check_float("sumo_warmup", sumo_warmup, 0, strict=False)
    if not sumo_available():
        raise RuntimeError("--vs-sumo needs SUMO: pip install 'icv-envs[bench]' (eclipse-sumo, libsumo)")
    if not 0 < measure < seconds:
        raise ValueError(f"seconds = {seconds!r} with measure = {measure!r}; allowed: 0 < measure < seconds (the "
                         f"bench times the last {measure:g} s of the run: --seconds must exceed {measure:g})")
    if api not in APIS:
        raise ValueError(f"api = {api!r}; allowed: {list(APIS)}")
    env = parallel_env(vgr=float(vgr), duration=float(seconds), method="formation", **APIS[api])
    env.reset(seed=seed)
    pf = int(env.core.config["policy_frequency"])
    frames = int(env.core.config["simulation_frequency"]) // pf
    warm_steps = int(round((seconds - measure) * pf))
    with JitClock() as warm_jit:  # (counted for the peak memory's note: a first run compiles here)
        for _ in tqdm(range(warm_steps // 50), desc="highway-ramps warm-up (x50 steps)", mininterval=5.0,
                      file=sys.stderr):
            _icv_steps(env, 50, api)
        _icv_steps(env, warm_steps % 50, api)
    warm_cpu = warm_jit.window_cpu_seconds  # (the compiler's included, as before stop 54)
    rss_icv = _rss_mb()
    n = len(env.agents)
    ring = SumoRing(max(n, 1), seed=seed)
    ring.step(int(round(sumo_warmup / ring.dt)))
    per_chunk = int(round(measure * pf / chunks))
    ours = collections.Counter()  # (every figure a chunk reports, summed over the chunks)
    theirs = {"cpu": 0.0, "wall": 0.0, "vehicle_steps": 0}
    counts = []
    chunk_ratios = []  # each slice pair's own ratio: the spread of the run's ratio on this host
    for _ in tqdm(range(chunks), desc="alternating slices", file=sys.stderr):
        counts.append(len(env.agents))
        r = _icv_chunk(env, per_chunk, api)
        ours.update(r)
        q = ring.step(per_chunk * frames)
        for k in theirs:
            theirs[k] += q[k]
        if r["cpu"] > 0 and q["cpu"] > 0 and q["vehicle_steps"]:
            chunk_ratios.append((r["vehicle_steps"] / r["cpu"]) / (q["vehicle_steps"] / q["cpu"]))
    sumo_vehicles = ring.traci.vehicle.getIDCount()
    ring.close()
    m = env.metrics()
    env.close()
    o_cpu = ours["vehicle_steps"] / ours["cpu"]
    s_cpu = theirs["vehicle_steps"] / theirs["cpu"]
    res = {
        "bench": "highway-ramps-vs-sumo",
        "vgr": float(vgr), "sim_seconds": float(seconds), "measured_seconds": float(measure), "api": api,
        "icv_vehicles": [int(min(counts)), int(max(counts))], "sumo_vehicles": int(sumo_vehicles),
        "icv_vehicle_steps_per_cpu_s": o_cpu, "sumo_vehicle_steps_per_cpu_s": s_cpu, "ratio_cpu": o_cpu / s_cpu,
        "icv_vehicle_steps_per_wall_s": ours["vehicle_steps"] / ours["wall"],
        "sumo_vehicle_steps_per_wall_s": theirs["vehicle_steps"] / theirs["wall"],
        "ratio_wall": (ours["vehicle_steps"] / ours["wall"]) / (theirs["vehicle_steps"] / theirs["wall"]),
        "icv_warmup_cpu_s": warm_cpu, "peak_rss_mb_icv_run": rss_icv, "peak_rss_mb_with_sumo": _rss_mb(),
        "warmup_jit_compiles": warm_jit.compiles,
        "peak_rss_includes_compiler": warm_jit.compiles + ours["jit_compiles"] > 0,
        "collisions": m["collisions"], "lost": m["lost"], "bar_ratio": 4.0,
        "jit_seconds_excluded": ours["jit_seconds_excluded"], "jit_cpu_seconds_excluded": ours["jit_cpu_seconds_excluded"],
        "jit_compiles": ours["jit_compiles"],
        "icv_gc_share": ours["gc_seconds"] / ours["cpu"] if ours["cpu"] > 0 else None,
        "icv_gc_full_collections": ours["gc_full_collections"],
        "ratio_cpu_chunks": chunk_ratios,
        "ratio_cpu_chunks_median": float(np.median(chunk_ratios)) if chunk_ratios else None,
        "sumo": "SUMO 1.28 libsumo, Krauss + LC2013, dt 0.04 s",
        "python": f"{platform.python_implementation()} {platform.python_version()} numpy {np.__version__}",
    }
    echo(f"highway-ramps VGR {vgr:.3g} ({api}), last {measure:g} s of {seconds:g}: icv_envs {o_cpu:,.0f} veh-steps/s "
         f"({res['icv_vehicles'][0]}-{res['icv_vehicles'][1]} vehicles), SUMO {s_cpu:,.0f} veh-steps/s "
         f"({sumo_vehicles} vehicles): x{res['ratio_cpu']:.2f} (CPU time; wall x{res['ratio_wall']:.2f}); "
         f"peak RSS {rss_icv:.0f} MB")
    echo(f"  garbage collection {res['icv_gc_share']:.1%} of our CPU time ({ours['gc_full_collections']} full "
         f"collections; included above)")
    if chunk_ratios:
        echo(f"  each pair of slices on its own: median x{np.median(chunk_ratios):.2f}, x{min(chunk_ratios):.2f}-"
             f"x{max(chunk_ratios):.2f} over {len(chunk_ratios)} pairs (this host's noise at the slices' scale)")
    if ours["jit_seconds_excluded"] > 0:
        echo("  " + jit_note(ours["jit_seconds_excluded"], ours["jit_compiles"], "our timed slices"))
    if res["peak_rss_includes_compiler"]:
        echo("  " + rss_note(warm_jit.compiles + ours["jit_compiles"]))
    return res


def time_icv_formation(n: int, seconds: float = 5.0, warmup: float = 1.0, seed: int = 0) -> dict:
    """CPU ms per simulated second of HighwayFormation with ``n`` vehicles
    (formations of 12, expert through the PettingZoo API)."""
    from icv_envs.envs.highway_formation_v0 import parallel_env

    n, seed = check_int("n", n, 1), check_int("seed", seed, 0)
    seconds, warmup = check_float("seconds", seconds, 0), check_float("warmup", warmup, 0, strict=False)
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    total = warmup + seconds
    env = parallel_env(vehicles_count=int(n), formation_size=12, initial_position=None,
                       road_length=float(span + 30.0 * total + 300.0), duration=float(total + 1.0))
    env.reset(seed=seed)
    pf = int(env.core.config["policy_frequency"])
    _icv_chunk(env, int(round(warmup * pf)))
    r = _icv_chunk(env, int(round(seconds * pf)))
    env.close()
    return {"ms_per_sim_s": 1e3 * r["cpu"] / seconds, "vehicle_steps_per_s": r["vehicle_steps"] / r["cpu"],
            "gc_ms_per_sim_s": 1e3 * r["gc_seconds"] / seconds, "gc_full_collections": r["gc_full_collections"]}


def time_sumo(n: int, seconds: float = 5.0, warmup: float = 1.0, seed: int = 0) -> dict:
    from icv_envs.experiments.sumo_ring import SumoRing

    n, seed = check_int("n", n, 1), check_int("seed", seed, 0)
    seconds, warmup = check_float("seconds", seconds, 0), check_float("warmup", warmup, 0, strict=False)
    ring = SumoRing(n, seed=seed)
    ring.step(int(round(warmup / ring.dt)))
    r = ring.step(int(round(seconds / ring.dt)))
    ring.close()
    return {"ms_per_sim_s": 1e3 * r["cpu"] / seconds, "vehicle_steps_per_s": r["vehicle_steps"] / r["cpu"],
            "vehicles": r["vehicles"]}


def scaling(sizes=(50, 100, 200, 400, 800, 1600, 3200), seconds: float = 20.0, out: str | None = None,
            echo=print) -> dict:
    """The scaling curve (module docstring): per size, ``seconds`` simulated
    seconds timed on each side after 1 s not timed. Default 20 s (5 s until
    stop 54): at 3200 agents the garbage collector's full collections come
    about every 40 policy steps (5 in 200, 85 ms each), so a 5 s window (25
    steps) held none or one, and the point moved between 37 and 60 ms per
    simulated second with the process's history (``results/bench/stop54/
    seq3200.txt``, ``seq3200_gc.txt``); 20 s (100 steps) held one or two
    in three runs."""
    from tqdm import tqdm

    from icv_envs.experiments.sumo_ring import sumo_available

    seconds = check_float("seconds", seconds, 0, unit="simulated seconds")
    sizes = check_int_list("sizes", sizes, 1, "vehicle counts")
    rows = []
    for n in tqdm(sizes, desc="scaling", file=sys.stderr):
        o = time_icv_formation(n, seconds)
        s = time_sumo(n, seconds) if sumo_available() else {"ms_per_sim_s": None, "vehicle_steps_per_s": None}
        row = {"vehicles": int(n), "icv_ms_per_sim_s": o["ms_per_sim_s"], "sumo_ms_per_sim_s": s["ms_per_sim_s"],
               "icv_vehicle_steps_per_s": o["vehicle_steps_per_s"],
               "sumo_vehicle_steps_per_s": s["vehicle_steps_per_s"],
               "ratio": (s["ms_per_sim_s"] / o["ms_per_sim_s"]) if s["ms_per_sim_s"] else None,
               "icv_gc_ms_per_sim_s": o["gc_ms_per_sim_s"], "icv_gc_full_collections": o["gc_full_collections"]}
        rows.append(row)
        echo(f"{n:5d} vehicles: icv_envs {o['ms_per_sim_s']:8.1f} ms/sim-s (garbage collection "
             f"{o['gc_ms_per_sim_s']:.1f} of it, {o['gc_full_collections']} full)   SUMO "
             f"{s['ms_per_sim_s'] or float('nan'):8.1f} ms/sim-s   x{row['ratio'] or float('nan'):.2f}")
    res = {"bench": "scaling", "seconds": seconds, "time": "process CPU time", "results": rows}
    if out:
        d = Path(out)
        d.mkdir(parents=True, exist_ok=True)
        with open(d / "scaling.csv", "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        plot_scaling(rows, d / "scaling.png")
        (d / "scaling.json").write_text(json.dumps(res, indent=2))
    return res


def plot_scaling(rows: list, path) -> None:
    """The scaling curve's PNG from its rows (log-log: ours, its garbage
    collection where there was any, SUMO's, real time)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    x = [r["vehicles"] for r in rows]
    ax.loglog(x, [r["icv_ms_per_sim_s"] for r in rows], "o-", label="icv_envs (HighwayFormation, expert, PettingZoo)")
    gcx = [(r["vehicles"], r["icv_gc_ms_per_sim_s"]) for r in rows if r.get("icv_gc_ms_per_sim_s")]
    if gcx:
        ax.loglog(*zip(*gcx), "o:", color="C0", alpha=0.6, label="  of it, Python's garbage collector")
    if rows[0]["sumo_ms_per_sim_s"] is not None:
        ax.loglog(x, [r["sumo_ms_per_sim_s"] for r in rows], "s--", label="SUMO 1.28 libsumo (ring, Krauss+LC2013)")
    ax.loglog(x, [1000.0] * len(x), ":", color="gray", label="real time")
    ax.set_xlabel("vehicles")
    ax.set_ylabel("CPU ms per simulated second (25 Hz physics)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(0.0, 0.93))  # (below the real-time line)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m icv_envs.experiments.sumo_bench")
    p.add_argument("what", choices=["scaling", "ramps"])
    p.add_argument("--sizes", default="50,100,200,400,800,1600,3200")
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    if a.what == "scaling":
        res = scaling([int(s) for s in a.sizes.split(",")], a.seconds, a.out)
    else:
        res = ramps_vs_sumo()
    print(json.dumps(res))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
