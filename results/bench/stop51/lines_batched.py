"""line_profiler over the Python of a batched learned world-step (stop 51):
16 HighwayFormation worlds x 20 agents, zero actions (``--expert``: the
expert's), 400 steps of warm-up, 200 profiled. Times are per line in all
(line_profiler adds its own cost per line: read them as shares)."""
import sys
import numpy as np
from line_profiler import LineProfiler
from icv_envs.vector import BatchedWorlds
import icv_envs.vector as V, icv_envs.envs.agents_step as A, icv_envs.sim.formations as FM, icv_envs.sim.world as W
import icv_envs.envs.highway_rows as HR, icv_envs.envs.highway_formation as HF, icv_envs.envs.parallel as P
import icv_envs.sim.traffic as T, icv_envs.envs.dict_edge as D
expert = "--expert" in sys.argv
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
bw.reset()
acts = np.zeros((16, bw.K, 2), dtype=np.float32)
for _ in range(400):
    bw.step(bw.expert_actions if expert else acts)
lp = LineProfiler()
for cls, names in [(V.BatchedWorlds, ["step"]), (A.AgentsStep, ["_ma_advance", "_advance", "_before_physics", "_controls"]),
                   (FM.FormationManager, ["update", "_keep_refs", "references", "_refs"]),
                   (W.World, ["substeps", "record_min_gap", "set_expert_driven"]),
                   (HR.HighwayRows, ["_post_rows", "_feature_args", "_reward_args"])]:
    for n in names:
        f = cls.__dict__.get(n)
        if f is not None:
            lp.add_function(f)
for mod in (P, HF, D, T):
    for name, obj in vars(mod).items():
        if isinstance(obj, type) and obj.__module__ == mod.__name__:
            for n, f in vars(obj).items():
                if callable(f) and hasattr(f, "__code__"):
                    lp.add_function(f)
for _ in range(200):
    lp.runcall(bw.step, bw.expert_actions if expert else acts)
lp.print_stats(output_unit=1e-6, stripzeros=True)
