"""The paper's ring (HighwayRamps VGR 1/3, formation expert, PettingZoo
dicts, 300 s of warm-up): each kernel's calls in 100 policy steps replayed
back to back, per kernel (us per step), against the step's CPU time.

    PYTHONPATH=<tree> python results/bench/stop52/ring_kernels.py
"""
import collections
import sys
import time

sys.path.insert(0, "scripts")
import bench_kernel_boundary as kb  # noqa: E402

from icv_envs.envs import highway_ramps_v0  # noqa: E402


def make():
    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=400.0)
    env.reset(seed=0)

    def step():
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})

    for _ in range(1500):
        step()
    return env, step


env, step = make()
for _ in range(50):
    step()
c0 = time.process_time()
for _ in range(100):
    step()
step_us = (time.process_time() - c0) / 100 * 1e6
env, step = make()
counts = collections.Counter()
per = collections.defaultdict(collections.Counter)
calls = []
undo = kb._wrap_kernels(counts, per, calls)
try:
    for _ in range(100):
        step()
finally:
    for mod, name, obj in undo:
        setattr(mod, name, obj)
by = collections.defaultdict(list)
for k, a, b in calls:
    by[k.py_func.__name__].append((k, a, b))
rows = []
for name, cl in by.items():
    rows.append((kb._replay(cl) / 100 * 1e6, name, len(cl) / 100))
tot = sum(r[0] for r in rows)
print(f"step {step_us:.0f} us at {len(env.agents)} agents; kernels replayed {tot:.0f} us ({tot / step_us:.0%}), "
      f"{counts['calls'] / 100:.1f} calls, {counts['returned_arrays'] / 100:.1f} returned arrays per step")
for us, name, c in sorted(rows, reverse=True)[:20]:
    print(f"  {us:7.1f} us  {c:4.2f} calls  {name}")
