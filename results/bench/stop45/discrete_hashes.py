"""Bit-identity of DiscreteMetaAction runs between two trees (stop 45: the
meta-action layer's unchecked law calls, its id lookups and the batched
integer check): each case runs a PettingZoo env with seeded random meta
actions (and one with every agent IDLE) and hashes every step's
observations, rewards, terminations, truncations and the world's vehicle
arrays, then a BatchedWorlds run. Run from outside the trees:

    PYTHONPATH=<tree> python discrete_hashes.py

and compare the printed JSON lines."""
import hashlib, importlib, json
import numpy as np

CASES = [
    ("lane-drop-s3", "highway_formation_v0", {"scenario": "lane-drop"}, 3, 150, "random"),
    ("free-30-s4", "highway_formation_v0", {"vehicles_count": 30, "initial_position": None}, 4, 150, "random"),
    ("on-ramp-s5-idle", "highway_formation_v0", {"scenario": "on-ramp"}, 5, 150, "idle"),
    ("ramps-vgr05-s6", "highway_ramps_v0", {"vgr": 0.5, "duration": 40.0}, 6, 200, "random"),
    ("intersection-2500-s7", "intersection_v0", {"throughput": 2500.0, "duration": 60.0}, 7, 300, "random"),
]


def run(mod, cfg, seed, steps, kind):
    env = importlib.import_module(f"icv_envs.envs.{mod}").parallel_env(action={"type": "DiscreteMetaAction"}, **cfg)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    for _ in range(steps):
        if env.episode_over:
            break
        acts = {a: (int(rng.integers(5)) if kind == "random" else 1) for a in env.agents}
        obs, rew, term, trunc, _ = env.step(acts)
        for a in sorted(obs):
            h.update(a.encode()); h.update(np.ascontiguousarray(obs[a]).tobytes())
            h.update(np.float64(rew[a]).tobytes()); h.update(bytes([term[a], trunc[a]]))
        veh = env.core._vehicles()
        for arr in (veh.vid, env.core.world.traffic.x if hasattr(env.core.world, "traffic") else env.core.world.fleet.x):
            h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()[:16]


out = {name: run(mod, cfg, seed, steps, kind) for name, mod, cfg, seed, steps, kind in CASES}
from icv_envs.vector import BatchedWorlds
bw = BatchedWorlds(3, config={"vehicles_count": 12, "initial_position": None, "duration": 10.0,
                              "action": {"type": "DiscreteMetaAction"}}, seed=9)
bw.reset()
bw.action_space.seed(9)
h = hashlib.sha256()
try:  # (before stop 45 the batch refused every discrete action: its action space was a Box)
    for _ in range(80):
        o, r, te, tr, m, info = bw.step(bw.action_space.sample())
        for x in (o, r, te, tr, m):
            h.update(np.ascontiguousarray(x).tobytes())
    out["batched-discrete"] = h.hexdigest()[:16]
except ValueError as exc:
    out["batched-discrete"] = f"error: {str(exc)[:60]}"
print(json.dumps(out))
