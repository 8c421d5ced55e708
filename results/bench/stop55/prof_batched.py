"""Stop 55: where 16 batched worlds of 20 agents spend a step (zero actions). PYTHONPATH=<tree> python prof_batched.py [cprofile|time]"""
import sys, time, numpy as np
from icv_envs.vector import BatchedWorlds
mode = sys.argv[1] if len(sys.argv) > 1 else "time"
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
bw.reset(); acts = np.zeros(bw._act_shape)
for _ in range(50): bw.step(acts)
t = time.process_time()
if mode == "cprofile":
    import cProfile, pstats
    pr = cProfile.Profile(); pr.enable()
    for _ in range(300): bw.step(acts)
    pr.disable(); pstats.Stats(pr).sort_stats("tottime").print_stats(50)
else:
    for _ in range(300): bw.step(acts)
dt = time.process_time() - t
print(f"{dt / 300 / 16 * 1e6:.1f} us per world-step, {300 * 16 * 20 / dt:,.0f} agent-steps per CPU s (20 agents assumed)")
