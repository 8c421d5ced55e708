"""The intersection bench's window through the array API (step_rows, the
expert's rows as actions) beside the dicts (stop 47): how much of the gap to
100k agent-steps per CPU s is the PettingZoo dict layer."""
import sys, time
import numpy as np
from icv_envs.envs.intersection_v0 import parallel_env

def run(api, seed=0, warmup=100.0, seconds=150.0):
    env = parallel_env(method="multi-vp", throughput=2200.0, duration=warmup + seconds + 10)
    obs, infos = env.reset(seed=seed)
    def step_d():
        nonlocal infos
        infos = env.step({a: infos[a]["expert_action"] for a in env.agents})[4]
    def step_r():
        env.step_rows(env.core.expert_actions())
    step = step_d if api == "dicts" else step_r
    while env.core.world.time < warmup - 1e-9:
        step()
    t0 = env.core.world.time; n = 0; c0 = time.process_time()
    while env.core.world.time < t0 + seconds - 1e-9:
        n += len(env.core._vehicles().vid); step()
    return n / (time.process_time() - c0), env.metrics()["collisions"]

for api in sys.argv[1:] or ["dicts", "rows"]:
    r, c = run(api)
    print(f"{api}: {r / 1e3:.1f}k agent-steps per CPU s (collisions {c})")
