"""What the expert-driven check costs batched training worlds (issue 10).

    PYTHONPATH=$PWD python scripts/bench_expert_check.py [--worlds 16] [--vehicles 20] [--steps 60] [--reps 3]

``BatchedWorlds`` of HighwayFormation with learned (here: random, fixed
seed) actions, stepped with the envs' ``expert_driven_check`` on (every
action compared with the expert's, so the expert is computed every step)
and off (``BatchedWorlds(expert=False)``'s default), alternately in one
process; prints agent-steps per CPU second of each and the ratio per
repetition, then one JSON line.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from icv_envs.rl.bench import batched_sps


def rate(check: bool, worlds: int, vehicles: int, steps: int) -> float:
    r = batched_sps(vehicles, worlds, steps, expert=False, seed=0, config={"expert_driven_check": check},
                    actions="small")
    return r["agent_steps_per_cpu_s"]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--vehicles", type=int, default=20)
    p.add_argument("--steps", type=int, default=60)
    p.add_argument("--reps", type=int, default=3)
    a = p.parse_args()
    rate(False, 2, a.vehicles, 5)  # warm-up (imports, numba caches)
    rows = []
    for r in range(a.reps):
        on = rate(True, a.worlds, a.vehicles, a.steps)
        off = rate(False, a.worlds, a.vehicles, a.steps)
        rows.append({"check_on": on, "check_off": off, "ratio": off / on})
        print(f"rep {r}: check on {on:,.0f}, off {off:,.0f} agent-steps per CPU s; ratio {off / on:.2f}")
    print(json.dumps({"bench": "expert-check", "worlds": a.worlds, "vehicles": a.vehicles, "steps": a.steps,
                      "reps": rows, "ratio_median": float(np.median([x["ratio"] for x in rows]))}))


if __name__ == "__main__":
    main()
