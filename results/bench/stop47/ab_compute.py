"""In-process A/B of the intersection expert's controls (stop 47 review):
on the same states, every step, ``compute`` through the one-call path and
through the separate calls (the instance's ``_ONE_CALL_HOOKS`` None), in
alternating order, CPU time of each summed; also how often the one-call
path fell back (a vehicle standing in the box). A within-process pair on
the same state removes most of the host's noise between processes.

    PYTHONPATH=<tree> python results/bench/stop47/ab_compute.py [METHOD THROUGHPUT SEED]"""
import sys, time
import numpy as np
from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.policies._kernels import box_obstacle_rows

method, tp, seed = (sys.argv[1], float(sys.argv[2]), int(sys.argv[3])) if len(sys.argv) > 3 else ("multi-vp", 2200.0, 0)
env = parallel_env(method=method, throughput=tp, duration=400, expert_in_info=False)
env.reset(seed=seed)
core = env.core
ex, w = core.expert, core.world
while w.time < 100 - 1e-9:
    env.step_rows(core.expert_actions())
t_one = t_sep = 0.0
fallback = steps = 0
def one():
    return ex.compute(w)
def sep():
    ex._ONE_CALL_HOOKS = None
    try:
        return ex.compute(w)
    finally:
        del ex._ONE_CALL_HOOKS
while w.time < 300 - 1e-9:
    if w.fleet.n:
        rs = w.route()
        fallback += bool(len(box_obstacle_rows(rs.phase, rs.s, rs.L, w.fleet.speed, 1.0)))
        order = (one, sep) if steps % 2 else (sep, one)
        for fn in order:
            c0 = time.perf_counter_ns(); fn(); dt = time.perf_counter_ns() - c0
            if fn is one:
                t_one += dt
            else:
                t_sep += dt
        steps += 1
    env.step_rows(core.expert_actions())
print(f"{method} {tp:g} veh/h seed {seed}: {steps} steps, fallback in {fallback}; compute one-call "
      f"{t_one / steps / 1e3:.1f} us, separate {t_sep / steps / 1e3:.1f} us, ratio {t_sep / t_one:.2f}")
