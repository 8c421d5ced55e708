"""The README's intersection tables (seed sweep, held-out seeds, saturation sweep) from the committed runs.

    python scripts/readme_intersection_tables.py

Rows come from ``scripts/intersection_table_rows.py SEEDSPEC DIR...`` (seed means +- 95% t-intervals,
via :func:`icv_envs.experiments.intersection_compare.summarise`).
"""
import subprocess
import sys
from pathlib import Path

R = "results/intersection"
ROWS = str(Path(__file__).with_name("intersection_table_rows.py"))


def rows(spec, *dirs):
    out = subprocess.run([sys.executable, ROWS, spec, *dirs], capture_output=True, text=True, check=True).stdout
    return [l for l in out.splitlines() if l.startswith("|")], [l for l in out.splitlines() if l.startswith("capacity")]


HDR = ("| demand [veh/h] | method | seeds | achieved [veh/h] | served share | mean speed [m/s] | fluctuation [m/s^2] | "
       "mean delay [s] | PET p05 [s] | min PET [s] | collisions | jammed (at R1) | jammed veh-s | runs with a jam |\n"
       "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
dev, _ = rows("0-19", f"{R}/seed_sweep_stop23", f"{R}/seed_sweep_fcfs_stop21")
held, _ = rows("20-29", f"{R}/seed_sweep_stop23_heldout")
held = [l.replace(" | multi-vp | ", " | multi-vp (held out) | ").replace(" | single-vp | ", " | single-vp (held out) | ")
        for l in held]
print(HDR)
print("\n".join(dev + held))
sat_dir = Path(f"{R}/saturation_sweep_stop23")
if sat_dir.exists():
    sat, cap = rows("all", str(sat_dir))
    print()
    print(HDR)
    print("\n".join(sat))
    print(cap)
