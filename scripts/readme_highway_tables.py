"""Print README's per-method highway table (markdown) from the ``summary.json``
of one or more ``icv-envs compare highway-ramps`` output directories.

One row per (method, VGR): seed means with 95% t half-widths for the
figures that carry an interval, the worst seed for the safety margins
(minimum time headway; 5th-percentile time headway), collisions summed over
seeds.

    python scripts/readme_highway_tables.py results/highway_ramps results/highway_ramps_close
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from icv_envs.envs.highway_ramps import METHODS


def rows(dirs: list[str]) -> list[dict]:
    table = []
    for d in dirs:
        fp = Path(d, "summary.json")
        if not fp.is_file():
            raise SystemExit(f"{d}: no summary.json")
        table += json.loads(fp.read_text())["table"]
    return sorted(table, key=lambda r: (r["vgr"], METHODS.index(r["method"])))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args(argv)
    print("| method | VGR | seeds | remaining | queued | exited | missed exits | mean speed [m/s] "
          "| speed fluct. [m/s^2] | min time headway [s], worst seed | p05 time headway [s], worst seed | collisions |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows(a.dirs):
        print(f"| {r['method']} | {r['vgr']:g} | {r['seeds']} | {r['remaining']:.1f} +- {r['remaining_ci95']:.1f} "
              f"| {r['queued']:.1f} | {r['exited']:.1f} | {r['missed_exits']:.1f} "
              f"| {r['mean_speed']:.2f} +- {r['mean_speed_ci95']:.2f} "
              f"| {r['speed_fluctuation']:.3f} +- {r['speed_fluctuation_ci95']:.3f} "
              f"| {r['min_time_headway_worst']:.2f} | {r['time_headway_p05_worst']:.2f} | {r['collisions']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
