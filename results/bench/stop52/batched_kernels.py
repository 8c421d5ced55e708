"""Batched HighwayFormation worlds (16 x 20 agents, zero actions;
``--expert``: the expert's), each kernel's calls in 200 steps replayed back
to back, per kernel, in us per world-step, against the world-step's CPU time.

    PYTHONPATH=<tree> python results/bench/stop52/batched_kernels.py [--expert]
"""
import collections
import sys
import time

sys.path.insert(0, "scripts")
import bench_kernel_boundary as kb  # noqa: E402

expert = "--expert" in sys.argv
window = kb._batched(expert)
window()
c0 = time.process_time()
n = window()
step_us = (time.process_time() - c0) / n * 1e6
window = kb._batched(expert)
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
for k, a, b in calls:
    by[k.py_func.__name__].append((k, a, b))
rows = []
for name, cl in by.items():
    rows.append((kb._replay(cl) / n * 1e6, name, len(cl) / n, per[name]["returned_arrays"] / n))
tot = sum(r[0] for r in rows)
print(f"world-step {step_us:.1f} us; kernels replayed {tot:.1f} us ({tot / step_us:.0%}), "
      f"{counts['calls'] / n:.1f} calls, {counts['returned_arrays'] / n:.1f} returned arrays per world-step")
for us, name, c, ra in sorted(rows, reverse=True)[:20]:
    print(f"  {us:7.2f} us  {c:4.2f} calls  {ra:5.2f} returned  {name}")
