"""The paper's intersection comparison (Sec. 6.2, Fig. 14): methods x throughputs x seeds.

``compare_intersection`` runs every (method, throughput, seed) of the grid
in a local process pool (default: one worker per core) or on a Ray cluster
(``backend="ray"``), shows a progress bar and writes to ``out``:

* ``results.csv``: one row per run (columns :data:`CSV_COLUMNS`: ``method,
  throughput, seed, collisions, lost, achieved_throughput, mean_speed,
  speed_fluctuation, mean_delay, ...``);
* ``runs/<method>_tp<throughput>_seed<seed>.json``: the run's metrics;
* ``mean_speed_vs_throughput.png`` and ``speed_fluctuation_vs_throughput.png``
  (the paper's Fig. 14 a and b: seed mean per method, min-max band), plus
  ``achieved_throughput_vs_throughput.png`` and ``mean_delay_vs_throughput.png``;
* ``summary.json``: per method and throughput, the seed means and the
  collision / lost totals.

Definitions (one place each): ``mean_speed`` and ``speed_fluctuation`` (mean
|a|) over all vehicle-substeps, :mod:`icv_envs.experiments.metrics`;
``throughput`` is the demand (vehicles/h generated at R3, all legs);
``achieved_throughput`` the vehicles/h that cleared the box over the run
(lower than the demand in short runs: nothing clears during the first ~80 s,
the free-flow travel time from R3); ``mean_delay`` the mean over vehicles
that cleared the box of their travel time from R3 minus that distance at
the desired speed (10 m/s), so a vehicle faster than 10 m/s has a negative
delay; ``lost`` = spawned - removed - left_road - remaining - crashed_removed
must be 0.
"""

from __future__ import annotations

import csv
import json
import math
import time
from pathlib import Path

import numpy as np

from icv_envs.envs.intersection import MAX_THROUGHPUT, METHODS
from icv_envs.experiments.compare import check_backend, run_jobs

__all__ = ["CSV_COLUMNS", "METHODS", "validate_grid", "run_intersection", "compare_intersection",
           "summarise", "plot_results"]

CSV_COLUMNS = [
    "method", "throughput", "seed", "seconds", "lane_use", "collisions", "lost", "achieved_throughput",
    "mean_speed", "speed_fluctuation", "mean_delay", "spawned", "cleared", "remaining", "queued",
    "envelope_box_binding", "virtual_cap_binding", "wall_seconds", "real_time_factor",
]
_COLOURS = {"multi-vp": "tab:red", "single-vp": "tab:blue", "fcfs": "tab:grey"}


def validate_grid(methods, throughputs, seeds, seconds) -> None:
    """Raise ValueError naming the bad value: unknown method, throughput <= 0, seeds < 1, seconds <= 0."""
    methods = list(methods)
    if not methods:
        raise ValueError("no methods given; allowed: " + ", ".join(METHODS))
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"unknown methods {bad}; allowed: {list(METHODS)}")
    if not list(throughputs):
        raise ValueError("no throughput given")
    for v in throughputs:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= MAX_THROUGHPUT:
            raise ValueError(f"throughput {v!r} is invalid; allowed: 0 < throughput <= {MAX_THROUGHPUT:g} vehicles/h")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ValueError(f"seeds = {seeds!r}; allowed: an integer >= 1 (runs use seeds 0..seeds-1)")
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) or seconds <= 0:
        raise ValueError(f"seconds = {seconds!r}; allowed: a number > 0")


def run_intersection(method: str, throughput: float, seed: int, seconds: float, config: dict | None = None) -> dict:
    """One run of the intersection driven by the method's expert; returns its metrics."""
    from icv_envs.envs.intersection_v0 import parallel_env

    cfg = {"expert_in_info": False}
    cfg.update(config or {})
    cfg.update({"method": method, "throughput": float(throughput), "duration": float(seconds)})
    env = parallel_env(**cfg)
    env.reset(seed=int(seed))
    t0 = time.perf_counter()
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    wall = time.perf_counter() - t0
    m = env.metrics()
    m.update({"seed": int(seed), "seconds": float(seconds), "wall_seconds": wall,
              "real_time_factor": float(seconds) / wall if wall > 0 else None,
              "collision_log": [list(c) for c in env.core.world.collision_log[:50]]})
    env.close()
    return m


def _run_job(args):
    return run_intersection(*args)


def _tag(method, throughput, seed) -> str:
    return f"{method}_tp{throughput:g}_seed{seed}"


