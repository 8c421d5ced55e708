"""Real time per stage of the intersection's array-path step (stop 47):
selected methods wrapped by a perf_counter timer (about 0.2 us per call;
not the hooks of the expert's one-call paths, whose wrapping would turn them off),
inclusive times in us per step."""
import collections, sys, time
from icv_envs.envs.intersection_v0 import parallel_env
env = parallel_env(method="multi-vp", throughput=2200.0, duration=560, expert_in_info=False)
env.reset(seed=0)
core = env.core
while core.world.time < 100 - 1e-9:
    env.step_rows(core.expert_actions())
E = type(core.expert); C = type(core); W = type(core.world)
names = {E: ["update", "compute", "_prune", "_lane_change_progress", "_regroup",
             "_reroute_stuck", "_coordinate", "_start_lane_changes", "_references", "tree", "_detach_inverted",
             "references", "_apply_yields", "_signals", "_member_rows"],
         C: ["_advance", "_react", "_post_rows", "_spawn_due", "_feature_args", "_reward_args", "_before_physics", "_leaders", "ma_step_rows"],
         W: ["substeps", "route"]}
tot = collections.Counter(); cnt = collections.Counter()
def wrap(cls, name):
    f = getattr(cls, name)
    key = f"{cls.__name__}.{name}"
    def w(*a, **k):
        t0 = time.perf_counter_ns()
        try:
            return f(*a, **k)
        finally:
            tot[key] += time.perf_counter_ns() - t0; cnt[key] += 1
    setattr(cls, name, w)
for cls, ns in names.items():
    for n in ns:
        wrap(cls, n)
steps = 0
c0 = time.process_time()
while core.world.time < 550 - 1e-9:
    env.step_rows(core.expert_actions()); steps += 1
cpu = time.process_time() - c0
print(f"{steps} steps, {cpu / steps * 1e6:.0f} us per step (with the timers)")
for k, v in sorted(tot.items(), key=lambda kv: -kv[1]):
    print(f"  {k:40s} {v / steps / 1e3:7.1f} us/step  {cnt[k] / steps:5.2f} calls")
