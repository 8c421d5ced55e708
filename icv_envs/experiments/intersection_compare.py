"""The paper's intersection comparison (Sec. 6.2, Fig. 14): methods x demands x seeds, to saturation.

``compare_intersection`` runs every (method, demand, seed) of the grid in a
local process pool (default: one worker per core) or on a Ray cluster
(``backend="ray"``), shows a progress bar and writes to ``out``:

* ``results.csv``: one row per run (columns :data:`CSV_COLUMNS`);
* ``runs/<method>_tp<demand>_seed<seed>.json``: the run's metrics;
* ``summary.json``: per method and demand the seed mean and 95% confidence
  interval (Student t over seeds) of every figure, collision and jam totals,
  and per method the capacity (below);
* plots against the demand, seed mean with its 95% CI band:
  ``mean_speed``, ``speed_fluctuation`` (the paper's Fig. 14 a and b),
  ``achieved_throughput`` (with the demand diagonal), ``mean_delay``,
  ``pet_min``, ``jammed``.

Definitions (one place each, :mod:`icv_envs.sim.intersection_metrics`):
``throughput`` is the DEMAND (vehicles/h generated at R3, all legs);
``mean_speed``, ``speed_fluctuation`` (mean |dv/dt| of the realised speed),
``speed_std``, ``stopped_share``, ``commanded_abs_accel`` over all
vehicle-substeps; ``pet_min`` / ``pet_p05`` post-encroachment time at the
conflict areas; ``jammed`` vehicles stopped > 10 s outside a queue at the
box; ``achieved_throughput`` the vehicles/h that cleared the box over the
run (the sweep runs a warm-up of ``warmup`` seconds, default 100 s: the
free-flow time from R3 to the box is 78 s, so the statistics start with the
zones filled); ``mean_delay`` the mean over vehicles that cleared the box of
their travel time from R3 minus that distance at 10 m/s; ``lost`` =
spawned - removed - left_road - remaining - crashed_removed must be 0.

Capacity (our definition, the paper gives none): the achieved throughput
follows the demand while the method serves what arrives; once the demand
exceeds what the method can serve, vehicles queue (in the zones and at the
spawn points) and the achieved throughput stops growing.  ``capacity`` of a
method is the largest swept demand whose seed-mean ``served_share`` (the
vehicles that cleared the box over the arrivals due at R3 while the
statistics ran; the Poisson arrivals of one seed can fall 15% short of the
nominal demand, so the nominal demand is not the reference) is at least
:data:`SERVED_SHARE` (95%) AND for which every smaller swept demand passes
too (runs written before ``served_share`` existed: achieved over nominal); ``saturated_at`` is the next swept demand (the
first that fails), ``None`` if none fails (capacity not reached in the
sweep); ``max_achieved`` is the largest seed-mean achieved throughput seen.
"""

from __future__ import annotations

import csv
import json
import math
import time
from pathlib import Path

import numpy as np

from icv_envs.envs.intersection import MAX_THROUGHPUT, METHODS, IntersectionEnv
from icv_envs._args import check_float, check_int
from icv_envs.experiments._checks import check_run_config, check_throughput, check_workers
from icv_envs.experiments.compare import check_backend, run_jobs
from icv_envs.experiments.seeds import parse_seeds

__all__ = ["CSV_COLUMNS", "METHODS", "DEFAULT_DEMANDS", "SERVED_SHARE", "validate_grid", "run_intersection",
           "compare_intersection", "collect_runs", "summarise", "capacity", "mean_ci", "plot_results"]

CSV_COLUMNS = [
    "method", "throughput", "seed", "seconds", "warmup", "lane_use", "collisions", "warmup_collisions", "jammed",
    "warmup_jammed",
    "jammed_vehicle_seconds", "lost", "achieved_throughput", "mean_speed", "speed_fluctuation", "speed_std",
    "stopped_share", "commanded_abs_accel", "mean_delay", "pet_min", "pet_p05", "pet_samples", "realised_demand",
    "served_share", "spawned",
    "cleared", "remaining", "queued", "not_spawned", "envelope_box_binding", "virtual_cap_binding",
    "wall_seconds", "real_time_factor",
]
#: default demand sweep [veh/h]: 500 to 5000 in steps of 500
DEFAULT_DEMANDS = [float(v) for v in range(500, 5001, 500)]
#: share of the demand the achieved throughput must reach for the demand to count as served
SERVED_SHARE = 0.95
_FIGURES = ("achieved_throughput", "mean_speed", "speed_fluctuation", "speed_std", "stopped_share",
            "commanded_abs_accel", "mean_delay", "pet_p05", "remaining", "queued", "realised_demand", "served_share")
