"""Where a step of the intersection goes, part by part, for comparing two
trees on a noisy machine (issue 10): multi-vp at ``--throughput`` veh/h
(2200) through the PettingZoo API, every vehicle an agent driven by the
expert's action from its info (as ``icv-envs bench intersection``), the
zones filled to 60 vehicles first, then ``--steps`` policy steps; process
CPU time per step and ``time.perf_counter`` totals of the main parts
(wrapped methods; a part nested in another is counted in both).

    PYTHONPATH=<tree> python scripts/bench_intersection_parts.py [--steps 1200]

Run it for both trees, alternately, more than once: the total moves by 10%
or more between runs on a shared machine; the parts' ratios are steadier.
"""

from __future__ import annotations

import argparse
import time

from bench_ring_parts import wrap_parts  # the sibling script's part timer (scripts/ is on sys.path when run)

PARTS = [
    ("icv_envs.envs.base", "IcvAgentsEnv", "_ma_advance"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_advance"),
    ("icv_envs.sim.intersection_world", "IntersectionWorld", "substep"),
    ("icv_envs.sim.intersection_metrics", "PetStats", "record"),
    ("icv_envs.sim.intersection_metrics", "JamWatch", "record"),
    ("icv_envs.sim.intersection_metrics", "MotionStats", "record"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "update"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "_coordinate"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "_references"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "tree"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "_start_lane_changes"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "compute"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "_envelope"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "_steering"),
    ("icv_envs.policies.platoon_expert", "PlatoonExpert", "_longitudinal"),
    ("icv_envs.policies.platoon_common", "Corridors", "__init__"),
    ("icv_envs.sim.intersection_world", "IntersectionWorld", "route"),
    ("icv_envs.envs.intersection", "IntersectionEnv", "_spawn_due"),
    ("icv_envs.envs.intersection", "IntersectionEnv", "_features"),
    ("icv_envs.envs.base", "IcvAgentsEnv", "_observe_rows"),
    ("icv_envs.envs.intersection", "IntersectionEnv", "_rewards_rows"),
]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--steps", type=int, default=1200, help="policy steps timed")
    p.add_argument("--throughput", type=float, default=2200.0, help="demand (veh/h)")
    a = p.parse_args()
    acc: dict[str, float] = {}
    wrap_parts(PARTS, acc, qualified=True)
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method="multi-vp", throughput=a.throughput, duration=300.0 + a.steps / 5.0 + 10.0)
    obs, infos = env.reset(seed=0)
    while len(env.agents) < 60 and env.core.world.time < 300:
        obs, rew, term, trunc, infos = env.step({ag: infos[ag]["expert_action"] for ag in env.agents})
    acc.clear()
    n = 0
    t0 = time.process_time()
    for _ in range(a.steps):
        n += len(env.agents)
        obs, rew, term, trunc, infos = env.step({ag: infos[ag]["expert_action"] for ag in env.agents})
    total = time.process_time() - t0
    print(f"step {total * 1e3 / a.steps:.2f} ms CPU ({n / a.steps:.1f} agents on average; "
          f"{n / total:,.0f} agent-steps per CPU s, wrappers included)")
    for k, v in sorted(acc.items(), key=lambda kv: -kv[1]):
        print(f"  {k:34s} {v * 1e3 / a.steps:7.3f} ms")


if __name__ == "__main__":
    main()
