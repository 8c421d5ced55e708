"""README table rows from runs/*.json: python scripts/intersection_table_rows.py SEEDSPEC DIR... (SEEDSPEC e.g. 0-19 or all)."""
import json, sys
from pathlib import Path
from icv_envs.experiments.intersection_compare import summarise
spec, dirs = sys.argv[1], sys.argv[2:]
runs = []
for d in dirs:
    runs += [json.loads(p.read_text()) for p in sorted(Path(d, "runs").glob("*.json"))]
if spec != "all":
    lo, hi = map(int, spec.split("-")); runs = [r for r in runs if lo <= int(r["seed"]) <= hi]
s = summarise(runs)
def f(x, ci, fmt):
    if x is None: return "n/a"
    return fmt.format(x) + ("" if ci is None or ci != ci else " +- " + fmt.format(ci))
for r in s["table"]:
    js = sum(x.get("jammed_vehicle_seconds", 0.0) for x in runs if x["method"] == r["method"] and x["throughput"] == r["throughput"])
    ss = r.get("served_share")
    print(f"| {r['throughput']:.0f} | {r['method']} | {r['seeds']} | {f(r['achieved_throughput'], r['achieved_throughput_ci95'], '{:.0f}')} | "
          f"{ss:.3f} | {f(r['mean_speed'], r['mean_speed_ci95'], '{:.2f}')} | {f(r['speed_fluctuation'], r['speed_fluctuation_ci95'], '{:.3f}')} | "
          f"{f(r['mean_delay'], r['mean_delay_ci95'], '{:.2f}')} | {r['pet_p05']:.2f} | {r['pet_min']:.2f} | {r['collisions']} | "
          f"{r['jammed']} ({r['jammed_at_R1_entry']}) | {js:.0f} | {r['runs_with_jams']} |")
print("capacity:", json.dumps(s["capacity"]))
