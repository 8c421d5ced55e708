"""Step cost of two source trees, alternately, in one run (issue 10).

    git worktree add /tmp/ref <commit>
    python scripts/bench_trees.py /tmp/ref . [--case intersection] [--reps 6] [--steps N] [--out FILE]

Each repetition runs the reference tree, then the tree under test, each in a
fresh process (``PYTHONPATH=<tree>``), and times ``--steps`` policy steps
(process CPU time) of one case:

* ``intersection`` (default ``--steps 1200``): multi-vp at ``--throughput``
  veh/h (2200), the zones filled to 60 vehicles first; every vehicle an
  agent, the expert's action from the infos (as ``icv-envs bench
  intersection``); agent-steps per CPU s;
* ``intersection-rows`` (from stop 47; default ``--steps 1200``): the same
  through the array path (``step_rows`` with the core's
  ``expert_actions()``, ``expert_in_info=False``: as ``icv-envs bench
  intersection --api rows``);
* ``ring`` (default ``--steps 500``, 100 s): HighwayRamps at VGR 1/3 under
  the formation expert through the PettingZoo API, after 500 s of warm-up
  (the steady state of ``icv-envs bench highway-ramps --vs-sumo``);
  vehicle-steps (one vehicle, one physics step) per CPU s;
* ``batched`` / ``batched-expert`` (default ``--steps 100``):
  :class:`icv_envs.vector.BatchedWorlds`, 16 HighwayFormation worlds of 20
  agents (``--worlds``, ``--vehicles``, ``--seed``: another setting, from
  stop 50), zero actions / the expert's action for every agent (as the batched
  part of ``icv-envs bench train``) / ``batched-noisy`` (from stop 52): a
  stochastic policy's actions, N(0, 0.3) clipped to [-1, 1], drawn from
  ``--seed`` before the run (the steering then often meets the lateral
  acceleration limit, where zero actions never do; a policy part-way
  through training: SB3's PPO starts at a standard deviation of 1) /
  ``batched-uniform`` (from stop 53): uniform in [-1, 1], an untrained
  policy (``icv-envs bench train``'s ``uniform`` actions);
  agent-steps per CPU s of the second
  of two identical runs (the first loads the kernels from numba's cache:
  before stop 38 the only run was timed, and the load at the first
  collision, step 102 of 103, fell inside it).

Prints each pair's ratio (test / reference) and their median; a shared
machine moves single figures by 20% or more, the pairs' median much less.
The pairs run the reference first and the test first in turn (from stop
52; the reference always ran first before, and on this machine the first
run of a pair was 3-4% faster on the intersection case, whichever tree it
was): use an even ``--reps``.
Both trees must simulate the same amount (the step counts are checked).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

CHILD = """
import json, sys, time
from icv_envs.envs.intersection_v0 import parallel_env
steps, tp = int(sys.argv[1]), float(sys.argv[2])
env = parallel_env(method="multi-vp", throughput=tp, duration=300.0 + steps / 5.0 + 10.0)
obs, infos = env.reset(seed=0)
while len(env.agents) < 60 and env.core.world.time < 300:
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
c0, n = time.process_time(), 0
for _ in range(steps):
    n += len(env.agents)
    obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
print(json.dumps({"cpu": time.process_time() - c0, "agent_steps": n}))
"""


CHILD_ROWS = """
import json, sys, time
from icv_envs.envs.intersection_v0 import parallel_env
steps, tp = int(sys.argv[1]), float(sys.argv[2])
env = parallel_env(method="multi-vp", throughput=tp, duration=300.0 + steps / 5.0 + 10.0, expert_in_info=False)
env.reset(seed=0)
core = env.core
while len(env.agents) < 60 and core.world.time < 300:
    env.step_rows(core.expert_actions())
c0, n = time.process_time(), 0
for _ in range(steps):
    n += env.num_agents
    env.step_rows(core.expert_actions())
print(json.dumps({"cpu": time.process_time() - c0, "agent_steps": n}))
"""

RING = """
import json, sys, time
from icv_envs.envs.highway_ramps_v0 import parallel_env
steps = int(sys.argv[1])
env = parallel_env(vgr=1.0 / 3.0, duration=600.0, method="formation")
env.reset(seed=0)
for _ in range(2500):
    ex = env.expert_actions()
    env.step({a: ex[a] for a in env.agents})
w = env.core.world
v0, c0 = w.motion.vehicle_steps, time.process_time()
for _ in range(steps):
    ex = env.expert_actions()
    env.step({a: ex[a] for a in env.agents})
print(json.dumps({"cpu": time.process_time() - c0, "agent_steps": w.motion.vehicle_steps - v0}))
"""

BATCHED = """
import json, sys, time
import numpy as np
from icv_envs.vector import BatchedWorlds
steps, expert, kind = int(sys.argv[1]), sys.argv[2] == "1", sys.argv[2]
noisy = kind in ("noisy", "uniform")
B, N, seed = (int(x) for x in sys.argv[3:6])
# the same run twice, the second timed: the first loads every kernel the run
# reaches from numba's cache (at the first step, and at the first collision)
for timed in (False, True):
    bw = BatchedWorlds(B, config={"vehicles_count": N, "initial_position": None}, seed=seed, expert=expert)
    bw.reset()
    acts = np.zeros((B, bw.K, 2), dtype=np.float32)
    rng = np.random.default_rng(seed)
    draw = (lambda: rng.uniform(-1.0, 1.0, acts.shape)) if kind == "uniform" else (lambda: np.clip(rng.normal(0.0, 0.3, acts.shape), -1.0, 1.0))
    noise = [draw().astype(np.float32) for _ in range(steps)] if noisy else None
    for _ in range(3):
        bw.step(bw.expert_actions if expert else acts)
    c0, n = time.process_time(), 0
    for k in range(steps):
        if expert:
            acts = bw.expert_actions
        elif noisy:
            acts = noise[k]
        n += int(bw.mask.sum())
        bw.step(acts)
    cpu = time.process_time() - c0
