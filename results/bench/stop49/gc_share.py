"""Share of garbage collection in a step (stop 49): gc callbacks time each
collection by generation over a window of the batched (learned / --expert),
intersection rows or ring case."""
import gc, sys, time, collections
import numpy as np
case = sys.argv[1] if len(sys.argv) > 1 else "batched"
if case.startswith("batched"):
    from icv_envs.vector import BatchedWorlds
    expert = case == "batched-expert"
    bw = BatchedWorlds(16, config={"vehicles_count": 20, "initial_position": None}, seed=0, expert=expert)
    bw.reset()
    acts = np.zeros((16, bw.K, 2), dtype=np.float32)
    def one():
        bw.step(bw.expert_actions if expert else acts)
    warm, N = 100, 300
elif case == "intersection-rows":
    from icv_envs.envs.intersection_v0 import parallel_env
    env = parallel_env(method="multi-vp", throughput=2200.0, duration=560, expert_in_info=False)
    env.reset(seed=0)
    def one():
        env.step_rows(env.core.expert_actions())
    warm, N = 500, 1000
else:
    from icv_envs.envs.highway_ramps_v0 import parallel_env
    env = parallel_env(vgr=1.0 / 3.0, duration=600.0, method="formation")
    env.reset(seed=0)
    def one():
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    warm, N = 1500, 300
for _ in range(warm):
    one()
acc = collections.Counter(); cnt = collections.Counter(); t0 = [0.0]
def cb(phase, info):
    if phase == "start":
        t0[0] = time.perf_counter()
    else:
        acc[info["generation"]] += time.perf_counter() - t0[0]; cnt[info["generation"]] += 1
gc.callbacks.append(cb)
print("gc counts/threshold", gc.get_count(), gc.get_threshold(), "objects tracked", len(gc.get_objects()))
c0 = time.perf_counter()
for _ in range(N):
    one()
el = time.perf_counter() - c0
gc.callbacks.remove(cb)
tot = sum(acc.values())
print(f"{case}: {el / N * 1e6:.1f} us per step; gc {tot / el * 100:.2f}% ({dict(cnt)} collections; "
      + ", ".join(f"gen{g} {acc[g] / max(cnt[g], 1) * 1e6:.0f} us each" for g in sorted(acc)) + ")")
