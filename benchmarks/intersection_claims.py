"""The paper's four intersection claims (Sec. 6.2, Fig. 14), tested on a sweep.

Reads the ``runs/*.json`` of one or more sweep directories (written by
``icv-envs compare intersection`` or ``benchmarks/intersection_seeds.py``)
and prints, per claim, our figure with its 95% interval and whether the
claim is reproduced; writes ``claims.json`` and ``claims.md`` to ``--out``.

Every comparison between two methods is *paired by seed*: a seed draws the
same arrivals (times, legs, movements, lanes) for every method, so the
per-seed difference removes the traffic's variance.  The interval is the
Student t 95% interval of the mean paired difference over the seeds both
methods ran; a claim "A > B" is *reproduced* when the interval lies above
0, *contradicted* when it lies below 0, *not resolved* otherwise.  The
thresholds of the claims are ours where the paper gives words only:
"near 10 m/s" = seed mean within 0.5 m/s of the 10 m/s free speed.

    python benchmarks/intersection_claims.py results/intersection/saturation --out results/intersection/saturation
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from icv_envs.experiments.intersection_compare import mean_ci as ci

VP = ("multi-vp", "single-vp")
NEAR = 0.5  # m/s: "near 10 m/s"
V_FREE = 10.0


def load(dirs) -> list[dict]:
    runs = []
    for d in dirs:
        files = sorted(Path(d, "runs").glob("*.json"))
        if not files:
            raise SystemExit(f"no runs/*.json in {d!r}")
        runs += [json.loads(f.read_text()) for f in files]
    seen = {}
    for r in runs:
        key = (r["method"], float(r["throughput"]), int(r["seed"]))
        if key in seen:
            raise SystemExit(f"run {key} appears twice in {list(map(str, dirs))}")
        seen[key] = r
    return list(seen.values())


def by(runs, method, demand, key) -> dict[int, float]:
    return {int(r["seed"]): float(r[key]) for r in runs
            if r["method"] == method and float(r["throughput"]) == demand and r.get(key) is not None}


def paired(runs, a, b, demand, key) -> dict | None:
    xa, xb = by(runs, a, demand, key), by(runs, b, demand, key)
    seeds = sorted(set(xa) & set(xb))
    if not seeds:
        return None
    d = [xa[s] - xb[s] for s in seeds]
    m, h = ci(d)
    verdict = "not resolved"
    if h is not None and m - h > 0:
        verdict = "yes"
    elif h is not None and m + h < 0:
        verdict = "no (reversed)"
    return {"a": a, "b": b, "demand": demand, "key": key, "seeds": len(seeds), "diff": m, "ci95": h,
            "verdict": verdict}


def fmt(m, h, nd=2) -> str:
    return f"{m:.{nd}f}" if h is None else f"{m:.{nd}f} +- {h:.{nd}f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="sweep directories with runs/*.json")
    ap.add_argument("--out", default=None, help="write claims.json and claims.md here (default: the first dir)")
    ap.add_argument("--split", type=float, default=2000.0, help="the paper's demand split, veh/h (default 2000)")
    ap.add_argument("--reservation", default="fcfs", help="the reservation method to compare (default fcfs)")
    a = ap.parse_args(argv)
    runs = load(a.dirs)
    demands = sorted({float(r["throughput"]) for r in runs})
    low = [v for v in demands if v <= a.split]
    high = [v for v in demands if v > a.split]
    res = a.reservation
    out = {"runs": len(runs), "demands": demands, "claims": []}
    lines = ["| claim | demand [veh/h] | ours (seed mean +- 95% CI; differences paired by seed) | seeds | reproduced? |",
             "|---|---:|---|---:|---|"]

    # 1. both VP variants near 10 m/s below the split
    for v in low:
        for m in VP:
            s = list(by(runs, m, v, "mean_speed").values())
            if not s:
                continue
            mm, h = ci(s)
            ok = abs(mm - V_FREE) <= NEAR
            out["claims"].append({"claim": 1, "method": m, "demand": v, "mean_speed": mm, "ci95": h, "ok": ok})
            lines.append(f"| 1. {m} near 10 m/s | {v:g} | {fmt(mm, h)} m/s | {len(s)} | {'yes' if ok else 'no'} |")
    def add(claim, label, a_, b_, v, key, unit, nd):
        p = paired(runs, a_, b_, v, key)
        if p is not None:
            out["claims"].append({"claim": claim, **p})
            lines.append(f"| {claim}. {label} | {v:g} | {fmt(p['diff'], p['ci95'], nd)} {unit} | {p['seeds']} | "
                         f"{p['verdict']} |")

    # 2. above the split: multi-vp > single-vp > reservation in mean speed
    for v in high:
        for x, y in (("multi-vp", "single-vp"), ("single-vp", res)):
            add(2, f"speed {x} > {y}", x, y, v, "mean_speed", "m/s", 2)
    # 3. reservation has the lowest speed fluctuation
    for v in demands:
        for m in VP:
            add(3, f"fluctuation {m} > {res}", m, res, v, "speed_fluctuation", "m/s^2", 3)
    # 4. multi-vp smoother than single-vp
    for v in demands:
        add(4, "fluctuation single-vp > multi-vp", "single-vp", "multi-vp", v, "speed_fluctuation", "m/s^2", 3)
    md = "\n".join(lines)
    print(md)
    dest = Path(a.out or a.dirs[0])
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "claims.json").write_text(json.dumps(out, indent=1))
    (dest / "claims.md").write_text(md + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
