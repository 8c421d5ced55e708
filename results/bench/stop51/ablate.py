"""Which of stop 51's changes the batched learned world-step's gain comes
from (one process, blocks of 20 steps alternating in ABBA order between this tree's code
and the code with one change undone by a patch, 12 rounds; process CPU per
world-step, median over rounds). 16 HighwayFormation worlds x 20 agents,
zero actions."""
import time, statistics
import numpy as np
from icv_envs.vector import BatchedWorlds
import icv_envs.sim.traffic as T, icv_envs.envs.highway_formation as HF, icv_envs.envs.agents_step as A
import icv_envs.sim.world as W, icv_envs.sim.formations as FM

bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
bw.reset(); acts = np.zeros((16, bw.K, 2), np.float32)
for _ in range(150): bw.step(acts)

def numpy_cos_sin(self):
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

def masks_drivers(self, vids):
    A.AgentsStep._policy_drivers(self, vids)

orig = {"keep": T.Traffic.keep_cos_sin, "hcs": T.Traffic.heading_cos_sin, "pd": HF.HighwayFormationEnv._policy_drivers,
        "rows": A.AgentsStep._all_rows}
def fresh_rows(self, n):
    return np.arange(n)  # (not remembered: the reward's builder gathers the actions)
undo = {
    "cos/sin kept from the substeps (NumPy's computed instead)": lambda on: (
        setattr(T.Traffic, "keep_cos_sin", no_keep if on else orig["keep"]),
        setattr(T.Traffic, "heading_cos_sin", numpy_cos_sin if on else orig["hcs"])),
    "set_policy_driven (the masks instead)": lambda on: setattr(HF.HighwayFormationEnv, "_policy_drivers",
                                                                  masks_drivers if on else orig["pd"]),
    "rows remembered (the gather instead)": lambda on: setattr(A.AgentsStep, "_all_rows", fresh_rows if on else orig["rows"]),
}
def block(n=20):
    t0 = time.process_time()
    for _ in range(n): bw.step(acts)
    return (time.process_time() - t0) / (n * 16) * 1e6
for name, f in undo.items():
    base, und = [], []
    for r in range(12):  # (ABBA: the order alternates, so a drift within a round cancels)
        if r % 2:
            f(True); und.append(block()); f(False); base.append(block())
        else:
            base.append(block()); f(True); und.append(block()); f(False)
    b, u = statistics.median(base), statistics.median(und)
    print(f"{name:60s} this tree {b:6.1f} us, undone {u:6.1f} us, saves {u - b:5.1f} us "
          f"(per round: {', '.join(f'{y - x:.1f}' for x, y in zip(base, und))})")
