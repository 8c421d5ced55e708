"""Stop 54: seq3200.py with the garbage collector's collections and their time in each window (gc.callbacks).
Run: PYTHONPATH=<tree> python seq3200_gc.py"""
import math, time, gc
from icv_envs.experiments.sumo_bench import _icv_steps
from icv_envs.envs.highway_formation_v0 import parallel_env
st = {"t": 0.0, "n": [0, 0, 0], "dt": [0.0, 0.0, 0.0]}
def cb(phase, info):
    g = info["generation"]
    if phase == "start":
        st["t"] = time.perf_counter()
    else:
        st["n"][g] += 1; st["dt"][g] += time.perf_counter() - st["t"]
gc.callbacks.append(cb)
n = 3200
for rep in range(4):
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    env = parallel_env(vehicles_count=n, formation_size=12, initial_position=None, road_length=float(span + 30.0 * 6 + 300.0), duration=7.0)
    env.reset(seed=0); _icv_steps(env, 5)
    st["n"] = [0, 0, 0]; st["dt"] = [0.0, 0.0, 0.0]
    c = time.process_time(); _icv_steps(env, 25); t = time.process_time() - c
    print(rep, round(t / 25 * 1e3, 2), "ms/step; collections by generation", st["n"], "ms in them", [round(x * 1e3, 1) for x in st["dt"]], "thresholds", gc.get_threshold())
    env.close(); del env
