"""Long ring runs: HighwayRamps for 3600 s with each method (issue 11, item 1).

Runs ``formation``, ``lane-lp`` and ``idm`` on the 10 km ring at one VGR and
seed (one process per method) and writes ``ring_3600.json``, ``ring_3600.csv``
(one row per method: exits, missed exits, remaining, stopped at the end,
jammed, collisions, mean speed) and ``ring_3600.png`` (vehicles on the road,
standing vehicles and exits over time).

    nice -n 10 python benchmarks/ring_3600.py --seconds 3600 --vgr 0.33 --seed 0 --out bench_out/ring

``jammed`` counts vehicles that stood still > 30 s with >= 32 m of free lane
ahead (a deadlock of the driving logic, not congestion).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

METHODS = ("formation", "lane-lp", "idm")
KEYS = ("method", "vgr", "seed", "seconds", "spawned", "exited", "missed_exits", "remaining", "queued",
        "stopped_end", "jammed", "collisions", "mean_speed", "lost", "wall_seconds")


def one(job):
    method, vgr, seed, seconds = job
    from icv_envs.experiments.compare import run_ramps

    m = run_ramps(method, vgr, seed, seconds)
    ts = m["timeseries"]
    m["stopped_end"] = ts[-1]["stopped"] if ts else 0
    return m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--vgr", type=float, default=0.33)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--workers", type=int, default=min(3, os.cpu_count() or 1))
    ap.add_argument("--out", default="bench_out/ring_3600")
    a = ap.parse_args(argv)
    methods = [m for m in a.methods.split(",") if m]
    bad = [m for m in methods if m not in METHODS]
    if bad:
        ap.error(f"unknown methods {bad}; allowed: {list(METHODS)}")
    from tqdm import tqdm

    jobs = [(m, a.vgr, a.seed, a.seconds) for m in methods]
    results = []
    with ProcessPoolExecutor(max_workers=a.workers) as pool:
        for m in tqdm(pool.map(one, jobs), total=len(jobs), desc="ring runs"):
            results.append(m)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "ring_3600.json").write_text(json.dumps(results))
    with open(out / "ring_3600.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=KEYS, extrasaction="ignore")
        w.writeheader()
        for m in results:
            w.writerow(m)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    for m in results:
        ts = m["timeseries"]
        t = [r["t"] for r in ts]
        axes[0].plot(t, [r["remaining"] for r in ts], label=m["method"])
        axes[1].plot(t, [r["stopped"] for r in ts], label=m["method"])
        axes[2].plot(t, [r["exited"] for r in ts], label=m["method"])
    for ax, title in zip(axes, ("vehicles on the ring", "standing (< 0.1 m/s)", "exited (cumulative)")):
        ax.set_title(title)
        ax.set_xlabel("t [s]")
        ax.legend()
    fig.suptitle(f"HighwayRamps ring, VGR {a.vgr} veh/s per ramp, seed {a.seed}")
    fig.tight_layout()
    fig.savefig(out / "ring_3600.png", dpi=100)
    for m in results:
        print(" ".join(f"{k}={m.get(k)}" for k in KEYS), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
