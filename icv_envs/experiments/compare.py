"""The paper's highway comparison (Sec. 6.1, Figs. 9-11): methods x VGRs x
seeds on the 10 km ring, in parallel, with a CSV and plots.

``compare_highway_ramps`` runs every (method, vgr, seed) of the grid in a
local process pool (default: one worker per core) or on a Ray cluster
(``backend="ray"``), shows a progress bar, and writes to ``out``:

* ``results.csv``: one row per run (``method, vgr, seed, collisions, lost,
  remaining, mean_speed, speed_fluctuation, ...``);
* ``runs/<method>_vgr<vgr>_seed<seed>.json``: the run's totals, its 1 Hz time
  series and its density heat maps;
* ``remaining_vs_vgr.png``, ``mean_speed_vs_vgr.png``,
  ``speed_fluctuation_vs_vgr.png`` (mean and min-max over seeds per method),
  ``remaining_vs_time.png`` (Fig. 9 style) and ``heatmap_<method>.png``
  (vehicles per 500 m per lane, time-averaged, at the VGR nearest 1/3,
  seed 0; Fig. 10 style);
* ``summary.json``: per method and VGR, the seed means.
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from icv_envs.envs.highway_ramps import MAX_VGR, METHODS

__all__ = ["run_ramps", "compare_highway_ramps", "run_jobs", "CSV_COLUMNS", "validate_grid"]

CSV_COLUMNS = [
    "method", "vgr", "seed", "seconds", "collisions", "lost", "remaining", "mean_speed", "speed_fluctuation",
    "spawned", "exited", "missed_exits", "queued", "not_spawned", "min_gap", "wall_seconds", "real_time_factor",
]


def validate_grid(methods, vgrs, seeds, seconds) -> None:
    methods = list(methods)
    if not methods:
        raise ValueError("no methods given; allowed: " + ", ".join(METHODS))
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"unknown methods {bad}; allowed: {list(METHODS)}")
    if not list(vgrs):
        raise ValueError("no VGR given")
    for v in vgrs:
        if not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v <= MAX_VGR:
            raise ValueError(f"vgr {v!r} is invalid; allowed: 0 < vgr <= {MAX_VGR} vehicles/s per ramp")
    if not isinstance(seeds, int) or seeds < 1:
        raise ValueError(f"seeds = {seeds!r}; allowed: an integer >= 1 (runs use seeds 0..seeds-1)")
    if not isinstance(seconds, (int, float)) or not math.isfinite(seconds) or seconds <= 0:
        raise ValueError(f"seconds = {seconds!r}; allowed: a number > 0")


def run_ramps(method: str, vgr: float, seed: int, seconds: float, config: dict | None = None) -> dict:
    """One run of HighwayRamps driven by the method's controller; returns
    the totals plus ``timeseries`` and heat maps."""
    from icv_envs.envs.highway_ramps_v0 import parallel_env

    env = parallel_env(method=method, vgr=float(vgr), duration=float(seconds), **(config or {}))
    env.reset(seed=int(seed))
    t0 = time.perf_counter()
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    wall = time.perf_counter() - t0
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


def compare_highway_ramps(methods, vgrs, seeds: int, seconds: float, out, backend: str = "process",
                          workers: int | None = None, progress: bool = True, config: dict | None = None) -> dict:
    validate_grid(methods, vgrs, seeds, seconds)
    check_backend(backend)
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    jobs = [(m, float(v), s, float(seconds), config) for m in methods for v in vgrs for s in range(seeds)]
    results = run_jobs(_run_job, jobs, backend, workers, progress, "highway-ramps runs")
    results.sort(key=lambda r: (list(methods).index(r["method"]), r["vgr"], r["seed"]))
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


def summarise(results) -> dict:
    rows = {}
    for r in results:
        rows.setdefault((r["method"], r["vgr"]), []).append(r)
    table = []
    for (m, v), rs in sorted(rows.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        table.append({
            "method": m, "vgr": v, "seeds": len(rs),
            **{k: float(np.mean([x[k] for x in rs])) for k in ("remaining", "mean_speed", "speed_fluctuation",
                                                                   "exited", "missed_exits", "queued")},
            "collisions": int(sum(x["collisions"] for x in rs)),
            "lost": int(sum(x["lost"] for x in rs)),
        })
    return {"runs": len(results), "table": table}


def plot_results(results, out) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    methods = sorted({r["method"] for r in results}, key=lambda m: METHODS.index(m))
    colours = {"formation": "tab:red", "lane-lp": "tab:blue", "idm": "tab:grey"}
    files = []
    for key, label in (("remaining", "vehicles remaining on the road at the end"),
                       ("mean_speed", "mean speed [m/s]"),
                       ("speed_fluctuation", "speed fluctuation: mean |a| [m/s$^2$]")):
        fig, ax = plt.subplots(figsize=(6, 4))
        for m in methods:
            vs = sorted({r["vgr"] for r in results if r["method"] == m})
            ys = [[r[key] for r in results if r["method"] == m and r["vgr"] == v] for v in vs]
            mean = [np.mean(y) for y in ys]
            ax.plot(vs, mean, "o-", color=colours.get(m), label=m)
            ax.fill_between(vs, [min(y) for y in ys], [max(y) for y in ys], color=colours.get(m), alpha=0.15)
        ax.set_xlabel("vehicle generating rate [vehicles/s per on-ramp]")
        ax.set_ylabel(label)
        ax.set_title(f"HighwayRamps: {key.replace('_', ' ')} vs VGR")
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
        for r in results:
            if r["method"] == m and r["seed"] == 0:
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
    # density heat maps (Fig. 10), VGR nearest 1/3, seed 0
    for m in methods:
        rs = [r for r in results if r["method"] == m and r["seed"] == 0]
        if not rs:
            continue
        r = min(rs, key=lambda x: abs(x["vgr"] - 1 / 3))
        heat = np.asarray(r["heatmap_mean"])
        fig, ax = plt.subplots(figsize=(8, 2.4))
        im = ax.imshow(heat, aspect="auto", cmap="inferno", extent=[0, heat.shape[1] * r["heatmap_bin"], heat.shape[0] - 0.5, -0.5])
        ax.set_yticks(range(heat.shape[0]))
        ax.set_yticklabels([f"lane {i + 1}" for i in range(heat.shape[0])])
        ax.set_xlabel("position on the ring [m] (0 = first on-ramp)")
        ax.set_title(f"{m}: mean vehicles per {r['heatmap_bin']:g} m, VGR {r['vgr']:g}")
        fig.colorbar(im, ax=ax)
        fig.tight_layout()
        path = out / f"heatmap_{m}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        files.append(str(path))
    return files
