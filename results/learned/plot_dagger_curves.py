"""DAgger learning curves of the intersection clones (stop 22): per round, the collisions per 1000
agent-steps of the learner's own rollout (1800 env steps at 1500 veh/h, training seeds), for each
training seed, with the round each run saved (the fit whose rollout had the fewest failures).

    python results/learned/plot_dagger_curves.py   # -> results/learned/dagger_curves_intersection.png / .csv
"""

import csv
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).parent
RUNS = {"seed 0": "bc_dagger_intersection_leader_30rounds", "seed 1": "bc_dagger_intersection_leader_30rounds_seed1",
        "seed 2": "bc_dagger_intersection_leader_30rounds_seed2"}

fig, ax = plt.subplots(figsize=(7, 4))
rows = []
for label, name in RUNS.items():
    run = json.loads((HERE / name / "run.json").read_text())
    rounds = [r for r in run["train"]["rounds"] if r["driver"] == "learner"]
    x = [r["round"] for r in rounds]
    y = [r["rollout"]["collisions_per_1000_agent_steps"] for r in rounds]
    rows += [{"run": name, "round": a, "collisions_per_1000_agent_steps": b} for a, b in zip(x, y)]
    (line,) = ax.plot(x, y, marker=".", label=f"{label} (saved: round {run['train']['saved_round']})")
    s = run["train"]["saved_round"]
    if s in x:
        ax.plot([s], [y[x.index(s)]], "o", mfc="none", ms=10, color=line.get_color())
ax.set_yscale("symlog", linthresh=0.1)
ax.set_xlabel("DAgger round (the learner drives)")
ax.set_ylabel("collisions per 1000 agent-steps (rollout)")
ax.set_title("Intersection 1500 veh/h: BC + DAgger, leader features, 3 training seeds", fontsize=10)
ax.grid(True, alpha=0.3)
ax.legend()
fig.tight_layout()
fig.savefig(HERE / "dagger_curves_intersection.png", dpi=110)
with open(HERE / "dagger_curves_intersection.csv", "w", newline="") as fh:
    w = csv.DictWriter(fh, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
print(HERE / "dagger_curves_intersection.png")
