"""The highway methods' car-following margins side by side (issue 8, equal safety).

Reads the ``results.csv`` of ``icv-envs compare highway-ramps`` output
directories (one row per run) and plots, per method, the seed mean and 95%
t-interval of the 5th-percentile and of the minimum time headway against
the VGR, in one figure; writes ``margins.png`` and ``margins.csv`` to
``--out``.

    python scripts/highway_margins_plot.py results/highway_ramps results/highway_ramps_close --out results/highway_ramps_close
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path

import numpy as np

from icv_envs.experiments.intersection_compare import mean_ci

KEYS = (("time_headway_p05", "5th-percentile time headway [s]"), ("min_time_headway", "minimum time headway [s]"))
COLOURS = {"formation": "tab:red", "lane-lp": "tab:blue", "idm": "tab:grey", "lane-lp-close": "tab:cyan",
           "idm-close": "tab:olive"}


def main(argv=None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    vals = defaultdict(list)  # (method, vgr, key) -> values over seeds
    for d in a.dirs:
        with open(Path(d, "results.csv"), newline="") as fh:
            for row in csv.DictReader(fh):
                for k, _ in KEYS:
                    if row.get(k) not in (None, ""):
                        vals[(row["method"], float(row["vgr"]), k)].append(float(row[k]))
    methods = list(dict.fromkeys(m for m, _, _ in vals))
    out = Path(a.out)
    rows = []
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, (k, label) in zip(axes, KEYS):
        for m in methods:
            vg = sorted({v for mm, v, kk in vals if mm == m and kk == k})
            stats = [mean_ci(vals[(m, v, k)]) for v in vg]
            mean = np.array([s[0] for s in stats])
            half = np.array([s[1] or 0.0 for s in stats])
            ax.errorbar(vg, mean, yerr=half, fmt="o-", capsize=3, color=COLOURS.get(m), label=m)
            rows += [{"method": m, "vgr": v, "metric": k, "mean": s[0], "ci95": s[1], "seeds": len(vals[(m, v, k)])}
                     for v, s in zip(vg, stats)]
        ax.set_xlabel("vehicle generating rate [vehicles/s per on-ramp]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("HighwayRamps: car-following margins per method (seed mean, 95% t-interval)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out / "margins.png", dpi=120)
    with open(out / "margins.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    for r in rows:
        print(f"{r['method']:14s} vgr={r['vgr']:<6g} {r['metric']:17s} {r['mean']:.3f} +- {r['ci95'] or 0:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
