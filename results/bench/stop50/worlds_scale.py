"""A batched learned world-step against the number of worlds in one batch (stop 50, a hint on
cache effects, one run each): 150 steps of warm-up, then about 1,600 world-steps timed (process CPU)."""
import numpy as np, time, sys
from icv_envs.vector import BatchedWorlds
for B in (1, 4, 16, 64):
    bw = BatchedWorlds(B, config={"vehicles_count": 20, "initial_position": None}, seed=0)
    bw.reset(); a = np.zeros((B, bw.K, 2), np.float32)
    for _ in range(150): bw.step(a)
    steps = max(1600 // B, 50)
    c0 = time.process_time(); n = 0
    for _ in range(steps):
        n += int(bw.mask.sum()); bw.step(a)
    el = time.process_time() - c0
    print(B, f"{el / (steps * B) * 1e6:.1f} us per world-step, {n / el:,.0f} agent-steps/s")
