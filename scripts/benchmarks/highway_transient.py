"""Where the formation expert's acceleration comes from on HighwayRamps.

For every vehicle-substep of a run driven by the formation expert, the
realised |dv/dt| (the ``speed_fluctuation`` of :mod:`icv_envs.sim.metrics`)
is attributed to one class:

* ``free``: not a formation member (ramps, leaving for an exit, ...);
* ``far``: a member more than 5 m from its target (``|X - X_ref| > 5 m``);
* ``young``: a member within 5 m of its target but in its first 20 s after
  joining (or after its slot was re-assigned);
* ``settled``: every other member.

Printed per run (one JSON line): the share of all members' |a| from members
> 5 m from their target, the share from members in their first 20 s after
joining (whatever their error), the settled members' mean |a|, and the run's
totals. Usage::

    PYTHONPATH=. python scripts/benchmarks/highway_transient.py --vgr 0.333 --seeds 0,1,5 --seconds 600
"""

from __future__ import annotations

import argparse
import json

import numpy as np


def measure(vgr: float, seed: int, seconds: float, config: dict | None = None) -> dict:
    from icv_envs.envs.highway_ramps_v0 import parallel_env

    env = parallel_env(method="formation", vgr=float(vgr), duration=float(seconds), **(config or {}))
    env.reset(seed=int(seed))
    w = env.core.world
    cap = 100000
    k_group = np.full(cap, -2, dtype=np.int64)  # slot key per vehicle id: (group, metres behind the front)
    k_behind = np.full(cap, np.nan)
    joined_at = np.zeros(cap)
    acc = {k: 0.0 for k in ("far", "young", "young_any", "settled", "member", "free", "all")}
    cnt = {k: 0 for k in acc}
    original = w.motion.record

    def record(vid, v0, v1, a, dt):
        original(vid, v0, v1, a, dt)
        tr = w.traffic
        x_ref, lane_ref, _, member = w.manager.references(tr)
        cx, _ = tr.center()
        err = np.where(member, np.abs(w.road.wrap(cx - np.nan_to_num(x_ref))), np.inf)
        ra = np.abs(np.asarray(v1) - np.asarray(v0)) / dt
        t = w.time + dt
        ids = tr.vid
        g = np.where(member, tr.group, -1)
        new = member & ((k_group[ids] != g) | (k_behind[ids] != tr.tgt_behind))
        joined_at[ids[new]] = t
        k_group[ids] = g
        k_behind[ids] = np.where(member, tr.tgt_behind, np.nan)
        young = member & (t - joined_at[ids] < 20.0)
        far = member & (err > 5.0)
        classes = {
            "far": far, "young": member & ~far & young, "young_any": member & young,
            "settled": member & ~far & ~young, "member": member, "free": ~member,
            "all": np.ones(tr.n, dtype=bool),
        }
        for k, m in classes.items():
            acc[k] += float(ra[m].sum())
            cnt[k] += int(m.sum())

    w.motion.record = record
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({ag: ex[ag] for ag in env.agents})
    m = env.metrics()
    env.close()
    mem = max(acc["member"], 1e-12)
    return {
        "vgr": vgr, "seed": seed, "seconds": seconds,
        "share_abs_a_members_far_gt5m": acc["far"] / mem,
        "share_abs_a_members_first20s": acc["young_any"] / mem,
        "settled_mean_abs_a": acc["settled"] / max(cnt["settled"], 1),
        "member_mean_abs_a": acc["member"] / max(cnt["member"], 1),
        "free_mean_abs_a": acc["free"] / max(cnt["free"], 1),
        "member_share_of_vehicle_time": cnt["member"] / max(cnt["all"], 1),
        **{k: m[k] for k in ("speed_fluctuation", "commanded_abs_accel", "mean_speed", "remaining", "collisions",
                             "min_time_headway", "time_headway_p05", "min_gap", "queued")},
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vgr", type=float, default=1.0 / 3.0)
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--seconds", type=float, default=600.0)
    args = ap.parse_args(argv)
    from icv_envs.experiments.seeds import parse_seeds

    for s in parse_seeds(args.seeds):
        print(json.dumps(measure(args.vgr, s, args.seconds)), flush=True)


if __name__ == "__main__":
    main()
