"""Stop 54: seq3200.py with the step split by timers around its main parts (ms a step). Run: PYTHONPATH=<tree> python seq3200_parts.py"""
import math, time, gc
from icv_envs.experiments.sumo_bench import _icv_steps
from icv_envs.envs.highway_formation_v0 import parallel_env
from icv_envs.sim import world as W
from icv_envs.sim import formations as FM
from icv_envs.policies import formation_expert as FE
from icv_envs.envs import dict_edge as DE, highway_rows as HR, agents_step as AS
targets = [(W.World, "substeps"), (W.World, "record_min_gap"), (FM.FormationManager, "update"), (FE.FormationExpert, "compute"),
           (HR.HighwayRowsMixin if hasattr(HR, "HighwayRowsMixin") else None, "_post_rows"), (DE.DictEdge, "_info_dicts"), (DE.DictEdge, "_agent_dicts"), (DE.DictEdge, "_check_actions")]
acc = {}
for cls, name in targets:
    if cls is None: continue
    orig = cls.__dict__[name]
    is_static = isinstance(orig, staticmethod)
    f = orig.__func__ if is_static else orig
    def mk(f, key):
        def w(*a, **k):
            t = time.perf_counter(); r = f(*a, **k); acc[key] = acc.get(key, 0.0) + time.perf_counter() - t; return r
        return w
    setattr(cls, name, staticmethod(mk(f, name)) if is_static else mk(f, name))
n = 3200
for rep in range(4):
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    env = parallel_env(vehicles_count=n, formation_size=12, initial_position=None, road_length=float(span + 30.0 * 6 + 300.0), duration=7.0)
    env.reset(seed=0); _icv_steps(env, 5)
    acc.clear()
    c = time.process_time(); _icv_steps(env, 25); t = time.process_time() - c
    print(rep, round(t / 25 * 1e3, 2), "ms/step", {k: round(v / 25 * 1e3, 2) for k, v in acc.items()})
    env.close(); del env