_R1 = float(IntersectionEnv.default_config()["R1"])  # the sweeps run the default zones
_COLOURS = {"multi-vp": "tab:red", "single-vp": "tab:blue", "fcfs": "tab:grey", "fcfs-tight": "tab:green"}


def validate_grid(methods, throughputs, seeds, seconds) -> None:
    """Raise ValueError naming the bad value: ``methods`` and ``throughputs``
    lists (a bare string or number is not a list) of distinct values, unknown
    method, throughput <= 0, seeds < 1, seconds <= 0."""
    for name, vals, eg in (("methods", methods, "['multi-vp']"), ("throughputs", throughputs, "[1500.0]")):
        if not isinstance(vals, (list, tuple)):
            raise ValueError(f"{name} = {vals!r}; allowed: a list, e.g. {eg}")
        if len(set(vals)) != len(vals):
            raise ValueError(f"{name} = {vals!r} repeat a value; allowed: distinct values")
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
    parse_seeds(seeds)
    check_float("seconds", seconds, 0)


#: config keys an intersection run's own arguments set (a config may not set them too)
OWNED_CONFIG = {"method": "method (--method)", "throughput": "throughput (--throughput)",
                "duration": "seconds (--seconds)"}


def run_intersection(method: str, throughput: float, seed: int, seconds: float, config: dict | None = None) -> dict:
    """One run of the intersection driven by the method's expert; returns its metrics (``config`` may set
    ``warmup``: seconds run before the clock and the statistics start)."""
    from icv_envs.envs.intersection_v0 import parallel_env

    seed = check_int("seed", seed, 0)
    seconds = check_float("seconds", seconds, 0)
    cfg = {"expert_in_info": False}
    cfg.update(check_run_config(config, OWNED_CONFIG))
    throughput = check_throughput(throughput)
    cfg.update({"method": method, "throughput": throughput, "duration": seconds})
    env = parallel_env(**cfg)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    wall = time.perf_counter() - t0
    m = env.metrics()
    m.update({"seed": int(seed), "seconds": float(seconds), "warmup": float(cfg.get("warmup", 0.0)),
              "wall_seconds": wall,
              "real_time_factor": float(seconds) / wall if wall > 0 else None,
              "collision_log": [list(c) for c in env.core.world.collision_log[:50]],
              "jam_log": [list(j) for j in env.core.world.jams.log[:50]]})
    env.close()
    return m


def _run_job(args):
    return run_intersection(*args)


def _tag(method, throughput, seed) -> str:
    return f"{method}_tp{throughput:g}_seed{seed}"


def compare_intersection(methods, throughputs, seeds, seconds: float, out, backend: str = "process",
                         workers: int | None = None, progress: bool = True, config: dict | None = None) -> dict:
    """Run the grid (see the module docstring) and write CSV, JSON and plots to ``out``.

    ``seeds``: a count N (seeds 0..N-1) or a seed list / range string
    (:func:`icv_envs.experiments.seeds.parse_seeds`)."""
    validate_grid(methods, throughputs, seeds, seconds)
    check_backend(backend)
    check_workers(workers, backend)
    check_run_config(config, OWNED_CONFIG)
    seeds = parse_seeds(seeds)
    if config:
        # fail fast on a bad config, before starting workers
        from icv_envs.envs.intersection import IntersectionEnv

        IntersectionEnv(dict(config, duration=1.0))
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    jobs = [(m, float(v), s, float(seconds), config) for m in methods for v in throughputs for s in seeds]
    results = run_jobs(_run_job, jobs, backend, workers, progress, "intersection runs")
    order = list(methods)
    results.sort(key=lambda r: (order.index(r["method"]), r["throughput"], r["seed"]))
    for r in results:
        (out / "runs" / f"{_tag(r['method'], r['throughput'], r['seed'])}.json").write_text(json.dumps(r))
    return _write_outputs(results, out)


