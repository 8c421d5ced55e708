"""Do two source trees simulate the same thing, bit for bit, on this machine
(issue 10)? Each tree runs in a fresh process (``PYTHONPATH=<tree>``):

    git worktree add /tmp/ref <commit>
    python scripts/compare_trees.py /tmp/ref .

and the outputs are compared exactly (hashes of the raw bytes):

* ``fingerprints``: the nine trajectory fingerprints of
  ``tests/trajectory_hash.py`` (state, observations, rewards, the infos'
  expert actions), computed natively (NumPy's own SIMD dispatch on this
  machine, unlike the test, which pins it at AVX2) with the reference tree's
  ``trajectory_hash`` for both;
* ``highway metrics``: world statistics, motion moments and ``metrics()`` of
  five highway episodes (HighwayRamps formation VGR 1/3 for 200 s and
  lane-lp VGR 1/2 for 150 s, lane-drop, off-ramp, and 20 vehicles with half
  the actions random);
* ``intersection metrics``: ``metrics()`` of three 200 s intersection runs
  (multi-vp 2500 veh/h seed 4, single-vp 2000 seed 1, fcfs 3000 seed 2);
* ``batched``: every output of :class:`icv_envs.vector.BatchedWorlds` (3
  worlds) over 60-150 steps of random and expert actions on the three
  multi-agent envs, with and without the expert.

Prints one line per check and exits 1 if any differs.

``--pinned-reference`` runs the reference tree's processes with NumPy's
SIMD dispatch capped at AVX2 (``X86_V3``, as the fingerprint test pins it)
and the test tree's natively: ``compare_trees.py TREE TREE
--pinned-reference`` asks whether a tree's native runs on this machine are
its pinned ones (from stop 50).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

CHILD = r'''
import hashlib, json, sys
import numpy as np
ref_tests, check = sys.argv[1], sys.argv[2]

def h(obj):
    if isinstance(obj, np.ndarray):
        return hashlib.sha256(obj.dtype.str.encode() + str(obj.shape).encode() + obj.tobytes()).hexdigest()
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=repr).encode()).hexdigest()

out = {}
if check == "fingerprints":
    sys.path.insert(0, ref_tests)
    from trajectory_hash import CASES, fingerprint
    out = {name: fingerprint(module, config, seed, steps) for name, module, config, seed, steps in CASES}
elif check == "highway metrics":
    from icv_envs.envs import highway_formation_v0, highway_ramps_v0
    for name, mod, cfg, steps in [
            ("ramps", highway_ramps_v0, dict(vgr=1 / 3, duration=200.0, method="formation"), 1000),
            ("ramps-lp", highway_ramps_v0, dict(vgr=0.5, duration=150.0, method="lane-lp"), 750),
            ("lane-drop", highway_formation_v0, dict(scenario="lane-drop"), 300),
            ("off-ramp", highway_formation_v0, dict(scenario="off-ramp"), 300),
            ("random", highway_formation_v0, dict(vehicles_count=20), 200)]:
        env = mod.parallel_env(**cfg)
        env.reset(seed=2)
        rng = np.random.default_rng(0)
        for t in range(steps):
            if not env.agents and env.episode_over:
                break
            ex = env.expert_actions()
            env.step({a: (rng.uniform(-1, 1, 2) if name == "random" and t % 2 else ex[a]) for a in env.agents})
        w = env.core.world
        m = w.motion
        out[name] = h([w.stats, w.time, m.vehicle_steps, m.speed_sum, m.realised_abs_accel_sum,
                       m.commanded_abs_accel_sum, m.stopped_steps, [h(x) for x in (m._n, m._s1, m._s2)],
                       {k: v for k, v in env.metrics().items() if isinstance(v, (int, float))}])
elif check == "intersection metrics":
    from icv_envs.envs.intersection_v0 import parallel_env
    for method, tp, seed in [("multi-vp", 2500.0, 4), ("single-vp", 2000.0, 1), ("fcfs", 3000.0, 2)]:
        env = parallel_env(method=method, throughput=tp, duration=200.0)
        obs, infos = env.reset(seed=seed)
        while not env.episode_over:
            obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
        out[f"{method} {tp:g} veh/h seed {seed}"] = h(
            {k: v for k, v in env.metrics().items() if isinstance(v, (int, float))})
elif check == "batched":
    from icv_envs.vector import BatchedWorlds
    for env_name, cfg, steps in [("highway_formation", {"vehicles_count": 12, "duration": 8}, 60),
                                 ("highway_ramps", {"duration": 30}, 100),
                                 ("intersection", {"duration": 40, "throughput": 2500}, 150)]:
        for expert in (False, True):
            bw = BatchedWorlds(3, env=env_name, config=cfg, seed=1, expert=expert)
            rng = np.random.default_rng(0)
            o, m = bw.reset()
            digests = [h(o), h(m)]
            for t in range(steps):
                a = bw.expert_actions if expert and t % 2 else rng.uniform(-1, 1, (3, bw.K, 2)).astype(np.float32)
                r = bw.step(a)
                digests += [h(x) for x in r[:5]] + [h(r[5]["reset"]), h(r[5]["final_obs"])]
                if expert:
                    digests.append(h(r[5]["expert_actions"]))
            out[f"{env_name}, expert={expert}"] = h(digests)
print(json.dumps(out))
'''

CHECKS = ("fingerprints", "highway metrics", "intersection metrics", "batched")


def _pinned_env() -> dict:
    """This environment with NumPy's dispatch capped at ``X86_V3``, as the
    fingerprint test pins it (this checkout's
    ``tests/trajectory_hash.pinned_environment``); an error where the
    machine cannot run that level."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from trajectory_hash import pinned_environment

    env = pinned_environment()
    if env is None:
        raise SystemExit("--pinned-reference: this machine cannot run NumPy's X86_V3 (AVX2) level")
    return env


def _run(tree: Path, ref_tests: Path, check: str, base: dict | None = None) -> dict:
    env = dict(os.environ if base is None else base, PYTHONPATH=str(tree))
    res = subprocess.run([sys.executable, "-c", CHILD, str(ref_tests), check], cwd=tree, env=env, check=True,
                         capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("test")
    p.add_argument("--checks", default=",".join(CHECKS),
                   help=f"comma-separated subset of: {', '.join(CHECKS)} (default: all)")
    p.add_argument("--pinned-reference", action="store_true",
                   help="run the reference tree with NumPy capped at X86_V3 (AVX2), the test tree natively")
    a = p.parse_args(argv)
    checks = [c.strip() for c in a.checks.split(",") if c.strip()]
    bad = [c for c in checks if c not in CHECKS]
    if bad or not checks:
        raise SystemExit(f"--checks {a.checks!r}; allowed: a comma-separated subset of {list(CHECKS)}")
    ref, test = Path(a.reference).resolve(), Path(a.test).resolve()
    ref_tests = ref / "tests"
    if not (ref_tests / "trajectory_hash.py").exists():
        raise SystemExit(f"{ref} has no tests/trajectory_hash.py; pass a checkout of this repository")
    base = _pinned_env() if a.pinned_reference else None
    differs = 0
    for check in checks:
        r, t = _run(ref, ref_tests, check, base), _run(test, ref_tests, check)
        diff = sorted(k for k in r if r[k] != t.get(k)) + sorted(k for k in t if k not in r)
        differs += bool(diff)
        print(f"{check}: {len(r) - len(diff)} of {len(r)} identical" + (f"; DIFFER: {diff}" if diff else ""),
              flush=True)
    return 1 if differs else 0


if __name__ == "__main__":
    sys.exit(main())
