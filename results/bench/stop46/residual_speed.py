"""Stop 46: agent-steps per CPU second of 16 HighwayFormation worlds of 20 agents on FormationResidual (the expert's
action plus a residual), seeded random residuals in [-0.2, 0.2], expert=False, 100 steps timed after 20 (the second
of two identical runs); prints the sum of the last observations (the same on two trees that simulate the same).
Run from outside the trees: PYTHONPATH=<tree> python residual_speed.py"""
import numpy as np, time, json
from icv_envs.vector import BatchedWorlds
for timed in (False, True):
    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None, "action": {"type": "FormationResidual"}}, seed=0)
    bw.reset()
    rng = np.random.default_rng(0)
    for _ in range(20): bw.step(rng.uniform(-0.2, 0.2, bw._act_shape))
    c0, n = time.process_time(), 0
    for _ in range(100):
        n += int(bw.mask.sum()); bw.step(rng.uniform(-0.2, 0.2, bw._act_shape))
    cpu = time.process_time() - c0
print(json.dumps({"agent_steps": n, "agent_steps_per_cpu_s": n / cpu, "obs": float(bw.obs.sum())}))
