"""Per-kernel replay time of the batched case (learned or expert actions):
which compiled kernels' own work (with their boundary) fills the 106 us of
a world-step that the replay measures (stop 47)."""
import collections, sys, time
sys.path.insert(0, "scripts")
import numpy as np
import bench_kernel_boundary as bk

expert = "--expert" in sys.argv
window = bk._batched(expert, 0)
window()
counts = collections.Counter(); per = collections.defaultdict(collections.Counter); calls = []
undo = bk._wrap_kernels(counts, per, calls)
try:
    n = window()
finally:
    for mod, name, obj in undo:
        setattr(mod, name, obj)
for k, a, _ in calls:
    k(*a)
tot = collections.Counter(); cnt = collections.Counter()
for rep in range(3):
    for k, _, a in calls:
        t0 = time.perf_counter_ns(); k(*a); dt = time.perf_counter_ns() - t0
        if rep == 2:
            tot[k.py_func.__name__] += dt; cnt[k.py_func.__name__] += 1
    calls = [(k, b, bk._clone(b)) for k, _, b in calls] if rep < 2 else calls
s = sum(tot.values())
print(f"replay {s / n / 1e3:.1f} us per world-step (timer inside)")
for k, v in tot.most_common(15):
    print(f"  {k:28s} {v / n / 1e3:7.2f} us/world-step  {cnt[k] / n:5.2f} calls  {v / cnt[k] / 1e3:6.2f} us/call")
