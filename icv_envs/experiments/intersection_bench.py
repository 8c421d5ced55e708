"""Speed of the intersection environment (``icv-envs bench intersection``).

Runs the PettingZoo parallel env with every vehicle an agent and the
method's expert acting through the API (its action read from every agent's
info, observations, rewards and infos computed for all agents every step).
Per seed: ``warmup`` simulated seconds not timed (default 100 s, the
warm-up of ``icv-envs compare intersection``: the zones fill in about a
minute at 2200 veh/h), then ``seconds`` simulated seconds timed (default
500: the rest of a 600 s run). Reports ``agent_steps_per_s`` (agent-steps
per wall second: the sum over timed steps of the live agents),
``agent_steps_per_cpu_s`` (per second of this process's CPU time: what a
loaded, shared machine still measures fairly) and ``env_steps_per_s``, over
all seeds together and per seed, next to the reference measured for this
project: MetaDrive's multi-agent intersection at about 67 env steps/s with
about 20 agents, i.e. about 1,430 agent-steps/s. Time numba spends in
its compiler inside a window (a first run on a machine: the virtual
platoon's kernels are first called when the first node forms, about 55 s
into a run) is excluded from both clocks and reported
(``jit_seconds_excluded``, ``jit_cpu_seconds_excluded``, ``jit_compiles``;
:mod:`icv_envs._jit_clock`, from stop 54).

``api`` (``--api``, from stop 47; as ``bench highway-ramps --vs-sumo``'s):
``dicts`` (the default: PettingZoo's dicts, every info key, the expert's
action read from each agent's info), ``lean`` (PettingZoo's dicts without
per-step info keys: ``info_keys=[]``, ``expert_in_info=False``; the loop
asks ``expert_actions()`` for the dict of actions) or ``rows`` (the array
path, :meth:`~icv_envs.envs.parallel.CoreParallelEnv.step_rows`, with the
core's ``expert_actions()`` rows). All three drive the same trajectory
(``tests/test_intersection_compare.py``; over the bench's 600 s of seed 2
the same states at every step); they differ in what the API costs. The
expert's own statistics (``virtual_cap_binding`` and the other counters of
``metrics()`` that count per state the expert is asked about) can differ
by the last state: the dicts ask the expert about the final state too, for
its agents' labels (seed 2: 3941 against 3940).

Why a fixed warm-up and a long window (decided at stop 43): the arrivals
come in formations, so the number of vehicles in the zones swings between
about 30 and 85 at 2200 veh/h (seed 0: 50 s means from 34 to 66 between
100 and 600 s). Until stop 42 the bench warmed up until 60 agents were on
the road and timed the next 60 s: a window that starts at a peak, where
more agents share a step's fixed costs, so it overstated the steady rate
(95.8k agent-steps per CPU s at 61 agents on average, against 82k-83k over
the 240 s after the same moment in ``scripts/bench_trees.py``).
"""

from __future__ import annotations

import platform

import numpy as np

from icv_envs._args import check_float, check_int
from icv_envs._jit_clock import JitClock, jit_note
from icv_envs.experiments._checks import check_throughput
from icv_envs.experiments.bench import APIS  # (how the agents are stepped, ``--api``: module docstring)

__all__ = ["bench_intersection", "METADRIVE_AGENT_STEPS_PER_S", "APIS"]

#: MetaDrive multi-agent intersection, measured for this project (about 67 env steps/s x 20 agents).
METADRIVE_AGENT_STEPS_PER_S = 1430.0



def _stepper(env, api: str):
    """One step of the expert driving every agent through ``api``; the
    dicts' stepper reads the expert's actions from the last infos (its
    attribute ``infos``, set by the caller after ``reset``)."""
    if api == "rows":
        core = env.core

        def step():
            env.step_rows(core.expert_actions())
    elif api == "lean":
        def step():
            ex = env.expert_actions()
            env.step({a: ex[a] for a in env.agents})
    else:
        def step():
            infos = step.infos
            step.infos = env.step({a: infos[a]["expert_action"] for a in env.agents})[4]
    return step


def _one_seed(seed: int, seconds: float, warmup: float, throughput: float, method: str, api: str = "dicts") -> dict:
    """One seed's timed window (see the module docstring)."""
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method=method, throughput=float(throughput), duration=float(warmup + seconds + 10.0),
                       **APIS[api])
    step = _stepper(env, api)
    step.infos = env.reset(seed=seed)[1]
    while env.core.world.time < warmup - 1e-9:  # warm-up, not timed
        step()
    t_start = env.core.world.time
    agent_steps = steps = 0
    counts = []
    with JitClock() as jit:  # the window, numba's compiler excluded (icv_envs/_jit_clock.py)
        while env.core.world.time < t_start + seconds - 1e-9:
            n = env.num_agents
            step()
            agent_steps += n
            counts.append(n)
            steps += 1
    wall, cpu = jit.wall, jit.cpu
    m = env.metrics()
    env.close()
    return {"seed": int(seed), "env_steps": steps, "agent_steps": agent_steps, "wall_seconds": wall,
            "cpu_seconds": cpu, "mean_agents": float(np.mean(counts)) if counts else 0.0,
            "min_agents": int(min(counts)) if counts else 0, "max_agents": int(max(counts)) if counts else 0,
            "agent_steps_per_cpu_s": agent_steps / cpu if cpu > 0 else None,
            "collisions": m["collisions"], "lost": m["lost"], **jit.as_dict()}