def compare_intersection(methods, throughputs, seeds: int, seconds: float, out, backend: str = "process",
                         workers: int | None = None, progress: bool = True, config: dict | None = None) -> dict:
    """Run the grid (see the module docstring) and write CSV, JSON and plots to ``out``."""
    validate_grid(methods, throughputs, seeds, seconds)
    check_backend(backend)
    if config:
        # fail fast on a bad config, before starting workers
        from icv_envs.envs.intersection import IntersectionEnv

        IntersectionEnv(dict(config, duration=1.0))
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    jobs = [(m, float(v), s, float(seconds), config) for m in methods for v in throughputs for s in range(seeds)]
    results = run_jobs(_run_job, jobs, backend, workers, progress, "intersection runs")
    order = list(methods)
    results.sort(key=lambda r: (order.index(r["method"]), r["throughput"], r["seed"]))
    for r in results:
        (out / "runs" / f"{_tag(r['method'], r['throughput'], r['seed'])}.json").write_text(json.dumps(r))
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for r in results:
            w.writerow({k: r.get(k) for k in CSV_COLUMNS})
    summary = summarise(results)
    summary["plots"] = plot_results(results, out)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def summarise(results) -> dict:
    rows = {}
    for r in results:
        rows.setdefault((r["method"], r["throughput"]), []).append(r)
    table = []
    for (m, v), rs in sorted(rows.items(), key=lambda kv: (kv[0][1], METHODS.index(kv[0][0]))):
        delays = [x["mean_delay"] for x in rs if x["mean_delay"] is not None]
        table.append({
            "method": m, "throughput": v, "seeds": len(rs),
            **{k: float(np.mean([x[k] for x in rs])) for k in ("achieved_throughput", "mean_speed",
                                                                 "speed_fluctuation", "remaining", "queued")},
            "mean_delay": float(np.mean(delays)) if delays else None,
            "collisions": int(sum(x["collisions"] for x in rs)),
            "lost": int(sum(x["lost"] for x in rs)),
            "envelope_box_binding": int(sum(x.get("envelope_box_binding", 0) for x in rs)),
        })
    return {"runs": len(results), "table": table,
            "collisions": int(sum(r["collisions"] for r in results)),
            "lost": int(sum(r["lost"] for r in results))}


def plot_results(results, out) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    methods = sorted({r["method"] for r in results}, key=lambda m: METHODS.index(m))
    files = []
    for key, label in (("mean_speed", "average speed [m/s]"),
                       ("speed_fluctuation", "average speed fluctuation: mean |a| [m/s$^2$]"),
                       ("achieved_throughput", "achieved throughput [veh/h]"),
                       ("mean_delay", "mean delay [s]")):
        fig, ax = plt.subplots(figsize=(6, 4))
        for m in methods:
            vs = sorted({r["throughput"] for r in results if r["method"] == m})
            ys = [[r[key] for r in results if r["method"] == m and r["throughput"] == v and r[key] is not None]
                  for v in vs]
            keep = [i for i, y in enumerate(ys) if y]
            vs = [vs[i] for i in keep]
            ys = [ys[i] for i in keep]
            if not vs:
                continue
            ax.plot(vs, [np.mean(y) for y in ys], "o-", color=_COLOURS.get(m), label=m)
            ax.fill_between(vs, [min(y) for y in ys], [max(y) for y in ys], color=_COLOURS.get(m), alpha=0.15)
        if key == "achieved_throughput":
            lim = max(r["throughput"] for r in results)
            ax.plot([0, lim], [0, lim], ":", color="k", lw=0.8, label="demand")
        ax.set_xlabel("throughput demand [vehicles/h entering the intersection]")
        ax.set_ylabel(label)
        ax.set_title(f"Intersection: {key.replace('_', ' ')} vs throughput")
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        path = out / f"{key}_vs_throughput.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        files.append(str(path))
    return files


def parse_throughputs(text: str) -> list[float]:
    """``"1000,1500"`` -> ``[1000.0, 1500.0]``; ValueError naming the value unless every entry is a number > 0."""
    try:
        vals = [float(v) for v in str(text).split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--throughput must be comma-separated numbers of vehicles/h, got {text!r}") from None
    if not vals:
        raise ValueError("--throughput is empty")
    for v in vals:
        if not math.isfinite(v) or not 0 < v <= MAX_THROUGHPUT:
            raise ValueError(f"throughput {v!r} is invalid; allowed: 0 < throughput <= {MAX_THROUGHPUT:g} vehicles/h")
    return vals


def run_cli(args, echo=print) -> dict:
    """``icv-envs compare intersection``: ``args`` has ``methods`` (list or comma
    string; default all three), ``throughput`` (list or comma string),
    ``seeds``, ``seconds``, ``out``, ``backend``, ``workers`` and optionally
    ``lane_use``.  Prints one line per (method, throughput) and returns the
    summary (the CLI prints it as the last JSON line)."""
    methods = getattr(args, "methods", None) or list(METHODS)
    if isinstance(methods, str):
        methods = [m.strip() for m in methods.split(",") if m.strip()]
    tps = getattr(args, "throughput", None) or [1000.0, 1500.0, 2000.0, 2500.0, 3000.0]
    if isinstance(tps, str):
        tps = parse_throughputs(tps)
    config = {}
    if getattr(args, "lane_use", None):
        config["lane_use"] = args.lane_use
    summary = compare_intersection(methods, tps, args.seeds, float(args.seconds), args.out,
                                   backend=getattr(args, "backend", "process"),
                                   workers=getattr(args, "workers", None), progress=getattr(args, "progress", True),
                                   config=config or None)
    for row in summary["table"]:
        delay = "n/a" if row["mean_delay"] is None else f"{row['mean_delay']:6.2f}"
        echo(f"{row['method']:9s} throughput={row['throughput']:<6g} achieved={row['achieved_throughput']:7.1f} "
             f"mean_speed={row['mean_speed']:6.2f} speed_fluctuation={row['speed_fluctuation']:.3f} "
             f"mean_delay={delay} collisions={row['collisions']} lost={row['lost']}")
    summary["out"] = str(args.out)
    return summary


if __name__ == "__main__":  # pragma: no cover
    import argparse
    import sys

    p = argparse.ArgumentParser(description="intersection sweep (see the module docstring)")
    p.add_argument("--methods", default="multi-vp,single-vp,fcfs")
    p.add_argument("--throughput", default="1000,1500,2000,2500,3000")
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--out", default="intersection_out")
    p.add_argument("--backend", default="process")
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--lane-use", dest="lane_use", default=None)
    a = p.parse_args()
    try:
        s = run_cli(a)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
    print(json.dumps(s))
