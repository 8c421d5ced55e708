"""Stop 54: the garbage collector's share of a HighwayFormation step through PettingZoo's dicts (formations of 12,
the expert acting), N agents, STEPS policy steps after 5; FREEZE=1 calls gc.freeze() after those 5 steps.
Run: PYTHONPATH=<tree> [FREEZE=1] python gc_scale.py N STEPS [SEED]"""
import math, time, gc, sys
from icv_envs.experiments.sumo_bench import _icv_steps
from icv_envs.envs.highway_formation_v0 import parallel_env
st = {"t": 0.0, "n": [0, 0, 0], "dt": [0.0, 0.0, 0.0]}
def cb(phase, info):
    g = info["generation"]
    if phase == "start": st["t"] = time.perf_counter()
    else: st["n"][g] += 1; st["dt"][g] += time.perf_counter() - st["t"]
gc.callbacks.append(cb)
n = int(sys.argv[1]); steps = int(sys.argv[2]); seed = int(sys.argv[3]) if len(sys.argv) > 3 else 0
span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
total = steps / 5 + 2
env = parallel_env(vehicles_count=n, formation_size=12, initial_position=None, road_length=float(span + 30.0 * total + 300.0), duration=float(total + 1))
env.reset(seed=seed); _icv_steps(env, 5)
import os
if os.environ.get("FREEZE"): gc.freeze()
st["n"] = [0, 0, 0]; st["dt"] = [0.0, 0.0, 0.0]
c = time.process_time(); _icv_steps(env, steps); t = time.process_time() - c
print(n, steps, round(t / steps * 1e3, 2), "ms/step;", "gen counts", st["n"], "ms", [round(x * 1e3, 1) for x in st["dt"]], f"gc share {sum(st['dt'])/t:.1%}")
