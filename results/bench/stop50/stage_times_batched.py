"""Real time per stage of a batched learned world-step (stop 50; stop 49's
script with 400 warm-up steps, so kernels first loaded at a collision fall
outside the window, and without ``_hold_targets`` (inside
``FormationManager.update``'s one call from stop 50) and ``_reward_total``
(one of the hooks ``HighwayRows._post_rows`` stands for from stop 50:
wrapping it sends the step to the separate calls)): selected methods
wrapped by a perf_counter timer (~0.2 us a call), inclusive us per
world-step. 16 HighwayFormation worlds of 20 agents, zero actions
(``--expert``: the expert's)."""
import collections, sys, time
import numpy as np
from icv_envs.vector import BatchedWorlds
expert = "--expert" in sys.argv
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
bw.reset()
acts = np.zeros((16, bw.K, 2), dtype=np.float32)
for _ in range(400):
    bw.step(bw.expert_actions if expert else acts)
core = bw._envs[0] if hasattr(bw, "_envs") else None
import icv_envs.vector as V, icv_envs.envs.agents_step as A, icv_envs.sim.formations as FM, icv_envs.sim.world as W
import icv_envs.envs.highway_rows as HR, icv_envs.envs.highway_formation as HF, icv_envs.sim.join_plans as JP
classes = {}
def find(mod, name):
    return getattr(mod, name)
names = [(A.AgentsStep, ["_ma_advance", "_advance", "_react", "_post_rows", "_before_physics", "_controls", "_realign_rows", "_truncations", "_departed", "ma_step_rows", "_after_frames"]),
         (FM.FormationManager, ["update", "_profile", "_plan", "_reform", "_references", "references"]),
         (W.World, ["substeps", "record_min_gap", "set_expert_driven"]),
         (HR.HighwayRows, ["_post_rows", "_feature_args", "_reward_args"]),
         (JP.JoinPlans, ["profile", "plan", "_eval"]),
         (V.BatchedWorlds, ["step"])]
tot = collections.Counter(); cnt = collections.Counter()
def wrap(cls, name):
    f = cls.__dict__.get(name)
    if f is None:
        print("skip", cls.__name__, name); return
    key = f"{cls.__name__}.{name}"
    def w(*a, **k):
        t0 = time.perf_counter_ns()
        try:
            return f(*a, **k)
        finally:
            tot[key] += time.perf_counter_ns() - t0; cnt[key] += 1
    setattr(cls, name, w)
for cls, ns in names:
    for n in ns:
        wrap(cls, n)
# subclass overrides
for sub in type(bw).__mro__:
    pass
N = 300
t0 = time.perf_counter()
for _ in range(N):
    bw.step(bw.expert_actions if expert else acts)
el = time.perf_counter() - t0
ws = N * 16
print(f"{ws} world-steps, {el / ws * 1e6:.1f} us per world-step (with the timers)")
for k, v in sorted(tot.items(), key=lambda kv: -kv[1]):
    print(f"  {k:40s} {v / ws / 1e3:7.1f} us/world-step  {cnt[k] / ws:5.2f} calls")
