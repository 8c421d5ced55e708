import json, sys, time, numpy as np
from icv_envs.vector import BatchedWorlds
B, n, seed = 8, 30, 7
bw = BatchedWorlds(B, config={"vehicles_count": n, "initial_position": None}, seed=seed, expert=False)
bw.reset(); acts = np.zeros((B, bw.K, 2), dtype=np.float32)
for _ in range(3): bw.step(acts)
c0, m = time.process_time(), 0
for _ in range(150):
    m += int(bw.mask.sum()); bw.step(acts)
print(json.dumps({"agent_steps_per_cpu_s": m / (time.process_time() - c0)}))
