"""Merge the ``runs/*.json`` of several ``icv-envs compare highway-ramps``
output directories into one, as if one sweep had produced them.

Sweeps are grids (methods x VGRs x seeds); adding seeds or methods to a
finished sweep is a second grid. This reads every run of the given
directories (a run met twice, same method, VGR and seed, is an error unless
both copies carry identical figures), optionally keeps only ``--methods``,
and writes to ``--out`` exactly what ``compare_highway_ramps`` writes:
``runs/``, ``results.csv``, ``summary.json`` and the plots.

    python scripts/merge_highway_runs.py /tmp/hw_all --methods lane-lp-close,idm-close --out results/highway_ramps_close
    python scripts/merge_highway_runs.py /tmp/hw_all --plots-only --out results/highway_ramps_close
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from icv_envs.experiments.compare import CSV_COLUMNS, plot_results, validate_methods, write_results

# figures that depend on the machine, not on the run
_TIMING = ("wall_seconds", "real_time_factor")


def merge(dirs: list[str], methods: list[str] | None = None) -> list[dict]:
    """The runs of ``dirs`` (``runs/*.json``), keeping ``methods`` only if given."""
    if methods is not None:
        try:
            validate_methods(methods)
        except ValueError as e:
            raise SystemExit(str(e)) from None
    runs: dict = {}
    for d in dirs:
        files = sorted(Path(d, "runs").glob("*.json"))
        if not files:
            raise SystemExit(f"{d}: no runs/*.json")
        for fp in files:
            r = json.loads(fp.read_text())
            if methods is not None and r["method"] not in methods:
                continue
            key = (r["method"], float(r["vgr"]), int(r["seed"]))
            if key in runs and any(runs[key].get(k) != r.get(k) for k in CSV_COLUMNS if k not in _TIMING):
                raise SystemExit(f"run {key} found twice with different figures ({fp})")
            runs[key] = r
    if not runs:
        raise SystemExit(f"no runs of methods {methods} in {dirs}")
    return list(runs.values())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    ap.add_argument("--methods", default=None, help="comma-separated; default: every method found")
    ap.add_argument("--out", required=True)
    ap.add_argument("--plots-only", action="store_true",
                    help="write only the plots (e.g. every method's curves beside a directory that keeps a subset)")
    a = ap.parse_args(argv)
    methods = a.methods.split(",") if a.methods else None
    results = merge(a.dirs, methods)
    if a.plots_only:
        Path(a.out).mkdir(parents=True, exist_ok=True)
        plot_results(results, a.out)
    else:
        write_results(results, a.out, methods)
    print(f"{len(results)} runs -> {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
