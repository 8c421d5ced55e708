"""In-process A/B of whole ring steps (stop 48): two twin HighwayRamps envs
(VGR 1/3, the formation expert driving every agent through ``step_rows``;
same seed, the same states at every step, checked), one stepping with this
tree's ``quiet_substeps`` (the collision sweep's order along x kept from
frame to frame), the other with the reference tree's, loaded from copies
of its ``frames.py`` and ``neighbours.py`` in a package ``oldkern`` on
``sys.path`` (``--old DIR``, made by ``make_oldkern.sh REF DIR``). Each
step is timed on both, in alternating order, after ``--warmup`` s.

    PYTHONPATH=<tree> python results/bench/stop48/ab_ring.py --old DIR [SEED] [--warmup 300] [--steps 500]"""
import argparse, sys, time
ap = argparse.ArgumentParser()
ap.add_argument("seed", nargs="?", type=int, default=0)
ap.add_argument("--old", required=True)
ap.add_argument("--warmup", type=float, default=300.0)
ap.add_argument("--steps", type=int, default=500)
a = ap.parse_args()
sys.path.insert(0, a.old)
import oldkern.frames as oldf
import icv_envs.sim.world as wmod
from icv_envs.envs import highway_ramps_v0

new_k, old_k = wmod.quiet_substeps, oldf.quiet_substeps
envs = []
for _ in range(2):
    env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=a.warmup + a.steps / 5.0 + 10.0, expert_in_info=False)
    env.reset(seed=a.seed)
    envs.append(env)
kern = (new_k, old_k)
def step(k):
    wmod.quiet_substeps = kern[k]
    env = envs[k]
    env.step_rows(env.core.expert_actions())
while envs[0].core.world.time < a.warmup - 1e-9:
    step(0); step(1)
t = [0, 0]
n = veh = 0
for n in range(a.steps):
    veh += envs[0].core.world.traffic.n
    for k in ((0, 1) if n % 2 else (1, 0)):
        c0 = time.perf_counter_ns()
        step(k)
        t[k] += time.perf_counter_ns() - c0
    ta, tb = envs[0].core.world.traffic, envs[1].core.world.traffic
    assert ta.vid.tobytes() == tb.vid.tobytes() and ta.x.tobytes() == tb.x.tobytes(), "the twins diverged"
wmod.quiet_substeps = new_k
n = a.steps
print(f"ring seed {a.seed}: {n} steps after {a.warmup:g} s, {veh / n:.0f} vehicles; step with this tree's frames "
      f"{t[0] / n / 1e3:.0f} us, with the reference's {t[1] / n / 1e3:.0f} us, ratio {t[1] / t[0]:.3f}; "
      f"same world statistics: {envs[0].core.world.stats == envs[1].core.world.stats}")
