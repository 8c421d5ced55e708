"""formation_post_rows's parts timed on recorded arguments (stop 47)."""
import collections, sys, time
sys.path.insert(0, "scripts")
import numpy as np
import bench_kernel_boundary as bk
from icv_envs.sim._kernels import observation as ob
from icv_envs.sim._kernels.physics import interval_ends_at, lane_of1

window = bk._batched(False, 0)
window()
counts = collections.Counter(); per = collections.defaultdict(collections.Counter); calls = []
undo = bk._wrap_kernels(counts, per, calls)
try:
    n = window()
finally:
    for mod, name, obj in undo:
        setattr(mod, name, obj)
post = [a for k, a, _ in calls if k.py_func.__name__ == "formation_post_rows"][:400]
print("n vehicles", np.mean([len(a[0]) for a in post]), "rows", np.mean([len(a[18]) for a in post]), "K", post[0][29], "V", post[0][32], "idx", post[0][31+2])
def t(f, reps=3):
    best = 1e9
    for _ in range(reps):
        t0 = time.perf_counter_ns()
        for a in post: f(a)
        best = min(best, (time.perf_counter_ns() - t0) / len(post) / 1e3)
    return best
full = t(lambda a: ob.formation_post_rows(*a))
feat = t(lambda a: ob.formation_feature_rows(*a[:18]))
F_all = [ob.formation_feature_rows(*a[:18]) for a in post]
j = [0]
def rew(a):
    F = ob.formation_feature_rows(*a[:18])
    ob.formation_reward_terms(a[18], a[19], a[20], a[21], a[22], a[23], F, a[24], a[25], a[26], a[27], a[28])
def near(a):
    F = ob.formation_feature_rows(*a[:18])
    ob.nearest_along_road(F[:, 1].copy(), a[18], a[29], a[30], a[31], a[32])
def kin(a):
    F = ob.formation_feature_rows(*a[:18])
    sel, pr = ob.nearest_along_road(F[:, 1].copy(), a[18], a[29], a[30], a[31], a[32])
    ob.kinematics_rows(F, a[18], sel, pr, *a[33:])
print(f"full {full:.2f} us; features {feat:.2f}; +reward {t(rew):.2f}; features+near {t(near):.2f}; features+near+kin {t(kin):.2f}")
