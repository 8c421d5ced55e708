"""Trajectory fingerprints for the bit-identity test (tests/test_trajectory_hash.py).

A fingerprint is the SHA-256 of every policy step's full simulation state
(every float / int / bool array of :class:`icv_envs.sim.traffic.Traffic` plus
the formation manager's anchors), observations, rewards, terminations and the infos' expert actions and reward
components, in
agent order, over a short expert-driven PettingZoo episode. Any change in any
bit of any of them changes the hash.

Re-record (only when a change of trajectories is intended and explained)::

    PYTHONPATH=$PWD python tests/trajectory_hash.py --record

NumPy picks its SIMD kernels (sin, cos, exp, power, ...) at import time by
the CPU, and the AVX-512 kernels (dispatch level ``X86_V4`` and above) may
round the last bit differently from the AVX2 ones (``X86_V3``): the same
seed gives the same trajectory bit for bit on one kind of CPU, not across
kinds. The fingerprints are therefore computed, and recorded, in a
subprocess whose NumPy dispatch is capped at ``X86_V3``
(``NPY_DISABLE_CPU_FEATURES`` names every higher target the machine has),
so they are the same on every x86-64 machine with AVX2 (seen: an AVX2-only
machine and an AVX-512 one give the same hashes this way, and different
ones without the cap).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

REFERENCE = Path(__file__).parent / "data" / "trajectory_hashes.json"

# (name, module, config, seed, policy steps)
CASES = [
    ("formation-free-40", "highway_formation_v0", {"vehicles_count": 40, "initial_position": None}, 0, 60),
    ("formation-lane-drop", "highway_formation_v0", {"scenario": "lane-drop"}, 1, 80),
    ("formation-lane-change", "highway_formation_v0", {"scenario": "lane-change"}, 2, 80),
    ("formation-off-ramp", "highway_formation_v0", {"scenario": "off-ramp"}, 3, 80),
    ("formation-on-ramp", "highway_formation_v0", {"scenario": "on-ramp"}, 4, 80),
    ("ramps-formation", "highway_ramps_v0", {"vgr": 1.0, "duration": 60.0}, 0, 300),
    ("ramps-idm", "highway_ramps_v0", {"vgr": 0.5, "duration": 30.0, "method": "idm"}, 5, 150),
    ("intersection-multi-vp", "intersection_v0", {}, 0, 100),
    ("intersection-fcfs", "intersection_v0", {"method": "fcfs"}, 6, 100),
]


def _traffic_arrays(core):
    tr = core.world.traffic
    # public state only: private arrays are caches of it (the intersection fleet's id -> row table)
    names = sorted(k for k, v in vars(tr).items() if isinstance(v, np.ndarray) and not k.startswith("_"))
    return [(k, getattr(tr, k)) for k in names]


def fingerprint(module: str, config: dict, seed: int, steps: int) -> str:
    import importlib

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    env = mod.parallel_env(**config)
    h = hashlib.sha256()

    def feed(obs, infos, rew=None, term=None, trunc=None):
        for a in sorted(obs):
            h.update(a.encode())
            h.update(np.ascontiguousarray(obs[a], dtype=np.float32).tobytes())
            info = infos.get(a, {})
            if "expert_action" in info:
                h.update(np.ascontiguousarray(info["expert_action"], dtype=np.float32).tobytes())
            for k, v in sorted(info.get("rewards", {}).items()):
                h.update(k.encode() + np.float64(v).tobytes())
            if rew is not None:
                h.update(np.float64(rew[a]).tobytes())
                h.update(bytes([bool(term[a]), bool(trunc[a])]))
        for k, v in _traffic_arrays(env.core):
            h.update(k.encode())
            h.update(np.ascontiguousarray(v).tobytes())
        man = getattr(env.core.world, "manager", None)
        if man is not None and hasattr(man, "anchor"):
            for g in sorted(man.anchor):
                h.update(np.array([g, man.anchor[g]], dtype=np.float64).tobytes())

    obs, infos = env.reset(seed=seed)
    feed(obs, infos)
    for _ in range(steps):
        if env.episode_over:
            break
        ex = env.expert_actions()
        obs, rew, term, trunc, infos = env.step({a: ex[a] for a in env.agents})
        feed(obs, infos, rew, term, trunc)
    env.close()
    return h.hexdigest()


def all_fingerprints(names=None) -> dict:
    return {name: fingerprint(m, c, s, n) for name, m, c, s, n in CASES if names is None or name in names}


PINNED_LEVEL = "X86_V3"  # NumPy's AVX2 dispatch level: the fingerprints' reference CPU


def _active_targets_above() -> list[str]:
    """NumPy dispatch targets above :data:`PINNED_LEVEL` that are active in this process."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    order = list(__cpu_dispatch__)
    above = order[order.index(PINNED_LEVEL) + 1:] if PINNED_LEVEL in order else []
    return [f for f in above if __cpu_features__.get(f, False)]


def pinned_environment() -> dict | None:
    """Environment variables that cap NumPy's SIMD dispatch at
    :data:`PINNED_LEVEL` in a new process, or ``None`` where the machine
    cannot run that level (not x86-64, or no AVX2)."""
    from numpy._core._multiarray_umath import __cpu_features__

    if not __cpu_features__.get(PINNED_LEVEL, False):
        return None
    env = dict(os.environ)
    env.pop("NPY_ENABLE_CPU_FEATURES", None)
    env["NPY_DISABLE_CPU_FEATURES"] = " ".join(_active_targets_above())
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parents[1]), env.get("PYTHONPATH", "")])
    return env


def pinned_fingerprints(names=None) -> dict:
    """:func:`all_fingerprints` computed in a subprocess with NumPy's
    dispatch capped at :data:`PINNED_LEVEL` (module docstring)."""
    env = pinned_environment()
    if env is None:
        raise RuntimeError(f"this machine has no {PINNED_LEVEL} (AVX2) SIMD level; the fingerprints need it")
    args = [sys.executable, str(Path(__file__).resolve()), "--in-process"] + list(names or [])
    out = subprocess.run(args, env=env, capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"fingerprint subprocess failed ({out.returncode}):\n{out.stderr[-4000:]}")
    return json.loads(out.stdout)


if __name__ == "__main__":
    if "--in-process" in sys.argv:
        if _active_targets_above():
            sys.exit(f"NumPy's dispatch is not capped at {PINNED_LEVEL}; run through pinned_fingerprints()")
        names = [a for a in sys.argv[1:] if not a.startswith("--")] or None
        print(json.dumps(all_fingerprints(names)))
    elif "--record" in sys.argv:
        REFERENCE.parent.mkdir(exist_ok=True)
        REFERENCE.write_text(json.dumps(pinned_fingerprints(), indent=1) + "\n")
        print(REFERENCE.read_text())
    else:
        print(json.dumps(pinned_fingerprints(), indent=1))
