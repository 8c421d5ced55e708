"""The paper's three highway claims from a ``compare highway-ramps`` results.csv.

For each VGR: the formation method relative to the LP reference, as the mean
over seeds of the paired relative difference ``(F_s - LP_s) / LP_s`` (both
methods see the same arrivals for a seed) and its 95% confidence interval
(Student t over seeds). Usage::

    python scripts/benchmarks/highway_claims.py results/highway_ramps/results.csv
"""

from __future__ import annotations

import csv
import math
import sys

import numpy as np
from scipy.stats import t as student_t

CLAIMS = (
    ("remaining", "vehicles remaining on the road", "about -30%"),
    ("remaining_plus_queued", "remaining + queued at the ramps", "(not in the paper)"),
    ("mean_speed", "mean speed", "about +30%"),
    ("speed_fluctuation", "speed fluctuation (realised mean abs dv/dt)", "about -60%"),
    ("commanded_abs_accel", "commanded mean abs a (old figure, diagnostic)", "(diagnostic)"),
)


def load(path):
    rows = list(csv.DictReader(open(path)))
    for r in rows:
        for k in r:
            if k not in ("method",):
                try:
                    r[k] = float(r[k])
                except (TypeError, ValueError):
                    pass
        r["remaining_plus_queued"] = r["remaining"] + r["queued"]
    return rows


def rel_ci(f, lp):
    d = (np.asarray(f) - np.asarray(lp)) / np.asarray(lp)
    m = float(d.mean())
    h = float(student_t.ppf(0.975, len(d) - 1) * d.std(ddof=1) / math.sqrt(len(d))) if len(d) > 1 else float("nan")
    return m, h


def main(path):
    rows = load(path)
    vgrs = sorted({r["vgr"] for r in rows})
    print("| quantity | paper | VGR | formation | lane-lp | formation vs lane-lp (mean, 95% CI) | seeds |")
    print("|---|---|---:|---:|---:|---:|---|")
    for key, label, paper in CLAIMS:
        for v in vgrs:
            f = {int(r["seed"]): r[key] for r in rows if r["method"] == "formation" and r["vgr"] == v}
            lp = {int(r["seed"]): r[key] for r in rows if r["method"] == "lane-lp" and r["vgr"] == v}
            seeds = sorted(set(f) & set(lp))
            if not seeds:
                continue
            m, h = rel_ci([f[s] for s in seeds], [lp[s] for s in seeds])
            print(f"| {label} | {paper} | {v:g} | {np.mean([f[s] for s in seeds]):.3g} | "
                  f"{np.mean([lp[s] for s in seeds]):.3g} | {100 * m:+.0f}% (+-{100 * h:.0f}%) | "
                  f"{','.join(map(str, seeds))} |")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/highway_ramps/results.csv")
