"""Stop 51's changes in situ: twin batches (16 HighwayFormation worlds x 20
agents, the same seed, zero actions) stepped alternately in one process,
twin B with one change undone on its own objects (instance attributes, so
twin A runs this tree's code), 150 steps of warm-up, then 20 rounds of 10
steps each per twin (process CPU per world-step; medians, and the median
of the per-round differences)."""
import statistics, sys, time, types
import numpy as np
from icv_envs.vector import BatchedWorlds
import icv_envs.envs.agents_step as A


def numpy_cos_sin(self):  # stop 50's Traffic.heading_cos_sin
    c = self._cos_sin
    h = self.heading
    if c is not None and c[0] is h:
        return c[1], c[2]
    h.setflags(write=False)
    self._cos_sin = (h, np.cos(h), np.sin(h))
    return self._cos_sin[1], self._cos_sin[2]


def no_keep(self, c, s):
    self.heading.setflags(write=False)
    return c, s


def undo_cos_sin(bw):
    for env in bw.envs:
        tr = env.core.world.traffic  # (a reset makes a new Traffic: the window below has none)
        tr.heading_cos_sin = types.MethodType(numpy_cos_sin, tr)
        tr.keep_cos_sin = types.MethodType(no_keep, tr)


def undo_policy_drivers(bw):
    for env in bw.envs:
        env.core._policy_drivers = types.MethodType(A.AgentsStep._policy_drivers, env.core)


def undo_rows(bw):
    for env in bw.envs:
        env.core._all_rows = lambda n: np.arange(n)


CASES = {"cos_sin": undo_cos_sin, "policy_drivers": undo_policy_drivers, "rows": undo_rows, "none": lambda bw: None}
case = sys.argv[1] if len(sys.argv) > 1 else "policy_drivers"
twins = [BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0) for _ in range(2)]
acts = np.zeros((16, twins[0].K, 2), np.float32)
for bw in twins:
    bw.reset()
for _ in range(150):
    for bw in twins:
        bw.step(acts)
CASES[case](twins[1])
t = [[], []]
for r in range(20):
    order = (0, 1) if r % 2 == 0 else (1, 0)
    for k in order:
        c0 = time.process_time()
        for _ in range(10):
            twins[k].step(acts)
        t[k].append((time.process_time() - c0) / (10 * 16) * 1e6)
same = all(np.array_equal(a.obs, b.obs) for a, b in [twins])
d = [b - a for a, b in zip(*t)]
print(f"{case}: this tree {statistics.median(t[0]):.1f} us, undone {statistics.median(t[1]):.1f} us per world-step; "
      f"median difference {statistics.median(d):.1f} us; same observations: {same}")
