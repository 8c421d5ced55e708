"""Stop 51's changes one by one: each piece of a batched learned world-step
in its stop-50 form and in this stop's, timed side by side on the same live
world (timeit, best of 7 repeats of 2,000 calls; a 20-vehicle
HighwayFormation world of a 16-world batch after 150 steps of zero
actions). The stop-50 forms are written out here as that code had them.
This is the cost of each piece alone, warm; the step's paired bench
(scripts/bench_trees.py) is the measurement of the whole."""
import timeit
import numpy as np
from icv_envs.vector import BatchedWorlds
from icv_envs.sim.world import JAM_STOP_TIME
from icv_envs._ufuncs import count_nonzero

bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
bw.reset(); a = np.zeros((16, bw.K, 2), np.float32)
for _ in range(150):
    bw.step(a)
core = bw.envs[3].core; w = core.world; tr = w.traffic; m = w.manager
n = tr.n
rows_kept = core._all_rows(n)
crashed = tr.crashed.copy()
la = core._last_actions
pairs = {
    "who drives (learned actions)": (
        "em = np.zeros(len(tr.vid), dtype=bool); w.set_expert_driven(tr.vid, em, em)",
        "w.set_policy_driven()"),
    "the headings' cos and sin": (
        "h = tr.heading; (np.cos(h), np.sin(h))",
        "tr._cos_sin = None; tr.keep_cos_sin(S[10], S[11])"),
    "the last actions for the reward's builder": (
        "np.ascontiguousarray(la[np.arange(n)], dtype=np.float64)",
        "r = core._all_rows(n); np.ascontiguousarray(la if r is core._all_rows_kept else la[r], dtype=np.float64)"),
    "formations left without members": (
        "g = m._gids(); g[m._cnt[g] == 0].tolist()",
        "g = m._gids(); c = m._cnt[g]; count_nonzero(c) != len(c)"),
    "the jam watch's test": (
        "count_nonzero(tr.stopped_for > JAM_STOP_TIME)",
        "ls = w._long_stops; ls is not None and ls[0] is tr.stopped_for and not ls[1]"),
    "count_nonzero (one call)": ("np.count_nonzero(crashed)", "count_nonzero(crashed)"),
    "the live agents after a step": (
        "t = np.zeros(n, bool); ~(t | t); tr.vid[~(t | t)]",
        "t = np.zeros(n, bool); count_nonzero(t) or count_nonzero(t); tr.vid.copy()"),
    "the ids before the physics (twice a step) and their comparison": (
        "b = tr.vid.copy(); v = tr.vid.copy(); same(tr.vid, v); same(tr.vid, b)",
        "b = tr.vid; v = tr.vid; same(tr.vid, v); same(tr.vid, b)"),
    "departures and late spawns (nothing left or due)": (
        "old_departed(ev); old_spawn_due(core)",
        "core._departed(ev); core._spawn_due()"),
}
def old_departed(events):  # (stop 50's HighwayFormationEnv._departed)
    return {vid: {"exited": vid in events.exited, "left_road": vid in events.left_road, "crashed": False}
            for vid in events.exited | events.left_road}


def old_spawn_due(self):  # (stop 50's HighwayFormationEnv._spawn_due, nothing due)
    w = self.world
    c = self.config
    new = []
    while self._pending_spawns and float(self._pending_spawns[0]["time"]) <= w.time + 1e-9:
        pass
    if new:
        w.invalidate()
    return new


from icv_envs.envs.dict_edge import same_ids as same
from icv_envs.sim.world import StepEvents
ev = StepEvents()
S = np.vstack([np.zeros((10, n)), np.cos(tr.heading), np.sin(tr.heading)])
g = dict(globals())
tot_old = tot_new = 0.0
print(f"{'piece':62s} {'stop 50':>8s} {'stop 51':>8s}  (us per world-step)")
for name, (old, new) in pairs.items():
    t_old = min(timeit.repeat(old, globals=g, number=2000, repeat=7)) / 2000 * 1e6
    t_new = min(timeit.repeat(new, globals=g, number=2000, repeat=7)) / 2000 * 1e6
    tot_old += t_old; tot_new += t_new
    print(f"{name:62s} {t_old:8.2f} {t_new:8.2f}")
print(f"{'in all':62s} {tot_old:8.2f} {tot_new:8.2f}  (saved {tot_old - tot_new:.1f} us)")
