"""The paper's highway comparison (Sec. 6.1, Figs. 9-11): methods x VGRs x
seeds on the 10 km ring, in parallel, with a CSV and plots.

``compare_highway_ramps`` runs every (method, vgr, seed) of the grid in a
local process pool (default: one worker per core) or on a Ray cluster
(``backend="ray"``), shows a progress bar, and writes to ``out``:

* ``results.csv``: one row per run (``method, vgr, seed, collisions, lost,
  remaining, mean_speed, speed_fluctuation, speed_std, stopped_share,
  commanded_abs_accel, min_gap, min_time_headway, time_headway_p05, ...``;
  definitions in :mod:`icv_envs.sim.metrics`);
* ``runs/<method>_vgr<vgr>_seed<seed>.json``: the run's totals, its 1 Hz time
  series and its density heat maps;
* ``remaining_vs_vgr.png``, ``remaining_plus_queued_vs_vgr.png``,
  ``mean_speed_vs_vgr.png``, ``speed_fluctuation_vs_vgr.png``,
  ``min_time_headway_vs_vgr.png``, ``time_headway_p05_vs_vgr.png`` (seed mean and 95% confidence interval
  per method), ``remaining_vs_time.png`` (Fig. 9 style);
* ``heatmap.png`` (Fig. 10 as the paper draws it): vehicles per 500 m per
  lane, at the VGR nearest 1/3 and the first seed, one row per method, the
  snapshot at the end of the run (t = 600 s for 600 s runs) beside the time
  average, all panels on ONE colour scale so colours compare across
  methods; ``heatmap_<method>.png``: the same per method (same scale);
* ``summary.json``: per method and VGR, the seed means and the half-widths
  of their 95% confidence intervals (Student t, ``<key>_ci95``).
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from icv_envs.envs.highway_ramps import MAX_VGR, METHODS
from icv_envs._args import check_float, check_int
from icv_envs.experiments._checks import check_run_config, check_vgr, check_workers

__all__ = ["run_ramps", "compare_highway_ramps", "run_jobs", "CSV_COLUMNS", "validate_grid"]

CSV_COLUMNS = [
    "method", "vgr", "seed", "seconds", "collisions", "lost", "remaining", "queued", "mean_speed",
    "speed_fluctuation", "speed_std", "stopped_share", "commanded_abs_accel", "spawned", "exited", "missed_exits",
    "not_spawned", "min_gap", "min_time_headway", "time_headway_p05", "wall_seconds", "real_time_factor",
]
#: per-run figures summarised over seeds (mean and 95% CI)
SUMMARY_KEYS = ("remaining", "queued", "remaining_plus_queued", "mean_speed", "speed_fluctuation", "speed_std",
                "stopped_share", "commanded_abs_accel", "exited", "missed_exits", "min_gap", "min_time_headway",
                "time_headway_p05")


def validate_methods(methods) -> None:
    """A non-empty list of HighwayRamps method names, or ValueError naming the bad ones."""
    methods = list(methods)
    if not methods:
        raise ValueError("no methods given; allowed: " + ", ".join(METHODS))
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"unknown methods {bad}; allowed: {list(METHODS)}")
    if len(set(methods)) != len(methods):
        raise ValueError(f"methods = {methods!r} repeat a method; allowed: distinct methods")


def validate_grid(methods, vgrs, seeds, seconds) -> None:
    """Raise ValueError naming the bad value: ``methods`` and ``vgrs`` lists
    (a bare string or number is not a list), known methods, 0 < vgr <=
    :data:`MAX_VGR`, seeds (:func:`_seed_list`), seconds > 0 (bools are not numbers)."""
    for name, vals, eg in (("methods", methods, "['formation']"), ("vgrs", vgrs, "[0.33]")):
        if not isinstance(vals, (list, tuple)):
            raise ValueError(f"{name} = {vals!r}; allowed: a list, e.g. {eg}")
    validate_methods(methods)
    if not list(vgrs):
        raise ValueError("no VGR given")
    if len(set(vgrs)) != len(vgrs):
        raise ValueError(f"vgrs = {vgrs!r} repeat a value; allowed: distinct values")
    for v in vgrs:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= MAX_VGR:
            raise ValueError(f"vgr {v!r} is invalid; allowed: 0 < vgr <= {MAX_VGR} vehicles/s per ramp")
    _seed_list(seeds)
    check_float("seconds", seconds, 0)


def _seed_list(seeds) -> list[int]:
    """``seeds``: a count N (seeds 0..N-1), a list of seeds, or the text
    forms of :func:`icv_envs.experiments.seeds.parse_seeds`."""
    from icv_envs.experiments.seeds import parse_seeds

    if isinstance(seeds, (list, tuple)):
        bad = [s for s in seeds if isinstance(s, bool) or not isinstance(s, int) or s < 0]
        if bad or not seeds or len(set(seeds)) != len(seeds):
            raise ValueError(f"seeds = {seeds!r}; allowed: a non-empty list of distinct integers >= 0, or a count")
        return list(seeds)
    return parse_seeds(seeds)


def run_ramps(method: str, vgr: float, seed: int, seconds: float, config: dict | None = None, jit=None) -> dict:
    """One run of HighwayRamps driven by the method's controller; returns
    the totals plus ``timeseries`` and heat maps. ``jit``: a
    :class:`~icv_envs._jit_clock.JitClock` the run's loop runs inside,
    whose time is taken out of ``wall_seconds`` (``icv-envs bench
    highway-ramps``; a sweep's runs report their whole loop)."""
    from icv_envs.envs.highway_ramps_v0 import parallel_env

    seed = check_int("seed", seed, 0)
    seconds = check_float("seconds", seconds, 0)
    config = check_run_config(config, {"method": "method (--method)", "vgr": "vgr (--vgr)",
                                       "duration": "seconds (--seconds)"})
    vgr = check_vgr(vgr)
    env = parallel_env(method=method, vgr=vgr, duration=seconds, **config)
    env.reset(seed=seed)
    w0 = 0.0 if jit is None else jit.wall
    with contextlib.nullcontext() if jit is None else jit:
        t0 = time.perf_counter()
        while not env.episode_over:
            ex = env.expert_actions()
            env.step({a: ex[a] for a in env.agents})
        wall = time.perf_counter() - t0
    if jit is not None:  # (the clock's window, the compiler's seconds excluded)
        wall = jit.wall - w0
    m = env.metrics(series=True)
    m.update({"seed": int(seed), "seconds": float(seconds), "wall_seconds": wall,
              "real_time_factor": float(seconds) / wall if wall > 0 else None})
    env.close()
    return m


def _run_job(args):
    return run_ramps(*args)


def check_backend(backend: str) -> None:
    if backend not in ("process", "ray"):
        raise ValueError(f"backend {backend!r}; allowed: 'process', 'ray'")


def run_jobs(fn, jobs: list, backend: str = "process", workers: int | None = None, progress: bool = True,
             desc: str = "runs") -> list:
    """``[fn(j) for j in jobs]`` in completion order, on a local process pool
    (``workers`` processes, default one per core; 1 runs in this process) or
    on a Ray cluster (``backend="ray"``), with a progress bar. ``fn`` must be
    a module-level function (it is pickled)."""
    check_backend(backend)
    from tqdm import tqdm

    results = []
    bar = tqdm(total=len(jobs), desc=desc, disable=not progress)
    if backend == "ray":
        try:
            import ray
        except ImportError:
            raise ValueError("--backend ray needs Ray: pip install 'icv-envs[rllib]' (or ray)") from None
        ray.init(ignore_reinit_error=True, include_dashboard=False)
        remote = ray.remote(fn)
        pending = [remote.remote(j) for j in jobs]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            results.append(ray.get(done[0]))
            bar.update(1)
    else:
        workers = workers or os.cpu_count() or 1
        if workers == 1:
            for j in jobs:
                results.append(fn(j))
                bar.update(1)
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                futs = [pool.submit(fn, j) for j in jobs]
                for f in as_completed(futs):
                    results.append(f.result())
                    bar.update(1)
    bar.close()
    return results


def _tag(method, vgr, seed) -> str:
    return f"{method}_vgr{vgr:g}_seed{seed}"


def compare_highway_ramps(methods, vgrs, seeds, seconds: float, out, backend: str = "process",
                          workers: int | None = None, progress: bool = True, config: dict | None = None) -> dict:
    validate_grid(methods, vgrs, seeds, seconds)
    check_backend(backend)
    check_workers(workers, backend)
    check_run_config(config, {"method": "methods (--methods)", "vgr": "vgrs (--vgr)",
                              "duration": "seconds (--seconds)"})
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    jobs = [(m, float(v), s, float(seconds), config) for m in methods for v in vgrs for s in _seed_list(seeds)]
    results = run_jobs(_run_job, jobs, backend, workers, progress, "highway-ramps runs")
    return write_results(results, out, methods)


def write_results(results: list[dict], out, methods=None) -> dict:
    """Write a sweep's files to ``out``: ``runs/<method>_vgr<v>_seed<s>.json``
    (one per run), ``results.csv`` (one row per run), ``summary.json`` (seed
    means with 95% intervals, returned) and the plots. Runs are ordered by
    ``methods`` (default: ``METHODS``), VGR and seed."""
    order = list(methods) if methods is not None else list(METHODS)
    results = sorted(results, key=lambda r: (order.index(r["method"]), r["vgr"], r["seed"]))
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    for r in results:
        (out / "runs" / f"{_tag(r['method'], r['vgr'], r['seed'])}.json").write_text(json.dumps(r))
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for r in results:
            w.writerow({k: r.get(k) for k in CSV_COLUMNS})
    summary = summarise(results)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    plot_results(results, out)
    return summary


def ci95(values) -> float:
    """Half-width of the 95% confidence interval of the mean (Student t;
    0 for a single value)."""
    x = np.asarray([v for v in values if v is not None], dtype=np.float64)
    if len(x) < 2:
        return 0.0
    from scipy.stats import t

    return float(t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))


