"""Stop 55: where the paper's ring spends a step (the last 100 s of 600, VGR 1/3), by API.
    PYTHONPATH=<tree> python prof_ring.py {dicts,lean,rows} [pyinstrument|cprofile|time]"""
import sys, time
from icv_envs.envs.highway_ramps_v0 import parallel_env
from icv_envs.experiments.bench import APIS
from icv_envs.experiments.sumo_bench import _icv_steps, _vehicle_steps
api = sys.argv[1]; mode = sys.argv[2] if len(sys.argv) > 2 else "time"
env = parallel_env(vgr=1 / 3, duration=600.0, method="formation", **APIS[api])
env.reset(seed=int(sys.argv[3]) if len(sys.argv) > 3 else 0)
_icv_steps(env, 2500, api)
vs0 = _vehicle_steps(env); t = time.process_time()
if mode == "pyinstrument":
    from pyinstrument import Profiler
    p = Profiler(interval=0.0005); p.start(); _icv_steps(env, 500, api); p.stop()
    print(p.output_text(unicode=False, color=False, show_all=False))
elif mode == "cprofile":
    import cProfile, pstats
    pr = cProfile.Profile(); pr.enable(); _icv_steps(env, 500, api); pr.disable()
    pstats.Stats(pr).sort_stats("tottime").print_stats(45)
else:
    _icv_steps(env, 500, api)
dt = time.process_time() - t
print(f"{api}: {len(env.agents)} agents, {(_vehicle_steps(env) - vs0) / dt:,.0f} veh-steps per CPU s, {dt / 500 * 1e3:.3f} ms/step")
