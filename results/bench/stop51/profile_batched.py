"""cProfile of the batched learned world-step (stop 51): Python functions by
own time and calls per world-step. 16 HighwayFormation worlds x 20 agents,
zero actions (``--expert``: the expert's), 400 steps warm-up, 300 profiled."""
import cProfile, pstats, sys
import numpy as np
from icv_envs.vector import BatchedWorlds
expert = "--expert" in sys.argv
bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
bw.reset()
acts = np.zeros((16, bw.K, 2), dtype=np.float32)
for _ in range(400):
    bw.step(bw.expert_actions if expert else acts)
N = 300
pr = cProfile.Profile()
pr.enable()
for _ in range(N):
    bw.step(bw.expert_actions if expert else acts)
pr.disable()
ws = N * 16
st = pstats.Stats(pr)
rows = []
for (f, l, fn), (cc, nc, tt, ct, callers) in st.stats.items():
    rows.append((tt, nc, ct, f"{f.split('/')[-1]}:{l}:{fn}"))
tot_calls = sum(r[1] for r in rows)
tot_t = sum(r[0] for r in rows)
print(f"{tot_calls / ws:.1f} calls per world-step, {tot_t / ws * 1e6:.1f} us own time (profiled)")
for tt, nc, ct, name in sorted(rows, reverse=True)[:60]:
    print(f"{tt / ws * 1e6:7.2f} us {nc / ws:6.2f} calls  cum {ct / ws * 1e6:7.2f}  {name}")