def _value(r, k):
    if k == "remaining_plus_queued":
        return r["remaining"] + r["queued"]
    return r.get(k)


def summarise(results) -> dict:
    rows = {}
    for r in results:
        rows.setdefault((r["method"], r["vgr"]), []).append(r)
    table = []
    for (m, v), rs in sorted(rows.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        row = {"method": m, "vgr": v, "seeds": len(rs), "seed_list": sorted(x["seed"] for x in rs)}
        for k in SUMMARY_KEYS:
            vals = [_value(x, k) for x in rs if _value(x, k) is not None]
            row[k] = float(np.mean(vals)) if vals else None
            row[f"{k}_ci95"] = ci95(vals) if vals else None
        for k in ("min_gap", "min_time_headway", "time_headway_p05"):
            vals = [x[k] for x in rs if x.get(k) is not None]
            row[f"{k}_worst"] = float(min(vals)) if vals else None
        row["collisions"] = int(sum(x["collisions"] for x in rs))
        row["lost"] = int(sum(x["lost"] for x in rs))
        table.append(row)
    return {"runs": len(results), "table": table}


def plot_results(results, out) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    methods = sorted({r["method"] for r in results}, key=lambda m: METHODS.index(m))
    colours = {"formation": "tab:red", "lane-lp": "tab:blue", "idm": "tab:grey", "lane-lp-close": "tab:cyan",
               "idm-close": "tab:olive"}
    files = []
    for key, label in (("remaining", "vehicles remaining on the road at the end"),
                       ("remaining_plus_queued", "remaining on the road + queued at the ramps"),
                       ("mean_speed", "mean speed [m/s]"),
                       ("speed_fluctuation", "speed fluctuation: mean |dv/dt| [m/s$^2$]"),
                       ("min_time_headway", "minimum time headway [s]"),
                       ("time_headway_p05", "5th-percentile time headway [s]")):
        fig, ax = plt.subplots(figsize=(6, 4))
        for m in methods:
            vs = sorted({r["vgr"] for r in results if r["method"] == m})
            ys = [[_value(r, key) for r in results if r["method"] == m and r["vgr"] == v] for v in vs]
            ys = [[y for y in yy if y is not None] for yy in ys]
            keep = [i for i, y in enumerate(ys) if y]
            vs, ys = [vs[i] for i in keep], [ys[i] for i in keep]
            mean = np.array([np.mean(y) for y in ys])
            half = np.array([ci95(y) for y in ys])
            ax.plot(vs, mean, "o-", color=colours.get(m), label=m)
            ax.fill_between(vs, mean - half, mean + half, color=colours.get(m), alpha=0.15)
        seeds_n = len({r["seed"] for r in results})
        ax.set_xlabel("vehicle generating rate [vehicles/s per on-ramp]")
        ax.set_ylabel(label)
        ax.set_title(f"HighwayRamps: {key.replace('_', ' ')} vs VGR (mean, 95% CI, {seeds_n} seeds)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend()
        fig.tight_layout()
        path = out / f"{key}_vs_vgr.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        files.append(str(path))
    # remaining vehicles over time, one panel per method (Fig. 9)
    fig, axes = plt.subplots(1, len(methods), figsize=(4.5 * len(methods), 3.6), sharey=True, squeeze=False)
    for ax, m in zip(axes[0], methods):
        first = min(r["seed"] for r in results)
        for r in results:
            if r["method"] == m and r["seed"] == first:
                ts = r["timeseries"]
                ax.plot([p["t"] for p in ts], [p["remaining"] for p in ts], label=f"VGR {r['vgr']:g}")
        ax.set_title(m)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("vehicles on the road")
    axes[0][-1].legend(fontsize=8)
    fig.tight_layout()
    path = out / "remaining_vs_time.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    files.append(str(path))
    files += plot_heatmaps(results, out, methods)
    return files


def plot_heatmaps(results, out, methods) -> list[str]:
    """Fig. 10: per method, the density snapshot at the end of the run and
    the time average, vehicles per ``heatmap_bin`` metres per lane, at the
    VGR nearest 1/3 and the first seed, on one colour scale for all panels."""
    import matplotlib.pyplot as plt

    out = Path(out)
    first = min(r["seed"] for r in results)
    picked = {}
    for m in methods:
        rs = [r for r in results if r["method"] == m and r["seed"] == first and "heatmap_final" in r]
        if rs:
            picked[m] = min(rs, key=lambda x: (abs(x["vgr"] - 1 / 3), x["vgr"]))
    if not picked:
        return []
    vmax = max(max(np.max(r["heatmap_final"]), np.max(r["heatmap_mean"])) for r in picked.values())
    vmax = max(float(vmax), 1.0)

    def panel(ax, heat, r, title):
        heat = np.asarray(heat)
        im = ax.imshow(heat, aspect="auto", cmap="inferno", vmin=0.0, vmax=vmax, interpolation="nearest",
                       extent=[0, heat.shape[1] * r["heatmap_bin"], heat.shape[0] - 0.5, -0.5])
        ax.set_yticks(range(heat.shape[0]))
        ax.set_yticklabels([f"lane {i + 1}" for i in range(heat.shape[0])], fontsize=8)
        ax.set_title(title, fontsize=9)
        return im

    files = []
    # constrained layout keeps each panel's title clear of the tick labels above it
    fig, axes = plt.subplots(len(picked), 2, figsize=(13, 2.3 * len(picked) + 0.9), squeeze=False,
                             layout="constrained")
    for row, (m, r) in enumerate(picked.items()):
        t_end = r["timeseries"][-1]["t"] if r.get("timeseries") else r["sim_seconds"]
        im = panel(axes[row][0], r["heatmap_final"], r, f"{m}: snapshot at t = {t_end:g} s, VGR {r['vgr']:g}")
        panel(axes[row][1], r["heatmap_mean"], r, f"{m}: time average over the run, VGR {r['vgr']:g}")
    for ax in axes[-1]:
        ax.set_xlabel("position on the ring [m] (0 = first on-ramp)")
    fig.colorbar(im, ax=axes.ravel().tolist(), label=f"vehicles per {r['heatmap_bin']:g} m per lane", shrink=0.9)
    path = out / "heatmap.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    files.append(str(path))
    for m, r in picked.items():
        fig, axes = plt.subplots(2, 1, figsize=(9, 4.6), squeeze=False, layout="constrained")
        t_end = r["timeseries"][-1]["t"] if r.get("timeseries") else r["sim_seconds"]
        im = panel(axes[0][0], r["heatmap_final"], r, f"{m}: snapshot at t = {t_end:g} s, VGR {r['vgr']:g}")
        panel(axes[1][0], r["heatmap_mean"], r, f"{m}: time average")
        axes[1][0].set_xlabel("position on the ring [m] (0 = first on-ramp)")
        fig.colorbar(im, ax=[axes[0][0], axes[1][0]], label=f"vehicles per {r['heatmap_bin']:g} m (scale shared by all methods)")
        path = out / f"heatmap_{m}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        files.append(str(path))
    return files
