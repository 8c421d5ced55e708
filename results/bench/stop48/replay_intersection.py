"""Per-kernel replay time of the intersection (multi-vp 2200 veh/h, seed 0,
array path, 150 s after 100 s): each compiled kernel called again on clones
of the arguments it got, timed one call at a time; which kernels' own work
(boundary included) fills an intersection step (stop 48). Run from the
checkout's root: ``PYTHONPATH=<tree> python results/bench/stop48/replay_intersection.py [SEED]``."""
import collections, sys, time
import os; sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "scripts"))
import bench_kernel_boundary as bk
from icv_envs.envs.intersection_v0 import parallel_env

seed = int(sys.argv[1]) if len(sys.argv) > 1 else 0
env = parallel_env(method="multi-vp", throughput=2200.0, duration=450.0)
env.reset(seed=seed)
core = env.core
while core.world.time < 100 - 1e-9:
    env.step_rows(core.expert_actions())
def window(seconds=150):
    n = 0; t0 = core.world.time
    while core.world.time < t0 + seconds - 1e-9:
        env.step_rows(core.expert_actions()); n += 1
    return n
c0 = time.process_time(); n0 = window(50); step_us = (time.process_time() - c0) / n0 * 1e6
counts = collections.Counter(); per = collections.defaultdict(collections.Counter); calls = []
undo = bk._wrap_kernels(counts, per, calls)
try:
    n = window()
finally:
    for mod, name, obj in undo:
        setattr(mod, name, obj)
tot = collections.Counter(); cnt = collections.Counter()
calls = [(k, b, bk._clone(b)) for k, _, b in calls]
for rep in range(3):
    for k, _, a in calls:
        t0 = time.perf_counter_ns(); k(*a); dt = time.perf_counter_ns() - t0
        if rep == 2:
            tot[k.py_func.__name__] += dt; cnt[k.py_func.__name__] += 1
    calls = [(k, b, bk._clone(b)) for k, b, _ in calls]
s = sum(tot.values())
print(f"step {step_us:.1f} us (process time, 50 s unwrapped); kernels replayed {s / n / 1e3:.1f} us per step, {n} steps")
for k, v in tot.most_common(25):
    print(f"  {k:30s} {v / n / 1e3:7.2f} us/step  {cnt[k] / n:5.2f} calls  {v / cnt[k] / 1e3:6.2f} us/call")
