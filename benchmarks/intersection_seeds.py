"""Seed sweep of the intersection experts: zero collisions and zero jams.

Runs every (method, demand, seed) of the grid (default: multi-vp, single-vp
and fcfs; 2000, 2500 and 3000 veh/h; seeds 0-19; 600 s) in a process pool
with a progress bar.  Every run's metrics are written to
``<out>/runs/<method>_tp<demand>_seed<seed>.json`` as soon as it finishes
(an interrupted sweep keeps what it ran; ``--collect DIR ...`` merges such
directories), then ``results.csv``, ``summary.json``, ``table.json`` and the
plots, and one line per (method, demand) is printed: runs, collisions,
jammed vehicles (and how many of them stood at the entry of the
coordinating zone: within 30 m inside R1 or queued outside it, from the jam
log; only the first 50 jammed vehicles of a run are logged), runs with a
jam, mean delay, minimum PET.  Exit status 1 if
any run had a collision or a jammed vehicle (definitions:
:mod:`icv_envs.sim.intersection_metrics`).

    nice -n 10 python benchmarks/intersection_seeds.py --seeds 0-19 --seconds 600 --out results/intersection/seed_sweep
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path


def _job(args):
    from icv_envs.experiments.intersection_compare import run_intersection

    return run_intersection(*args)


def main(argv=None) -> int:
    from tqdm import tqdm

    from icv_envs.experiments.intersection_compare import collect_runs, parse_throughputs, validate_grid
    from icv_envs.experiments.seeds import parse_seeds

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--methods", default="multi-vp,single-vp,fcfs")
    p.add_argument("--throughput", default="2000,2500,3000")
    p.add_argument("--seeds", default="0-19", help="a count N or a list/range such as 0-19 or 5,7,10-12")
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--lane-use", dest="lane_use", default=None)
    p.add_argument("--warmup", type=float, default=0.0,
                   help="seconds run before the clock and the statistics start (collisions and jams of the "
                        "warm-up are counted in the table too); default 0: from an empty intersection")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--skip-existing", action="store_true",
                   help="do not re-run a (method, demand, seed) whose runs/*.json is already in --out (resume)")
    p.add_argument("--out", default="intersection_seed_sweep")
    p.add_argument("--collect", nargs="*", default=None, help="only merge these earlier output directories into --out")
    a = p.parse_args(argv)
    out = Path(a.out)
    if a.collect is None:
        methods = [m.strip() for m in a.methods.split(",") if m.strip()]
        tps = parse_throughputs(a.throughput)
        validate_grid(methods, tps, a.seeds, a.seconds)
        config = {"lane_use": a.lane_use} if a.lane_use else {}
        if a.warmup:
            config["warmup"] = a.warmup
        # seed outermost: an interrupted sweep keeps whole (method x demand) grids for its first seeds
        jobs = [(m, v, s, a.seconds, config) for s in parse_seeds(a.seeds) for v in tps for m in methods]
        (out / "runs").mkdir(parents=True, exist_ok=True)
        if a.skip_existing:
            jobs = [j for j in jobs if not (out / "runs" / f"{j[0]}_tp{j[1]:g}_seed{j[2]}.json").exists()]
        with ProcessPoolExecutor(max(1, a.workers)) as ex:
            futs = [ex.submit(_job, j) for j in jobs]
            for fut in tqdm(as_completed(futs), total=len(futs), desc="seed sweep"):
                r = fut.result()
                (out / "runs" / f"{r['method']}_tp{r['throughput']:g}_seed{r['seed']}.json").write_text(json.dumps(r))
        parts = [out]
    else:
        parts = a.collect
    s = collect_runs(parts, out)
    bad = 0
    print(f"{'method':10s} {'demand':>6s} {'runs':>4s} {'collisions':>10s} {'jammed':>6s} {'at R1':>6s} "
          f"{'jam runs':>8s} {'delay [s]':>9s} {'PET min [s]':>11s}")
    for r in s["table"]:
        bad += r["collisions"] + r["jammed"]
        d = "n/a" if r["mean_delay"] is None else f"{r['mean_delay']:.2f}"
        pm = "n/a" if r["pet_min"] is None else f"{r['pet_min']:.2f}"
        print(f"{r['method']:10s} {r['throughput']:6g} {r['seeds']:4d} {r['collisions']:10d} {r['jammed']:6d} "
              f"{r['jammed_at_R1_entry']:6d} {r['runs_with_jams']:8d} {d:>9s} {pm:>11s}")
    (out / "table.json").write_text(json.dumps(s["table"], indent=1))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
