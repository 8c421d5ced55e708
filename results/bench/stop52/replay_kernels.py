"""Each kernel's calls in a window of steps replayed back to back, per
kernel, in us per step, against the step's CPU time (stop 52):
``--case ring``: the paper's ring (HighwayRamps VGR 1/3, formation expert,
PettingZoo dicts, 300 s of warm-up), 100 policy steps; ``--case batched``:
16 HighwayFormation worlds of 20 agents (zero actions; ``--expert``: the
expert's), 200 steps, per world-step. The replay copies each call's
arguments first, so it reads memory the step had in cache: read the
figures as an upper bound of each kernel's share.

    PYTHONPATH=<tree> python results/bench/stop52/replay_kernels.py --case ring|batched [--expert]

(run from the repository's root: it imports ``scripts/bench_kernel_boundary.py``)
"""
import argparse
import collections
import sys
import time

sys.path.insert(0, "scripts")
import bench_kernel_boundary as kb  # noqa: E402


def ring_window():
    from icv_envs.envs import highway_ramps_v0

    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=400.0)
    env.reset(seed=0)

    def step():
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})

    for _ in range(1500):
        step()

    def window():
        for _ in range(100):
            step()
        return 100

    return window


p = argparse.ArgumentParser()
p.add_argument("--case", choices=("ring", "batched"), required=True)
p.add_argument("--expert", action="store_true", help="batched: the expert's action for every agent")
a = p.parse_args()
make = ring_window if a.case == "ring" else (lambda: kb._batched(a.expert))
window = make()
window()
c0 = time.process_time()
n = window()
step_us = (time.process_time() - c0) / n * 1e6
window = make()
window()
counts = collections.Counter()
per = collections.defaultdict(collections.Counter)
calls = []
undo = kb._wrap_kernels(counts, per, calls)
try:
    n = window()
finally:
    for mod, name, obj in undo:
        setattr(mod, name, obj)
by = collections.defaultdict(list)
for k, args, args2 in calls:
    by[k.py_func.__name__].append((k, args, args2))
rows = [(kb._replay(cl) / n * 1e6, name, len(cl) / n, per[name]["returned_arrays"] / n) for name, cl in by.items()]
tot = sum(r[0] for r in rows)
unit = "step" if a.case == "ring" else "world-step"
print(f"{unit} {step_us:.1f} us; kernels replayed {tot:.1f} us ({tot / step_us:.0%}), "
      f"{counts['calls'] / n:.1f} calls, {counts['returned_arrays'] / n:.1f} returned arrays per {unit}")
for us, name, c, ra in sorted(rows, reverse=True)[:20]:
    print(f"  {us:7.2f} us  {c:4.2f} calls  {ra:5.2f} returned  {name}")
