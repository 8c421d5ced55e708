"""Two of stop 51's pieces timed inside the batched learned step of stop 50's tree (perf_counter around
each call; 16 x 20, zero actions, 150 steps of warm-up, 100 timed): NumPy's cos/sin of the headings and
World.set_expert_driven. Run with PYTHONPATH=<stop 50 tree>."""
import time, numpy as np
from icv_envs.vector import BatchedWorlds
import icv_envs.sim.traffic as T, icv_envs.sim.world as W
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
bw.reset(); a = np.zeros((16, bw.K, 2), np.float32)
for _ in range(150): bw.step(a)
acc = {"cs": [0, 0], "sed": [0, 0]}
def hcs(self):
    c = self._cos_sin
    h = self.heading
    if c is not None and c[0] is h:
        return c[1], c[2]
    t0 = time.perf_counter_ns()
    h.setflags(write=False)
    self._cos_sin = (h, np.cos(h), np.sin(h))
    acc["cs"][0] += time.perf_counter_ns() - t0; acc["cs"][1] += 1
    return self._cos_sin[1], self._cos_sin[2]
if not hasattr(T.Traffic, "keep_cos_sin"):
    T.Traffic.heading_cos_sin = hcs
orig = W.World.set_expert_driven
def sed(self, *a, **k):
    t0 = time.perf_counter_ns(); r = orig(self, *a, **k); acc["sed"][0] += time.perf_counter_ns() - t0; acc["sed"][1] += 1
    return r
W.World.set_expert_driven = sed
N = 100
c0 = time.process_time()
for _ in range(N): bw.step(a)
el = time.process_time() - c0
print(f"{el / (N*16) * 1e6:.1f} us per world-step")
for k, (t, n) in acc.items():
    if n: print(k, f"{t / n / 1e3:.2f} us per call, {n / (N*16):.2f} calls per world-step")
