"""Slot layout occupancy: the share of placeholder slot-steps and the
overflow (vehicles driven by the expert for lack of a slot) of
icv_envs.rl.slots with K from the config, every vehicle driven by the expert
through its slot (the traffic is the expert's, as in the raw env).

    PYTHONPATH=$PWD python scripts/benchmarks/slot_occupancy.py --seeds 3 --out results/slots

Runs the intersection at 1500 veh/h (the default 120 s episode starting
empty, and with a warm-up equal to the free-flow trip time so that it starts
in steady state) and, with --ramps, the highway-ramps default (600 s,
VGR 1/3). Writes occupancy.json and occupancy.md to --out.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

from tqdm import tqdm

from icv_envs.rl.slots import _trip_time_intersection, slot_parallel_env


def run(name: str, cfg: dict, seed: int) -> dict:
    env = slot_parallel_env(name, cfg)
    t0 = time.perf_counter()
    obs, info = env.reset(seed=seed)
    steps = vehicle_steps = 0
    while env.agents:
        vehicle_steps += len(env.env.agents)
        obs, rew, term, trunc, info = env.step({s: info[s]["expert_action"] for s in env.agents})
        steps += 1
    m = env.core.metrics()
    return {"env": name, "config": cfg, "seed": seed, "K": env.K, "steps": steps,
            "placeholder_fraction": env.placeholder_fraction, "mean_alive": vehicle_steps / max(steps, 1),
            "overflow_vehicle_steps": env.overflow_vehicle_steps, "vehicle_steps": vehicle_steps,
            "overflow_share": env.overflow_vehicle_steps / max(vehicle_steps, 1),
            "collisions": m.get("collisions"), "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default="results/slots")
    ap.add_argument("--ramps", action="store_true", help="also the highway-ramps default (slow: ~400 vehicles)")
    args = ap.parse_args(argv)
    probe = slot_parallel_env("intersection_v0", {})
    W = _trip_time_intersection(probe.core)
    cases = [("intersection_v0", {"throughput": 1500.0}),
             ("intersection_v0", {"throughput": 1500.0, "warmup": float(math.ceil(W))})]
    if args.ramps:
        cases.append(("highway_ramps_v0", {}))
    rows = []
    for name, cfg in tqdm([(n, c) for n, c in cases], desc="cases"):
        for seed in range(args.seeds if name == "intersection_v0" else 1):
            rows.append(run(name, cfg, seed))
            tqdm.write(json.dumps(rows[-1]))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "occupancy.json").write_text(json.dumps({"trip_time_intersection_s": W, "runs": rows}, indent=2))
    lines = ["| env | config | seed | K | mean alive | placeholder share | overflow share of vehicle-steps |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['env']} | `{json.dumps(r['config'])}` | {r['seed']} | {r['K']} | {r['mean_alive']:.1f} | "
                     f"{r['placeholder_fraction']:.3f} | {r['overflow_share']:.4f} |")
    (out / "occupancy.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
