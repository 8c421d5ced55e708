"""Speed of the intersection environment (``icv-envs bench intersection``).

Runs the PettingZoo parallel env with every vehicle an agent and the
method's expert acting through the API (its action read from every agent's
info, observations, rewards and infos computed for all agents every step):
first a warm-up until about ``target_vehicles`` vehicles are in the zones
(not timed), then ``seconds`` simulated seconds timed.  Reports
``agent_steps_per_s`` (agent-steps per wall second: the sum over timed
steps of the live agents), ``agent_steps_per_cpu_s`` (per second of this
process's CPU time: what a loaded, shared machine still measures fairly) and
``env_steps_per_s``, next to the reference
measured for this project: MetaDrive's multi-agent intersection at about
67 env steps/s with about 20 agents, i.e. about 1,430 agent-steps/s (the
bar is 10x that).
"""

from __future__ import annotations

import platform
import time

import numpy as np

__all__ = ["bench_intersection", "METADRIVE_AGENT_STEPS_PER_S"]

#: MetaDrive multi-agent intersection, measured for this project (about 67 env steps/s x 20 agents).
METADRIVE_AGENT_STEPS_PER_S = 1430.0


def bench_intersection(seconds: float = 60.0, throughput: float = 2200.0, method: str = "multi-vp",
                       target_vehicles: int = 60, max_warmup: float = 300.0, seed: int = 0, echo=print) -> dict:
    from icv_envs.envs.intersection_v0 import parallel_env

    if not seconds > 0:
        raise ValueError(f"seconds = {seconds!r}; allowed: a number > 0")
    env = parallel_env(method=method, throughput=float(throughput), duration=float(max_warmup + seconds + 10.0))
    obs, infos = env.reset(seed=seed)
    # warm-up: fill the zones
    while len(env.agents) < target_vehicles and env.core.world.time < max_warmup:
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    t_start = env.core.world.time
    agent_steps = 0
    steps = 0
    counts = []
    t0 = time.perf_counter()
    c0 = time.process_time()
    while env.core.world.time < t_start + seconds - 1e-9:
        n = len(env.agents)
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
        agent_steps += n
        counts.append(n)
        steps += 1
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    m = env.metrics()
    env.close()
    res = {
        "bench": "intersection",
        "method": method,
        "throughput": float(throughput),
        "sim_seconds": float(seconds),
        "wall_seconds": wall,
        "env_steps": steps,
        "mean_agents": float(np.mean(counts)) if counts else 0.0,
        "min_agents": int(min(counts)) if counts else 0,
        "max_agents": int(max(counts)) if counts else 0,
        "env_steps_per_s": steps / wall if wall > 0 else None,
        "agent_steps_per_s": agent_steps / wall if wall > 0 else None,
        "real_time_factor": float(seconds) / wall if wall > 0 else None,
        "cpu_seconds": cpu,
        "agent_steps_per_cpu_s": agent_steps / cpu if cpu > 0 else None,
        "metadrive_agent_steps_per_s": METADRIVE_AGENT_STEPS_PER_S,
        "ratio_vs_metadrive": (agent_steps / wall) / METADRIVE_AGENT_STEPS_PER_S if wall > 0 else None,
        "collisions": m["collisions"],
        "lost": m["lost"],
        "python": f"{platform.python_implementation()} {platform.python_version()} numpy {np.__version__}",
    }
    echo(f"intersection ({method}, {throughput:g} veh/h): {res['mean_agents']:.0f} agents on average "
         f"({res['min_agents']}-{res['max_agents']}), {res['env_steps_per_s']:.0f} env steps/s, "
         f"{res['agent_steps_per_s']:.0f} agent-steps/s (x{res['ratio_vs_metadrive']:.1f} MetaDrive's "
         f"~{METADRIVE_AGENT_STEPS_PER_S:.0f}), x{res['real_time_factor']:.1f} real time; "
         f"{res['agent_steps_per_cpu_s']:.0f} agent-steps per CPU second")
    return res


def run_cli(args, echo=print) -> dict:
    """``icv-envs bench intersection``: ``args.seconds`` (timed simulated
    seconds, default 60) and optionally ``args.throughput`` (vehicles/h,
    default 2200: about 60-70 vehicles in the zones) and ``args.method``."""
    seconds = getattr(args, "seconds", None) or 60.0
    tp = getattr(args, "throughput", None)
    if isinstance(tp, (list, tuple)):
        tp = tp[0] if tp else None
    tp = float(tp) if tp else 2200.0
    if not 0 < tp <= 20000:
        raise ValueError(f"throughput {tp!r} is invalid; allowed: 0 < throughput <= 20000 vehicles/h")
    method = getattr(args, "method", None) or "multi-vp"
    from icv_envs.envs.intersection import METHODS

    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; allowed: {list(METHODS)}")
    return bench_intersection(seconds=float(seconds), throughput=tp, method=method, echo=echo)
