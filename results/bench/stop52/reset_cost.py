"""CPU time of one world's reset in BatchedWorlds (16 HighwayFormation
worlds of 20 agents, seed 0): 320 resets after 32 untimed ones.

    PYTHONPATH=<tree> python results/bench/stop52/reset_cost.py
"""
import time

from icv_envs.vector import BatchedWorlds

bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0)
bw.reset()
for _ in range(2):
    for b in range(16):
        bw._reset_world(b)
c0 = time.process_time()
for _ in range(20):
    for b in range(16):
        bw._reset_world(b)
print(f"reset {(time.process_time() - c0) / 320 * 1e6:.0f} us CPU per world")
