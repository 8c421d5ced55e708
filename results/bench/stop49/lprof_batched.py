"""line_profiler over the batched learned case's hot Python (stop 49)."""
import sys
import numpy as np
from line_profiler import LineProfiler
from icv_envs.vector import BatchedWorlds
import icv_envs.vector as V, icv_envs.envs.agents_step as A, icv_envs.sim.formations as FM, icv_envs.sim.world as W
import icv_envs.envs.highway_rows as HR, icv_envs.sim.join_plans as JP, icv_envs.envs.highway_formation as HF
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=False)
bw.reset()
acts = np.zeros((16, bw.K, 2), dtype=np.float32)
for _ in range(100):
    bw.step(acts)
lp = LineProfiler()
env0 = bw._worlds[0] if hasattr(bw, "_worlds") else None
funcs = [V.BatchedWorlds.step, A.AgentsStep._ma_advance, A.AgentsStep._advance, W.World.substeps, W.World.record_min_gap,
         FM.FormationManager.update, FM.FormationManager._hold_targets, FM.FormationManager._profile,
         FM.FormationManager._references, FM.FormationManager._refs, HR.HighwayRows._post_rows, HR.HighwayRows._feature_args,
         HR.HighwayRows._reward_args, HR.HighwayRows._reward_total, JP.JoinPlans.profile, JP.JoinPlans._eval]
for name in dir(HF.HighwayFormationEnv):
    if name in ("_react", "_before_physics", "_drivers", "_vehicles", "ma_step_rows", "_truncations"):
        f = getattr(HF.HighwayFormationEnv, name)
        funcs.append(f)
for f in funcs:
    lp.add_function(f)
lp.enable_by_count()
N = 200
for _ in range(N):
    bw.step(acts)
lp.disable_by_count()
st = lp.get_stats()
ws = N * 16
rows = []
for (fn, line, name), timings in st.timings.items():
    tot = sum(t[2] for t in timings) * st.unit
    rows.append((tot, name, fn.split("/")[-1], line))
for tot, name, fn, line in sorted(rows, reverse=True):
    print(f"{tot / ws * 1e6:8.1f} us/world-step  {name} ({fn}:{line})")
if "--lines" in sys.argv:
    lp.print_stats(output_unit=1e-6, stripzeros=True)
