"""Re-select a ppo_recipe.py checkpoint on more validation episodes (issue 9, item 4).

ppo_recipe.py picks ``model.zip`` on ``--eval-episodes`` (default 2) validation
episodes per checkpoint: on lane-drop that is 16 vehicles, so "0 collisions"
says little (a collision rate of 5 per 100 vehicles passes it with
probability 0.95^16 = 44%), and many checkpoints tie. This script is the
second stage of a two-stage selection, in the spirit of successive halving:

1. **Candidates**: the checkpoints whose stage-1 validation (the ``curve.csv``
   rows of the run) had the fewest collisions, the ``--candidates`` best of
   them by stage-1 validation return (the recipe's own order).
2. **Stage 2**: each candidate runs ``--episodes`` more validation episodes on
   the seeds ``--seed`` + k (default 90002: the recipe's validation seeds are
   90000 + k and it used 90000-90001; the leaderboard's 1000000+ and the
   held-out 1000008+ are never touched), every agent driven by it, the run's
   own config (action and observation types included).
3. **Choice**: the fewest collisions over stage 2, ties by the highest mean
   team return, the recipe's rule (highway runs; open-road runs are not
   supported here, see ``--help``).

Writes ``OUT/model.zip`` (a copy of the chosen checkpoint), ``OUT/run.json``
(the run's, with ``reselection`` added: the candidates, their stage-2 figures
and the choice) and ``OUT/reselection.csv``, so OUT is a model directory the
leaderboard and ``icv-envs evaluate`` pick up.

    python baselines/reselect_checkpoint.py /work/ppo_meta_ld50_abort_seed1 --episodes 8 \
        --out results/learned/ppo_meta_lane-drop_50min_abort_seed1_resel
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import time
from pathlib import Path

from tqdm import tqdm

from icv_envs.rl.envs import env_family
from icv_envs.rl.evaluate import evaluate


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run", help="a ppo_recipe.py output directory that still holds checkpoints/")
    p.add_argument("--candidates", type=int, default=1000,
                   help="at most this many stage-1 checkpoints go to stage 2 (default: every tied one)")
    p.add_argument("--episodes", type=int, default=8, help="stage-2 validation episodes per candidate")
    p.add_argument("--seed", type=int, default=90002, help="first stage-2 validation seed")
    p.add_argument("--out", required=True)
    a = p.parse_args(argv)
    if a.candidates < 1 or a.episodes < 1:
        p.error(f"--candidates {a.candidates} / --episodes {a.episodes}: allowed integers >= 1")
    run = Path(a.run)
    meta = json.loads((run / "run.json").read_text())
    if meta.get("algo") != "ppo_recipe":
        p.error(f"{str(run)!r} is a {meta.get('algo')!r} run; allowed: a ppo_recipe.py run")
    if meta.get("env_kind") != "pettingzoo" or env_family(meta.get("env", "")) != "highway_formation":
        p.error(f"env {meta.get('env')!r}: stage 2 uses the highway rule (fewest collisions, then return); "
                "the open-road selection (throughput x no-collision share) is not implemented here")
    rows = []
    with open(run / "curve.csv") as fh:
        for r in csv.DictReader(fh):
            if r.get("val_return") and (run / "checkpoints" / r["slot_steps"] / "model.zip").is_file():
                rows.append((float(r["val_collisions_per_100"]), -float(r["val_return"]), r["slot_steps"]))
    if not rows:
        p.error(f"no checkpoints with a validation row in {str(run / 'curve.csv')!r}")
    fewest = min(r[0] for r in rows)
    cands = sorted(r for r in rows if r[0] == fewest)[: a.candidates]
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = dict(meta.get("config") or {})
    res = []
    t0 = time.perf_counter()
    for c1, negret, step in tqdm(cands, desc="stage 2"):
        ev = evaluate(meta["env"], str(run / "checkpoints" / step / "model.zip"), episodes=a.episodes,
                      seed=a.seed, config=cfg)
        veh = int(ev.get("vehicles") or 0)
        res.append({"checkpoint": step, "stage1_collisions_per_100": c1, "stage1_return": -negret,
                    "collisions": int(ev["collisions"]), "vehicles": veh,
                    "episode_return": float(ev["episode_return"]), "mean_speed": ev.get("mean_speed")})
    best = min(res, key=lambda r: (r["collisions"], -r["episode_return"]))
    shutil.copy(run / "checkpoints" / best["checkpoint"] / "model.zip", out / "model.zip")
    meta["reselection"] = {"from": str(run), "stage1_chosen": meta.get("train", {}).get("chosen_checkpoint"),
                           "candidates": a.candidates, "episodes": a.episodes, "seed": a.seed,
                           "chosen": best["checkpoint"], "results": res,
                           "wall_seconds": round(time.perf_counter() - t0, 1)}
    (out / "run.json").write_text(json.dumps(meta, indent=2))
    for name in ("curve.csv", "curve.png"):
        if (run / name).is_file():
            shutil.copy(run / name, out / name)
    with open(out / "reselection.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(res[0]))
        w.writeheader()
        w.writerows(res)
    for r in res:
        mark = " <- chosen" if r is best else ""
        print(f"{r['checkpoint']:>9s}  stage 1: {r['stage1_collisions_per_100']:.1f} coll/100, "
              f"{r['stage1_return']:.0f}  stage 2: {r['collisions']} collisions, return {r['episode_return']:.0f}{mark}")
    print(json.dumps({"chosen": best["checkpoint"], "stage1_chosen": meta["reselection"]["stage1_chosen"],
                      "collisions": best["collisions"], "episode_return": best["episode_return"]}))
    return 0 if math.isfinite(best["episode_return"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
