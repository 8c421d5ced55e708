"""Per-kernel time of the batched learned world-step's kernel calls replayed
back to back (stop 49): scripts/bench_kernel_boundary.py's recorder, then
each recorded call timed alone on its untouched copy (perf_counter_ns),
summed per kernel, us per world-step."""
import collections
import sys
import time

sys.path.insert(0, "/work/main/scripts")
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
for kernel, args, _ in calls:
    kernel(*args)
tot = collections.Counter(); cnt = collections.Counter()
for kernel, _, args in calls:
    t0 = time.perf_counter_ns()
    kernel(*args)
    tot[kernel.__name__ if hasattr(kernel, "__name__") else str(kernel)] += time.perf_counter_ns() - t0
    cnt[getattr(kernel, "__name__", str(kernel))] += 1
all_ = sum(tot.values())
print(f"{all_ / n / 1e3:.1f} us per world-step in {len(calls) / n:.1f} kernel calls")
for k, v in tot.most_common(15):
    print(f"  {k:28s} {v / n / 1e3:6.2f} us/world-step  {cnt[k] / n:5.2f} calls")
