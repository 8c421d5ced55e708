"""Trace the first jammed vehicle of an intersection run (issue 8): what holds it.

    PYTHONPATH=$PWD python scripts/trace_intersection_jam.py --method multi-vp --throughput 3000 --seed 3

Runs the method's expert (600 s after a 100 s warm-up, as the seed sweeps do) until the jam watchdog
logs its first vehicle (stopped more than 10 s outside a queue at the box), then runs the same seed
again (runs are deterministic) and prints, every 2 s over the 12 s before that moment, every vehicle
of that approach leg within 80 m of it: distance to the centre, speed, lane (current / expected /
changing into), stage, node, the vehicle it follows, longitudinal mode, reference ``xref`` against
its ``X`` (a reference larger than ``X`` lies behind it: it is held), the stop-before-the-box flag,
whether it is coordinated, and whether it would count as in a queue at the box.
"""

from __future__ import annotations

import argparse

import numpy as np

from icv_envs.envs.intersection_v0 import parallel_env

MODES = {0: "free", 1: "follow", 2: "tree", 3: "plan"}


def make(a):
    env = parallel_env(method=a.method, throughput=a.throughput, duration=a.seconds, warmup=a.warmup,
                       expert_in_info=False)
    env.reset(seed=a.seed)
    return env


def step(env):
    ex = env.expert_actions()
    env.step({ag: ex[ag] for ag in env.agents})


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--method", default="multi-vp")
    p.add_argument("--throughput", type=float, default=3000.0)
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--seconds", type=float, default=600.0)
    p.add_argument("--warmup", type=float, default=100.0)
    a = p.parse_args()
    env = make(a)
    w = env.core.world
    while not env.episode_over and not w.jams.log:
        step(env)
    if not w.jams.log:
        print("no jam in this run")
        return
    t_j, vid, d = w.jams.log[0]
    print(f"first jam: vehicle {vid} at t = {t_j} s, {d} m from the centre (stopped since about {t_j - 10:.1f} s)")
    env = make(a)
    core = env.core
    w, ex, f = core.world, core.expert, core.world.fleet
    t_next = t_j - 12.0
    while w.time < t_j + 1e-9:
        step(env)
        if w.time + 1e-9 < t_next or vid not in set(f.vid.tolist()):
            continue
        t_next += 2.0
        rs = w.route()
        r = int(f.rows([vid])[0])
        near = np.flatnonzero((f.leg == f.leg[r]) & (rs.phase == 0) & (np.abs(rs.dist - rs.dist[r]) < 80.0))
        near = near[np.argsort(rs.dist[near])]
        q = w._in_queue(near, rs.u, rs.lat_leg)
        coord = ex._coordinated(f)
        print(f"t = {w.time:.1f} s, nodes in the virtual platoon: {len(getattr(ex, 'nodes', {}))}")
        for i, k in enumerate(near):
            mode = MODES.get(int(ex._mode[k]), int(ex._mode[k]))
            print(f"  {'>' if f.vid[k] == vid else ' '} vid {f.vid[k]:4d} d {rs.dist[k]:6.1f} v {f.speed[k]:5.2f} "
                  f"lane {f.klane[k]}/{f.tlane[k]}/{f.lc_lane[k]:2d} mv {f.mv[k]:2d} stage {f.stage[k]} "
                  f"node {f.node[k]:4d} follows {f.ref[k]:4d} mode {mode:6s} xref {ex._xref[k]:6.1f} "
                  f"X {rs.X[k]:6.1f} stop {int(ex._stop[k])} coordinated {int(coord[k])} queued {int(q[i])}")
    print("expert stats:", ex.stats)


if __name__ == "__main__":
    main()
