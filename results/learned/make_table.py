"""Build the tables of results/learned/README_table.md from the eval.json files
written by eval.sh and the run.json files written by train.sh.

    python results/learned/make_table.py   # prints the tables; README_table.md has them between its prose
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
EVAL = HERE / "eval"

LABELS = {
    "expert": "expert (formation)",
    "zero": "zero (coast straight)",
    "random": "random (uniform)",
    "single-vp": "single-vp (reference)",
    "fcfs": "fcfs (reference)",
    "bc_expert_highway": "learned: bc_expert (BC + DAgger, 5 scenarios)",
    "ppo_shared_lanedrop": "learned: ppo_shared (lane-drop)",
    "ppo_single_lanedrop": "learned: ppo_single (lane-drop ego)",
    "bc_expert_intersection": "learned: bc_expert (BC + DAgger of multi-vp)",
    "ppo_shared_intersection": "learned: ppo_shared",
}


def load(group: str, name: str) -> dict:
    return json.loads((EVAL / group / name / "eval.json").read_text())


def f(v, nd=2):
    return "-" if v is None else f"{v:.{nd}f}"


def highway_table(group: str, names: list[str]) -> str:
    rows = ["| policy | collisions / vehicles | mean speed (m/s) | speed fluctuation (m/s^2) | min gap (m) | exited | "
            "episode return | episode length (steps) |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for n in names:
        r = load(group, n)
        rows.append(f"| {LABELS[n]} | {r['collisions']} / {r['vehicles']} | {f(r['mean_speed'])} | {f(r['speed_fluctuation'], 3)} | "
                    f"{f(r['min_gap'], 1)} | {r['exited']} | {f(r['episode_return'], 1)} +- "
                    f"{f(r['episode_return_std'], 1)} | {f(r['episode_length'], 1)} |")
    return "\n".join(rows)


def intersection_table(names: list[str]) -> str:
    rows = ["| policy | collisions / spawned | wrong exits | achieved (veh/h) | mean speed (m/s) | speed fluctuation (m/s^2) | "
            "mean delay (s) | exited | left road | lost | episode return |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for n in names:
        r = load("intersection", n)
        label = "expert (multi-vp)" if n == "expert" else LABELS[n]
        rows.append(f"| {label} | {r['collisions']} / {r['spawned']} | {r['wrong_exits']} | {f(r['achieved_throughput'], 0)} | "
                    f"{f(r['mean_speed'])} | "
                    f"{f(r['speed_fluctuation'], 3)} | {f(r['mean_delay'], 1)} | {r['exited']} | {r['left_road']} | "
                    f"{r['lost']} | {f(r['episode_return'], 0)} +- {f(r['episode_return_std'], 0)} |")
    return "\n".join(rows)


def training_table() -> str:
    wall = {}
    wf = HERE / "logs" / "wall.txt"
    if wf.is_file():
        for line in wf.read_text().splitlines():
            name, sec, _ = line.split()
            wall[name] = int(sec)
    rows = ["| model | script | env, config | budget | training data / stats | wall (s) |",
            "|---|---|---|---|---|---:|"]
    for name in ("bc_expert_highway", "ppo_shared_lanedrop", "ppo_single_lanedrop", "bc_expert_intersection",
                 "ppo_shared_intersection"):
        p = HERE / name / "run.json"
        if not p.is_file():
            continue
        run = json.loads(p.read_text())
        a, tr = run["args"], run["train"]
        if run["algo"] == "bc_expert":
            budget = (f"{a['expert_steps']} expert env steps + {a['dagger_iters']} DAgger x {a['dagger_steps']} "
                      f"env steps, {a['epochs']} epochs/fit")
            stats = f"{tr['samples']} agent-step samples, saved fit of round {tr['saved_round']}"
        elif run["algo"] == "ppo_shared":
            budget = f"{tr['timesteps']} slot-steps ({tr['slots']} slots)"
            stats = f"{tr['env_steps']} env steps, placeholder fraction {tr['placeholder_fraction']:.2f}"
        else:
            budget = f"{tr['timesteps']} env steps"
            stats = f"ep_len_mean {tr['ep_len_mean']:.0f} at the end"
        scen = f", scenarios {','.join(run['scenarios'])}" if run.get("scenarios") else ""
        rows.append(f"| `{name}` | {run['algo']} | `{run['env']}` `{json.dumps(run['config'])}`{scen} | {budget} | "
                    f"{stats} | {wall.get(name, '-')} |")
    return "\n".join(rows)


def main() -> None:
    print("## Training runs\n")
    print(training_table())
    hw = ["expert", "zero", "random", "bc_expert_highway", "ppo_shared_lanedrop", "ppo_single_lanedrop"]
    for sc in ("lane-drop", "on-ramp"):
        print(f"\n## Highway formation, {sc}, every ICV driven by the policy\n")
        print(highway_table(f"highway_{sc}", hw))
    print("\n## Highway formation, lane-drop, one ego driven by the policy among expert ICVs\n")
    print(highway_table("highway_ego_lane-drop", ["expert", "zero", "random", "ppo_single_lanedrop",
                                                  "bc_expert_highway", "ppo_shared_lanedrop"]))
    print("\n## Intersection, 1500 veh/h, 120 s after an 80 s expert warm-up, every vehicle driven by the policy\n")
    print(intersection_table(["expert", "single-vp", "fcfs", "zero", "random", "bc_expert_intersection",
                              "ppo_shared_intersection"]))


if __name__ == "__main__":
    main()
