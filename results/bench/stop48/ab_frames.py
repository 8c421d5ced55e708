"""In-process A/B of whole intersection steps (stop 48): two twin envs
(same seed, the same states at every step, checked), one stepping with
this tree's frame kernel (``intersection_frames``: the box's collision
pairs with a bound and the rows' order kept from frame to frame, the PET
candidates merged), the other with the reference tree's kernels, loaded
from copies of its ``frames.py``, ``intersection.py`` and ``stats.py`` in a
package ``oldkern`` on ``sys.path`` (``--old DIR``, made by
``make_oldkern.sh REF``). Each step is timed on both, in alternating order.

    PYTHONPATH=<tree> python results/bench/stop48/ab_frames.py --old /tmp/oldk [METHOD THROUGHPUT SEED]"""
import sys, time
args = sys.argv[1:]
old_dir = args[args.index("--old") + 1]
args = [a for i, a in enumerate(args) if a != "--old" and (i == 0 or args[i - 1] != "--old")]
sys.path.insert(0, old_dir)
import oldkern.frames as oldf
import icv_envs.sim.intersection_world as iw
from icv_envs.envs.intersection_v0 import parallel_env

method, tp, seed = (args[0], float(args[1]), int(args[2])) if len(args) > 2 else ("multi-vp", 2200.0, 0)
new_k, old_k = iw.intersection_frames, oldf.intersection_frames
envs = []
for _ in range(2):
    env = parallel_env(method=method, throughput=tp, duration=400, expert_in_info=False)
    env.reset(seed=seed)
    envs.append(env)
kern = (new_k, old_k)
def step(k):
    iw.intersection_frames = kern[k]
    env = envs[k]
    env.step_rows(env.core.expert_actions())
for _ in range(500):  # 100 s, not timed
    step(0); step(1)
t = [0, 0]
n = agents = 0
while envs[0].core.world.time < 300 - 1e-9:
    agents += envs[0].num_agents
    for k in ((0, 1) if n % 2 else (1, 0)):
        c0 = time.perf_counter_ns()
        step(k)
        t[k] += time.perf_counter_ns() - c0
    fa, fb = envs[0].core.world.fleet, envs[1].core.world.fleet
    assert fa.vid.tobytes() == fb.vid.tobytes() and fa.x.tobytes() == fb.x.tobytes(), "the twins diverged"
    n += 1
iw.intersection_frames = new_k
ma, mb = envs[0].core.metrics(), envs[1].core.metrics() if hasattr(envs[0].core, "metrics") else (None, None)
print(f"{method} {tp:g} veh/h seed {seed}: {n} steps, {agents / n:.0f} agents; step with this tree's frames "
      f"{t[0] / n / 1e3:.0f} us, with the reference's {t[1] / n / 1e3:.0f} us, ratio {t[1] / t[0]:.3f}; "
      f"same metrics: {ma == mb}")
