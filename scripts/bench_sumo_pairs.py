"""The ring against SUMO for two source trees, alternately (issue 10).

    git worktree add /tmp/ref <commit>
    python scripts/bench_sumo_pairs.py /tmp/ref . [--runs 3] [--seconds 600] [--out DIR]

Each run is ``icv-envs bench highway-ramps --vs-sumo`` (the paper's ring,
HighwayRamps VGR 1/3 under the formation expert through the PettingZoo API,
and SUMO's ring with as many vehicles, alternating in one process) in a
fresh process whose working directory is the tree: ``python -m`` puts the
working directory first on ``sys.path``, before ``PYTHONPATH``, so a run
started from another checkout silently imports that checkout instead (how
stop 30's pairs went wrong). Each run's JSON goes to ``--out``; the script
prints, per run, the tree, the ratio to SUMO, both sides' vehicle-steps per
CPU second and the icv_envs warm-up's CPU seconds (500 simulated seconds:
the steadier figure of the two trees' speed, SUMO not involved), then the
medians.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path


def run(tree: Path, out: Path, seconds: float) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run([sys.executable, "-m", "icv_envs.cli", "bench", "highway-ramps", "--vs-sumo", "--seconds",
                    str(seconds), "--out", str(out)], cwd=tree, env=env, check=True, capture_output=True, text=True)
    files = sorted(out.glob("*.json"))
    if not files:
        raise RuntimeError(f"no JSON written to {out}")
    res = json.loads(files[-1].read_text())
    res["tree"] = str(tree)
    return res


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("reference", type=Path)
    p.add_argument("test", type=Path)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--seconds", type=float, default=600.0, help="simulated seconds per run (the last 100 are measured)")
    p.add_argument("--out", type=Path, default=Path("results/bench/sumo_pairs"))
    a = p.parse_args()
    if a.runs < 1:
        raise SystemExit(f"--runs = {a.runs}; allowed: an integer >= 1")
    a.out = a.out.resolve()  # (the runs start in the trees)
    trees = {"reference": a.reference.resolve(), "test": a.test.resolve()}
    rows = {k: [] for k in trees}
    for i in range(1, a.runs + 1):
        for name, tree in trees.items():
            r = run(tree, a.out / f"{name}_run{i}", a.seconds)
            rows[name].append(r)
            print(f"run {i} {name:9s} ratio {r['ratio_cpu']:.2f}  icv {r['icv_vehicle_steps_per_cpu_s']:,.0f}  "
                  f"SUMO {r['sumo_vehicle_steps_per_cpu_s']:,.0f}  warm-up {r['icv_warmup_cpu_s']:.2f} s CPU", flush=True)
    summary = {}
    for name, rs in rows.items():
        summary[name] = {"tree": str(trees[name]), "ratio_cpu": [r["ratio_cpu"] for r in rs],
                         "icv_warmup_cpu_s": [r["icv_warmup_cpu_s"] for r in rs],
                         "median_ratio": statistics.median(r["ratio_cpu"] for r in rs),
                         "median_warmup_cpu_s": statistics.median(r["icv_warmup_cpu_s"] for r in rs)}
    summary["warmup_speedup"] = summary["reference"]["median_warmup_cpu_s"] / summary["test"]["median_warmup_cpu_s"]
    print(json.dumps(summary))
    (a.out / "summary.json").write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
