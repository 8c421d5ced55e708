"""Stop 54: the scaling curve's 3200-vehicle point, four times in one process (fresh env each): CPU ms per policy step
over 25 steps after 5. Run: PYTHONPATH=<tree> python seq3200.py"""
import math, time, gc, resource
from icv_envs.experiments.sumo_bench import _icv_steps
from icv_envs.envs.highway_formation_v0 import parallel_env
n = 3200
for rep in range(4):
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    env = parallel_env(vehicles_count=n, formation_size=12, initial_position=None, road_length=float(span + 30.0 * 6 + 300.0), duration=7.0)
    env.reset(seed=0); _icv_steps(env, 5)
    c = time.process_time(); _icv_steps(env, 25); t = time.process_time() - c
    print(rep, round(t / 25 * 1e3, 2), "ms/step", "tracked objects", len(gc.get_objects()), "maxrss MB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss//1024)
    env.close(); del env
