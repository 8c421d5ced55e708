"""In-process A/B of whole intersection steps (stop 47 review): two twin
envs (same seed, the same states at every step), one with this stop's
one-call paths, one with both turned off on the instance (the controls'
``_ONE_CALL_HOOKS`` None, the regrouping's hook ``_merging`` set on the
instance): the separate calls, as stop 46 made them. Each step of the
array path is timed on both, in alternating order; their states are
compared every step. A pair on the same state in one process removes most
of the host's noise between processes.

    PYTHONPATH=<tree> python results/bench/stop47/ab_step.py [METHOD THROUGHPUT SEED]"""
import sys, time
import numpy as np
from icv_envs.envs.intersection_v0 import parallel_env

method, tp, seed = (sys.argv[1], float(sys.argv[2]), int(sys.argv[3])) if len(sys.argv) > 3 else ("multi-vp", 2200.0, 0)
envs = []
for fast in (True, False):
    env = parallel_env(method=method, throughput=tp, duration=400, expert_in_info=False)
    env.reset(seed=seed)
    if not fast:
        ex = env.core.expert
        ex._ONE_CALL_HOOKS = None
        ex._merging = ex._merging
    envs.append(env)
for _ in range(500):  # 100 s, not timed
    for env in envs:
        env.step_rows(env.core.expert_actions())
t = [0, 0]
n = agents = 0
while envs[0].core.world.time < 300 - 1e-9:
    agents += envs[0].num_agents
    for k in ((0, 1) if n % 2 else (1, 0)):
        env = envs[k]
        c0 = time.perf_counter_ns()
        env.step_rows(env.core.expert_actions())
        t[k] += time.perf_counter_ns() - c0
    fa, fb = envs[0].core.world.fleet, envs[1].core.world.fleet
    assert fa.vid.tobytes() == fb.vid.tobytes() and fa.x.tobytes() == fb.x.tobytes(), "the twins diverged"
    n += 1
print(f"{method} {tp:g} veh/h seed {seed}: {n} steps, {agents / n:.0f} agents; step with the one-call paths "
      f"{t[0] / n / 1e3:.0f} us, with the separate calls {t[1] / n / 1e3:.0f} us, ratio {t[1] / t[0]:.3f}")
