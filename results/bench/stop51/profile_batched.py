"""Where the Python of a batched learned world-step goes (stop 51): 16
HighwayFormation worlds x 20 agents, zero actions (``--expert``: the
expert's), 400 steps of warm-up, then by function (cProfile, 300 steps:
own time and calls per world-step) or with ``--lines`` by line
(line_profiler over the step's methods, 200 steps). Both profilers add
their own cost per call or line: read the figures as shares."""
import sys
import numpy as np
from icv_envs.vector import BatchedWorlds
expert = "--expert" in sys.argv
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
bw.reset()
acts = np.zeros((16, bw.K, 2), dtype=np.float32)
for _ in range(400):
    bw.step(bw.expert_actions if expert else acts)


def by_function():
    import cProfile, pstats
    N = 300
    pr = cProfile.Profile()
    pr.enable()
    for _ in range(N):
        bw.step(bw.expert_actions if expert else acts)
    pr.disable()
    ws = N * 16
    st = pstats.Stats(pr)
    rows = []
    for (f, l, fn), (cc, nc, tt, ct, callers) in st.stats.items():
        rows.append((tt, nc, ct, f"{f.split('/')[-1]}:{l}:{fn}"))
    tot_calls = sum(r[1] for r in rows)
    tot_t = sum(r[0] for r in rows)
    print(f"{tot_calls / ws:.1f} calls per world-step, {tot_t / ws * 1e6:.1f} us own time (profiled)")
    for tt, nc, ct, name in sorted(rows, reverse=True)[:60]:
        print(f"{tt / ws * 1e6:7.2f} us {nc / ws:6.2f} calls  cum {ct / ws * 1e6:7.2f}  {name}")


def by_line():
    from line_profiler import LineProfiler
    import icv_envs.vector as V, icv_envs.envs.agents_step as A, icv_envs.sim.formations as FM
    import icv_envs.sim.world as W, icv_envs.envs.highway_rows as HR, icv_envs.envs.highway_formation as HF
    import icv_envs.envs.parallel as P, icv_envs.sim.traffic as T, icv_envs.envs.dict_edge as D
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


by_line() if "--lines" in sys.argv else by_function()