print(json.dumps({"cpu": cpu, "agent_steps": n}))
"""

# case -> (child code, default steps, unit, the child's arguments after the step count; ``{tp}``: --throughput)
CASES = {
    "intersection": (CHILD, 1200, "agent-steps", ("{tp}",)),
    "intersection-rows": (CHILD_ROWS, 1200, "agent-steps", ("{tp}",)),
    "ring": (RING, 500, "vehicle-steps", ()),
    "batched": (BATCHED, 100, "agent-steps", ("0", "{worlds}", "{vehicles}", "{seed}")),
    "batched-expert": (BATCHED, 100, "agent-steps", ("1", "{worlds}", "{vehicles}", "{seed}")),
    "batched-noisy": (BATCHED, 100, "agent-steps", ("noisy", "{worlds}", "{vehicles}", "{seed}")),
    "batched-uniform": (BATCHED, 100, "agent-steps", ("uniform", "{worlds}", "{vehicles}", "{seed}")),
}


def _run(tree: Path, steps: int, tp: float, case: str = "intersection", worlds: int = 16, vehicles: int = 20,
         seed: int = 0) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    code, _, _, args = CASES[case]
    extra = [a.format(tp=tp, worlds=worlds, vehicles=vehicles, seed=seed) for a in args]
    out = subprocess.run([sys.executable, "-c", code, str(steps)] + extra, cwd=tree, env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("test")
    p.add_argument("--case", choices=sorted(CASES), default="intersection")
    p.add_argument("--reps", type=int, default=6)
    p.add_argument("--steps", type=int, default=None, help="policy steps timed (default: per case, see above)")
    p.add_argument("--throughput", type=float, default=2200.0, help="intersection case only (veh/h)")
    p.add_argument("--worlds", type=int, default=16, help="batched cases only: worlds")
    p.add_argument("--vehicles", type=int, default=20, help="batched cases only: agents per world")
    p.add_argument("--seed", type=int, default=0, help="batched cases only: the batch's seed")
    p.add_argument("--out", default=None, help="also write the JSON line to this file")
    a = p.parse_args(argv)
    if a.reps < 1:
        raise SystemExit(f"--reps {a.reps}; allowed: an integer >= 1")
    for name in ("worlds", "vehicles"):
        if getattr(a, name) < 1:
            raise SystemExit(f"--{name} {getattr(a, name)}; allowed: an integer >= 1")
    if a.seed < 0:
        raise SystemExit(f"--seed {a.seed}; allowed: an integer >= 0")
    if not a.case.startswith("batched") and (a.worlds, a.vehicles, a.seed) != (16, 20, 0):
        raise SystemExit(f"--worlds, --vehicles and --seed apply to the batched cases only, not --case {a.case}")
    steps = CASES[a.case][1] if a.steps is None else a.steps
    if steps < 1:
        raise SystemExit(f"--steps {steps}; allowed: an integer >= 1")
    unit = CASES[a.case][2]
    ref, test = Path(a.reference).resolve(), Path(a.test).resolve()
    ratios, rows = [], []
    for i in range(a.reps):
        kw = {"worlds": a.worlds, "vehicles": a.vehicles, "seed": a.seed}
        # (the two trees' order alternates from pair to pair, from stop 52: the
        # first run of a pair was measured 3-4% faster than the second on the
        # intersection case, whichever tree it was)
        first = "reference" if i % 2 == 0 else "test"
        order = (("reference", ref), ("test", test)) if first == "reference" else (("test", test), ("reference", ref))
        got = {name: _run(tree, steps, a.throughput, a.case, **kw) for name, tree in order}
        r, t = got["reference"], got["test"]
        if r["agent_steps"] != t["agent_steps"]:
            raise SystemExit(f"the trees simulate different amounts ({r['agent_steps']} vs {t['agent_steps']} "
                             f"{unit}): not a like-for-like comparison")
        sr, st = r["agent_steps"] / r["cpu"], t["agent_steps"] / t["cpu"]
        ratios.append(st / sr)
        rows.append({"reference": sr, "test": st, "ratio": st / sr, "first": first})
        print(f"rep {i + 1}: reference {sr:,.0f}, test {st:,.0f} {unit} per CPU s, ratio {st / sr:.2f} "
              f"({first} first)", flush=True)
    res = {"case": a.case, "unit": f"{unit} per CPU s", "median_ratio": statistics.median(ratios), "pairs": rows,
           "steps": steps, "amount": r["agent_steps"], "reference": str(ref), "test": str(test)}
    if a.case.startswith("intersection"):
        res["throughput"] = a.throughput
    if a.case.startswith("batched"):
        res.update(worlds=a.worlds, vehicles=a.vehicles, seed=a.seed)
    print(f"median ratio test / reference over {a.reps} pairs: {res['median_ratio']:.2f}")
    line = json.dumps(res)
    print(line)
    if a.out:
        Path(a.out).write_text(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
