"""Seed sweep of the intersection experts: zero collisions and zero jams.

Runs every (method, demand, seed) of the grid (default: multi-vp, single-vp
and fcfs; 2000, 2500 and 3000 veh/h; seeds 0-19; 600 s), in a process pool
with a progress bar, writes ``results.csv`` and ``summary.json`` to ``--out``
and prints one line per (method, demand): runs, collisions, jammed vehicles,
runs with a jam, mean delay and minimum PET.  Exit status 1 if any run had
a collision or a jammed vehicle (definitions:
:mod:`icv_envs.sim.intersection_metrics`).

    nice -n 10 python benchmarks/intersection_seeds.py --seeds 0-19 --seconds 600 --out results/intersection/seed_sweep
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv=None) -> int:
    from icv_envs.experiments.intersection_compare import compare_intersection, parse_throughputs

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--methods", default="multi-vp,single-vp,fcfs")
    p.add_argument("--throughput", default="2000,2500,3000")
    p.add_argument("--seeds", default="0-19", help="a count N or a list/range such as 0-19 or 5,7,10-12")
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--lane-use", dest="lane_use", default=None)
    p.add_argument("--workers", type=int, default=None)
    p.add_argument("--out", default="intersection_seed_sweep")
    a = p.parse_args(argv)
    methods = [m.strip() for m in a.methods.split(",") if m.strip()]
    config = {"lane_use": a.lane_use} if a.lane_use else None
    s = compare_intersection(methods, parse_throughputs(a.throughput), a.seeds, a.seconds, a.out,
                             workers=a.workers, progress=True, config=config)
    bad = 0
    print(f"{'method':10s} {'demand':>6s} {'runs':>4s} {'collisions':>10s} {'jammed':>6s} {'jam runs':>8s} "
          f"{'delay [s]':>9s} {'PET min [s]':>11s}")
    for r in s["table"]:
        bad += r["collisions"] + r["jammed"]
        d = "n/a" if r["mean_delay"] is None else f"{r['mean_delay']:.2f}"
        pm = "n/a" if r["pet_min"] is None else f"{r['pet_min']:.2f}"
        print(f"{r['method']:10s} {r['throughput']:6g} {r['seeds']:4d} {r['collisions']:10d} {r['jammed']:6d} "
              f"{r['runs_with_jams']:8d} {d:>9s} {pm:>11s}")
    Path(a.out, "table.json").write_text(json.dumps(s["table"], indent=1))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
