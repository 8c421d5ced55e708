"""Bit-identity on seeds and settings that ``scripts/compare_trees.py`` and
the fingerprints do not use (issue 10): seven highway runs (the ring at VGR
1/3 and 1/2, lane drop, off-ramp, on-ramp, 60 free vehicles, lane change)
and three intersection runs (multi-vp, single-vp, fcfs at other demands and
seeds), expert-driven or with a share of random actions (collisions), each
hashed over every step's observations, rewards, terminations, expert labels
and simulation state, and its run metrics. Run it in both trees and compare the
JSON lines:

    PYTHONPATH=<tree> python scripts/new_seed_hashes.py <tree>

(prints ``{case: [hash prefix, crashes]}``; run from outside the trees'
directories, or the working directory's checkout is imported first).
``--without-observations`` (a second argument) leaves the observations out
of the hashes: a change meant to move only the observations (stop 40: the
order of exactly tied neighbours at the intersection) must leave these
hashes as they were."""
import hashlib, json, sys, importlib
import numpy as np
sys.path.insert(0, sys.argv[1] + "/tests")
from trajectory_hash import _traffic_arrays
CASES = [
    ("ramps-vgr13-s11", "highway_ramps_v0", {"vgr": 1/3, "duration": 80.0}, 11, 400, 0.0),
    ("ramps-vgr12-s12-rand", "highway_ramps_v0", {"vgr": 0.5, "duration": 60.0}, 12, 300, 0.15),
    ("lane-drop-s13-rand", "highway_formation_v0", {"scenario": "lane-drop"}, 13, 150, 0.2),
    ("off-ramp-s14", "highway_formation_v0", {"scenario": "off-ramp"}, 14, 150, 0.0),
    ("on-ramp-s15-rand", "highway_formation_v0", {"scenario": "on-ramp"}, 15, 150, 0.3),
    ("free-60-s16-rand", "highway_formation_v0", {"vehicles_count": 60, "initial_position": None}, 16, 120, 0.3),
    ("lane-change-s17", "highway_formation_v0", {"scenario": "lane-change"}, 17, 150, 0.0),
    ("intersection-multi-vp-2800-s31", "intersection_v0", {"method": "multi-vp", "throughput": 2800.0}, 31, 600, 0.0),
    ("intersection-single-vp-2400-s32-rand", "intersection_v0", {"method": "single-vp", "throughput": 2400.0}, 32, 600,
     0.2),
    ("intersection-fcfs-3200-s33-rand", "intersection_v0", {"method": "fcfs", "throughput": 3200.0}, 33, 600, 0.2),
]
WITH_OBS = "--without-observations" not in sys.argv[2:]
out = {}
for name, module, cfg, seed, steps, share in CASES:
    mod = importlib.import_module(f"icv_envs.envs.{module}")
    env = mod.parallel_env(**cfg)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    obs, infos = env.reset(seed=seed)
    crashes = 0
    for _ in range(steps):
        if env.episode_over:
            break
        ex = env.expert_actions()
        acts = {a: (rng.uniform(-1, 1, 2).astype(np.float32) if rng.random() < share else ex[a]) for a in env.agents}
        obs, rew, term, trunc, infos = env.step(acts)
        for a in sorted(obs):
            h.update(a.encode())
            if WITH_OBS:
                h.update(np.ascontiguousarray(obs[a], dtype=np.float32).tobytes())
            h.update(np.float64(rew[a]).tobytes()); h.update(bytes([bool(term[a]), bool(trunc[a])]))
            if "expert_action" in infos.get(a, {}):
                h.update(np.ascontiguousarray(infos[a]["expert_action"], dtype=np.float32).tobytes())
        for k, v in _traffic_arrays(env.core):  # (the world's public state arrays, as the fingerprints hash them)
            h.update(k.encode()); h.update(np.ascontiguousarray(v).tobytes())
        crashes += sum(1 for a in term if term[a] and not infos.get(a, {}).get("exited", False))
    m = env.core.metrics() if hasattr(env.core, "metrics") else {}
    h.update(json.dumps(m, sort_keys=True, default=str).encode())
    out[name] = (h.hexdigest()[:16], crashes)
print(json.dumps(out))