def bench_intersection(seconds: float = 500.0, throughput: float = 2200.0, method: str = "multi-vp",
                       warmup: float = 100.0, seeds: int = 3, echo=print, api: str = "dicts") -> dict:
    """The bench of the module docstring on seeds ``0 .. seeds-1``, the
    agents stepped through ``api`` (:data:`APIS`); returns the JSON record
    (the totals over the seeds, and ``per_seed``)."""
    if not isinstance(api, str) or api not in APIS:
        raise ValueError(f"api = {api!r}; allowed: {list(APIS)}")
    seconds = check_float("seconds", seconds, 0)
    warmup = check_float("warmup", warmup, 0, strict=False)
    seeds = check_int("seeds", seeds, 1)  # (seeds 0 .. seeds-1)
    throughput = check_throughput(throughput)
    per = [_one_seed(s, seconds, warmup, throughput, method, api) for s in range(seeds)]
    agent_steps = sum(p["agent_steps"] for p in per)
    steps = sum(p["env_steps"] for p in per)
    wall = sum(p["wall_seconds"] for p in per)
    cpu = sum(p["cpu_seconds"] for p in per)
    counts_mean = agent_steps / steps if steps else 0.0
    rates = [p["agent_steps_per_cpu_s"] for p in per if p["agent_steps_per_cpu_s"]]
    res = {
        "bench": "intersection",
        "method": method,
        "api": api,
        "throughput": float(throughput),
        "warmup_seconds": float(warmup),
        "sim_seconds": float(seconds),
        "seeds": int(seeds),
        "wall_seconds": wall,
        "env_steps": steps,
        "agent_steps": agent_steps,
        "mean_agents": counts_mean,
        "min_agents": min(p["min_agents"] for p in per),
        "max_agents": max(p["max_agents"] for p in per),
        "env_steps_per_s": steps / wall if wall > 0 else None,
        "agent_steps_per_s": agent_steps / wall if wall > 0 else None,
        "real_time_factor": float(seconds) * len(per) / wall if wall > 0 else None,
        "cpu_seconds": cpu,
        "agent_steps_per_cpu_s": agent_steps / cpu if cpu > 0 else None,
        "agent_steps_per_cpu_s_range": [min(rates), max(rates)] if rates else None,
        "metadrive_agent_steps_per_s": METADRIVE_AGENT_STEPS_PER_S,
        "ratio_vs_metadrive": (agent_steps / wall) / METADRIVE_AGENT_STEPS_PER_S if wall > 0 else None,
        "collisions": sum(p["collisions"] for p in per),
        "lost": sum(p["lost"] for p in per),
        "jit_seconds_excluded": sum(p["jit_seconds_excluded"] for p in per),
        "jit_cpu_seconds_excluded": sum(p["jit_cpu_seconds_excluded"] for p in per),
        "jit_compiles": sum(p["jit_compiles"] for p in per),
        "per_seed": per,
        "python": f"{platform.python_implementation()} {platform.python_version()} numpy {np.__version__}",
    }
    for p in per:
        echo(f"  seed {p['seed']}: {p['mean_agents']:.0f} agents on average ({p['min_agents']}-{p['max_agents']}), "
             f"{p['agent_steps_per_cpu_s']:.0f} agent-steps per CPU second")
    echo(f"intersection ({method}, {api}, {throughput:g} veh/h, {seconds:g} s after {warmup:g} s of warm-up, "
         f"{len(per)} seed{'s' if len(per) > 1 else ''}): {res['mean_agents']:.0f} agents on average "
         f"({res['min_agents']}-{res['max_agents']}), {res['env_steps_per_s']:.0f} env steps/s, "
         f"{res['agent_steps_per_s']:.0f} agent-steps/s (x{res['ratio_vs_metadrive']:.1f} MetaDrive's "
         f"~{METADRIVE_AGENT_STEPS_PER_S:.0f}), x{res['real_time_factor']:.1f} real time; "
         f"{res['agent_steps_per_cpu_s']:.0f} agent-steps per CPU second")
    if res["jit_seconds_excluded"] > 0:
        echo("  " + jit_note(res["jit_seconds_excluded"], res["jit_compiles"], "the timed windows"))
    return res


def run_cli(args, echo=print) -> dict:
    """``icv-envs bench intersection``: ``args.seconds`` (timed simulated
    seconds per seed, default 500), ``args.warmup`` (default 100),
    ``args.seeds`` (default 3), ``args.throughput`` (vehicles/h, default
    2200), ``args.method`` (default multi-vp) and ``args.api`` (default
    dicts)."""
    seconds = getattr(args, "seconds", None) or 500.0
    warmup = getattr(args, "warmup", None)
    warmup = 100.0 if warmup is None else float(warmup)
    seeds = getattr(args, "seeds", None)
    seeds = 3 if seeds is None else seeds
    tp = getattr(args, "throughput", None)
    if isinstance(tp, (list, tuple)):
        tp = tp[0] if tp else None
    tp = 2200.0 if tp is None else float(tp)  # (a given 0 is checked, not taken for the default)
    if not 0 < tp <= 20000:
        raise ValueError(f"throughput {tp!r} is invalid; allowed: 0 < throughput <= 20000 vehicles/h")
    method = getattr(args, "method", None) or "multi-vp"
    from icv_envs.envs.intersection import METHODS

    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; allowed: {list(METHODS)}")
    return bench_intersection(seconds=float(seconds), throughput=tp, method=method, warmup=warmup, seeds=seeds,
                              echo=echo, api=getattr(args, "api", None) or "dicts")