def _write_outputs(results: list, out: Path) -> dict:
    """``results.csv``, the summary (``summary.json``) and the plots of a sweep in ``out``."""
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_COLUMNS)
        w.writeheader()
        for r in results:
            w.writerow({k: r.get(k) for k in CSV_COLUMNS})
    summary = summarise(results)
    summary["plots"] = plot_results(results, out)
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def collect_runs(parts, out) -> dict:
    """Merge the ``runs/*.json`` of earlier sweeps (directories ``parts``, for
    example one per demand) into one ``results.csv``, ``summary.json`` and
    plot set in ``out``: a sweep that is run piecewise ends up as one."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    for d in parts:
        files = sorted(Path(d, "runs").glob("*.json"))
        if not files:
            raise ValueError(f"no runs/*.json in {d!r}")
        results += [json.loads(fp.read_text()) for fp in files]
    results.sort(key=lambda r: (METHODS.index(r["method"]), r["throughput"], r["seed"]))
    return _write_outputs(results, out)


def mean_ci(values) -> tuple[float | None, float | None]:
    """Seed mean and the half width of its 95% confidence interval (Student t,
    ``n - 1`` degrees of freedom; ``None`` half width for one value)."""
    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=np.float64)
    if not len(x):
        return None, None
    if len(x) == 1:
        return float(x[0]), None
    from scipy.stats import t

    return float(x.mean()), float(t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))


def capacity(rows) -> dict:
    """Capacity of one method from its table rows (module docstring): ``{"capacity",
    "saturated_at", "max_achieved"}``."""
    rows = sorted(rows, key=lambda r: r["throughput"])
    cap, sat = None, None
    for r in rows:
        share = r.get("served_share")
        if share is None and r["achieved_throughput"] is not None:  # runs written before served_share existed
            share = r["achieved_throughput"] / r["throughput"]
        if share is not None and share >= SERVED_SHARE:
            cap = r["throughput"]
        else:
            sat = r["throughput"]
            break
    ach = [r["achieved_throughput"] for r in rows if r["achieved_throughput"] is not None]
    return {"capacity": cap, "saturated_at": sat, "max_achieved": max(ach) if ach else None}


def _all_collisions(r) -> int:
    return int(r["collisions"]) + int(r.get("warmup_collisions", 0))


def _all_jammed(r) -> int:
    return int(r.get("jammed", 0)) + int(r.get("warmup_jammed", 0))


def _jammed_at_R1_entry(r, R1: float) -> int:
    """Logged jammed vehicles that stood at the entry of the coordinating zone
    (within 30 m inside ``R1`` or queued outside it) when first counted: waiting
    for a slot in the coordination (only a run's first 50 are logged)."""
    return sum(1 for j in r.get("jam_log", []) if len(j) > 2 and j[2] is not None and j[2] >= R1 - 30.0)


def summarise(results) -> dict:
    rows = {}
    for r in results:
        rows.setdefault((r["method"], r["throughput"]), []).append(r)
    table = []
    for (m, v), rs in sorted(rows.items(), key=lambda kv: (kv[0][1], METHODS.index(kv[0][0]))):
        row = {"method": m, "throughput": v, "seeds": len(rs), "seed_list": sorted(x["seed"] for x in rs)}
        for k in _FIGURES:
            row[k], row[k + "_ci95"] = mean_ci([x.get(k) for x in rs])
        pm = [x["pet_min"] for x in rs if x.get("pet_min") is not None]
        row["pet_min"] = float(min(pm)) if pm else None  # the minimum over all runs
        row["pet_min_mean"], row["pet_min_ci95"] = mean_ci(pm)
        row.update({
            # collisions and jams of the warm-up count too (they are not in the run's statistics)
            "collisions": int(sum(_all_collisions(x) for x in rs)),
            "jammed": int(sum(_all_jammed(x) for x in rs)),
            "runs_with_jams": int(sum(1 for x in rs if _all_jammed(x))),
            "jammed_at_R1_entry": int(sum(_jammed_at_R1_entry(x, _R1) for x in rs)),
            "lost": int(sum(x["lost"] for x in rs)),
            "envelope_box_binding": int(sum(x.get("envelope_box_binding", 0) for x in rs)),
        })
        table.append(row)
    caps = {m: capacity([r for r in table if r["method"] == m]) for m in dict.fromkeys(r["method"] for r in table)}
    return {"runs": len(results), "table": table, "capacity": caps, "served_share": SERVED_SHARE,
            "collisions": int(sum(_all_collisions(r) for r in results)),
            "jammed": int(sum(_all_jammed(r) for r in results)),
            "lost": int(sum(r["lost"] for r in results))}


_PLOTS = (("mean_speed", "average speed [m/s]"),
          ("speed_fluctuation", "speed fluctuation: mean |dv/dt| realised [m/s$^2$]"),
          ("achieved_throughput", "achieved throughput [veh/h]"),
          ("mean_delay", "mean delay [s]"),
          ("pet_min", "minimum PET over the runs [s]"),
          ("jammed", "jammed vehicles per run"))


def _seed_label(results, key: str) -> str:
    """How many seeds each point of a plot averages: one number when every (method, demand) cell has the
    same, else the range (a grid completed on some cells only must not look uniform)."""
    cells: dict = {}
    for r in results:
        cells.setdefault((r["method"], r["throughput"]), set()).add(r["seed"])
    counts = sorted({len(v) for v in cells.values()}) or [0]
    lo, hi = counts[0], counts[-1]
    text = f"{hi} seed{'s' if hi != 1 else ''} per point" if lo == hi else f"{lo}-{hi} seeds per point"
    if hi > 1 and key != "pet_min":
        text += ", band: 95% CI over seeds"
    return text


def plot_results(results, out) -> list[str]:
    """One PNG per figure of :data:`_PLOTS`: seed mean per method, 95% CI band (clipped at 0)
    (for ``pet_min`` the minimum over the seeds, no band)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    methods = sorted({r["method"] for r in results}, key=lambda m: METHODS.index(m))
    files = []
    for key, label in _PLOTS:
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        for m in methods:
            vs, ys, lo, hi = [], [], [], []
            for v in sorted({r["throughput"] for r in results if r["method"] == m}):
                vals = [r.get(key) for r in results if r["method"] == m and r["throughput"] == v]
                vals = [x for x in vals if x is not None]
                if not vals:
                    continue
                if key == "pet_min":
                    mu, h = float(min(vals)), None
                else:
                    mu, h = mean_ci(vals)
                vs.append(v)
                ys.append(mu)
                lo.append(max(0.0, mu - (h or 0.0)))  # every banded figure is non-negative
                hi.append(mu + (h or 0.0))
            if not vs:
                continue
            ax.plot(vs, ys, "o-", color=_COLOURS.get(m), label=m, ms=4)
            ax.fill_between(vs, lo, hi, color=_COLOURS.get(m), alpha=0.15)
        if key == "achieved_throughput":
            lim = max(r["throughput"] for r in results)
            ax.plot([0, lim], [0, lim], ":", color="k", lw=0.8, label="demand")
        ax.set_xlabel("demand [vehicles/h entering the intersection, all legs]")
        ax.set_ylabel(label)
        ax.set_title(f"Intersection: {key.replace('_', ' ')} ({_seed_label(results, key)})", fontsize=10)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
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
    if len(set(vals)) != len(vals):
        raise ValueError(f"--throughput {text!r} repeats a demand; allowed: distinct demands")
    for v in vals:
        if not math.isfinite(v) or not 0 < v <= MAX_THROUGHPUT:
            raise ValueError(f"throughput {v!r} is invalid; allowed: 0 < throughput <= {MAX_THROUGHPUT:g} vehicles/h")
    return vals


def run_cli(args, echo=print) -> dict:
    """``icv-envs compare intersection``: ``args`` has ``methods`` (list or comma
    string; default multi-vp, single-vp, fcfs), ``throughput`` (list or comma
    string; default :data:`DEFAULT_DEMANDS`), ``seeds`` (count, list or range
    string), ``seconds``, ``out``, ``backend``, ``workers`` and optionally
    ``lane_use`` and ``warmup`` (default 100 s).  Prints one line per (method,
    demand) and one per method with its capacity, and returns the summary
    (the CLI prints it as the last JSON line)."""
    methods = getattr(args, "methods", None)
    methods = ["multi-vp", "single-vp", "fcfs"] if methods is None else methods  # (a given empty list is an error)
    if isinstance(methods, str):
        methods = [m.strip() for m in methods.split(",") if m.strip()]
    tps = getattr(args, "throughput", None)
    tps = list(DEFAULT_DEMANDS) if tps is None else tps
    if isinstance(tps, str):
        tps = parse_throughputs(tps)
    config = {"warmup": float(getattr(args, "warmup", None) if getattr(args, "warmup", None) is not None else 100.0)}
    if getattr(args, "lane_use", None):
        config["lane_use"] = args.lane_use
    summary = compare_intersection(methods, tps, args.seeds, float(args.seconds), args.out,
                                   backend=getattr(args, "backend", "process"),
                                   workers=getattr(args, "workers", None), progress=getattr(args, "progress", True),
                                   config=config or None)

    def f(x, fmt):
        return "n/a" if x is None else format(x, fmt)

    for row in summary["table"]:
        echo(f"{row['method']:10s} demand={row['throughput']:<6g} achieved={f(row['achieved_throughput'], '7.1f')} "
             f"mean_speed={f(row['mean_speed'], '6.2f')} speed_fluctuation={f(row['speed_fluctuation'], '.3f')} "
             f"mean_delay={f(row['mean_delay'], '6.2f')} pet_min={f(row['pet_min'], '.2f')} "
             f"collisions={row['collisions']} jammed={row['jammed']} lost={row['lost']}")
    for m, c in summary["capacity"].items():
        echo(f"{m:10s} capacity={c['capacity']} saturated_at={c['saturated_at']} max_achieved={f(c['max_achieved'], '.0f')}")
    summary["out"] = str(args.out)
    return summary


if __name__ == "__main__":  # pragma: no cover
    import argparse
    import sys

    p = argparse.ArgumentParser(description="intersection sweep (see the module docstring)")
    p.add_argument("--methods", default="multi-vp,single-vp,fcfs")
    p.add_argument("--throughput", default=",".join(f"{v:g}" for v in DEFAULT_DEMANDS))
    p.add_argument("--seeds", default="3")
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--warmup", type=float, default=100.0)
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
