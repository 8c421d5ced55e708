"""Process-CPU microseconds per agent-step of the PettingZoo step (issue 10, item 1).

    PYTHONPATH=$PWD python scripts/bench_step_cost.py formation 800 60   # HighwayFormation, 800 agents, 60 steps
    PYTHONPATH=$PWD python scripts/bench_step_cost.py ramps 2500 60      # HighwayRamps after 2500 warm-up steps

Run it with two source trees (PYTHONPATH=<tree>) alternately to compare them.
"""
import sys, time, math, gc
which, n, steps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
from icv_envs.envs import highway_formation_v0, highway_ramps_v0
if which == "ramps":
    env = highway_ramps_v0.parallel_env(vgr=1/3, duration=600.0); env.reset(seed=0); warm = n
else:
    span = math.ceil(n / 12) * (6 * 20.0 + 60.0) + 100.0
    env = highway_formation_v0.parallel_env(vehicles_count=n, formation_size=12, initial_position=None,
        road_length=float(span + 30*60 + 300), duration=60.0); env.reset(seed=0); warm = 3
for _ in range(warm):
    ex = env.expert_actions(); env.step({a: ex[a] for a in env.agents})
tot = 0.0; vs = 0
for _ in range(steps):
    ex = env.expert_actions(); acts = {a: ex[a] for a in env.agents}; vs += len(acts)
    t = time.process_time(); env.step(acts); tot += time.process_time() - t
print(f"{which} {n}: {vs/steps:.0f} agents, {tot/vs*1e6:.1f} us/agent-step (process time)")
