"""Training-throughput benchmark: env steps per second of the single-agent
HighwayFormation env alone and inside Stable-Baselines3 PPO training, with
highway-env's ``highway-fast-v0`` measured in the same run as the reference
(machines are noisy: compare the ratios, never assert wall times).

    python -m icv_envs.rl.bench [--vehicles 20] [--env-steps 2000] [--ppo-steps 4096] [--out DIR]

Both envs get ``vehicles_count = vehicles`` (20 by default, highway-fast-v0's
own default) and the same driving: the "do nothing" action (icv_envs: ``[0, 0]``,
coast straight; highway-fast-v0: ``IDLE``) for the env-alone measurement, and
PPO ``MlpPolicy`` with the same hyper-parameters (``n_steps=512``,
``batch_size=64``, ``n_epochs=10``, one torch thread, CPU) for training.
Episode resets are included in the timings. Reported per env:

* ``env_sps``: env steps per second, env alone;
* ``ppo_sps``: env steps per second of ``PPO.learn`` (rollouts + updates);
* ``ppo_rollout_sps``: env steps per second of the rollout phase alone
  (env + policy inference), timed by a callback.

* ``env_sim_seconds_per_second``: simulated seconds per wall second, env
  alone (``env_sps / policy_frequency``).

Time numba spends in its compiler inside a timed window (a first run on a
machine: the env's kernels compile at their first call) is excluded from
it and reported (``env_jit_seconds_excluded`` / ``ppo_jit_seconds_excluded``
and the compile counts; :mod:`icv_envs._jit_clock`, from stop 54; the
batched worlds run twice and time the second run).

Beside them, the batched worlds of :mod:`icv_envs.vector` (16
HighwayFormation worlds of ``vehicles`` agents in this process,
:func:`batched_sps`): agent-steps per CPU second and per wall second with
external zero actions (no expert computed; the worlds stay full), with the
expert's action computed for every agent, and with external uniform random
actions, an untrained policy's (vehicles crash or leave the road and are
removed, so fewer agents share a world-step's cost: from stop 43;
``batched_learned_actions`` / ``batched_expert_actions`` /
``batched_untrained_actions``, each with its live agents per world and
world-steps per CPU second), and highway-fast-v0's agent-steps per second
(one controlled vehicle: its ``env_sps``).

A step is not the same amount of driving in both: icv_envs acts at 5 Hz
(0.2 s per step, physics at 25 Hz), highway-fast-v0 at 1 Hz (1 s per step,
physics at 5 Hz). ``env_speedup`` / ``ppo_speedup`` compare steps (what an RL
budget counts); ``sim_speedup`` compares simulated time. 20 ICVs do not fit
behind the default ``initial_position`` (150 m), so the icv env gets
``initial_position=None`` (automatic placement).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from icv_envs._args import check_config, check_flag, check_int
from icv_envs._jit_clock import JitClock, jit_note
from icv_envs.rl.models import platform_info

__all__ = ["bench_train", "env_sps", "ppo_sps", "main"]

ICV_ID = "icv_envs/HighwayFormation-v0"
REFERENCE_ID = "highway-fast-v0"


def _make(env_id: str, vehicles: int):
    import gymnasium as gym

    if env_id == ICV_ID:
        import icv_envs  # noqa: F401

        return gym.make(env_id, config={"vehicles_count": int(vehicles), "initial_position": None})
    import highway_env  # noqa: F401  (registers highway-fast-v0)

    return gym.make(env_id, config={"vehicles_count": int(vehicles)})


def _idle_action(env):
    space = env.action_space
    if hasattr(space, "n"):  # highway-env DiscreteMetaAction: 1 = IDLE
        return 1
    return np.zeros(space.shape, dtype=space.dtype)


def env_sps(env_id: str, vehicles: int = 20, steps: int = 2000, seed: int = 0) -> dict:
    """Env steps per second with the idle action, resets included."""
    check_int("vehicles", vehicles, 1)
    check_int("steps", steps, 1)
    check_int("seed", seed, 0)
    env = _make(env_id, vehicles)
    action = _idle_action(env)
    env.reset(seed=seed)
    episodes = 1
    with JitClock() as jit:  # the window, numba's compiler excluded (icv_envs/_jit_clock.py)
        for _ in range(steps):
            _, _, term, trunc, _ = env.step(action)
            if term or trunc:
                env.reset()
                episodes += 1
    wall = jit.wall
    cfg = env.unwrapped.config
    env.close()
    return {"env_sps": steps / wall, "env_sim_seconds_per_second": steps / wall / cfg["policy_frequency"],
            "steps": steps, "episodes": episodes,
            "policy_frequency": cfg["policy_frequency"], "simulation_frequency": cfg["simulation_frequency"],
            "env_jit_seconds_excluded": jit.seconds, "env_jit_compiles": jit.compiles}


def ppo_sps(env_id: str, vehicles: int = 20, steps: int = 4096, seed: int = 0) -> dict:
    """Env steps per second inside SB3 PPO training (total and rollout phase)."""
    check_int("vehicles", vehicles, 1)
    check_int("steps", steps, 1)
    check_int("seed", seed, 0)
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv

    torch.set_num_threads(1)

    class RolloutTimer(BaseCallback):
        """The rollout phases as windows of their own clock (``jit.wall``:
        their wall seconds without numba's compiler; a compilation at the
        reset before the first rollout is in ``learn``'s window, not in a
        rollout's)."""

        def __init__(self):
            super().__init__()
            self.jit = JitClock()

        def _on_rollout_start(self) -> None:
            self.jit.__enter__()

        def _on_rollout_end(self) -> None:
            self.jit.__exit__(None, None, None)

        def _on_step(self) -> bool:
            return True

    venv = DummyVecEnv([lambda: _make(env_id, vehicles)])
    model = PPO("MlpPolicy", venv, n_steps=512, batch_size=64, n_epochs=10, seed=seed, device="cpu", verbose=0)
    timer = RolloutTimer()
    with JitClock() as jit:  # (the env's kernels, first called in the first rollout: excluded from both clocks)
        try:
            model.learn(total_timesteps=steps, callback=timer)
        finally:
            timer.jit.__exit__(None, None, None)  # (a rollout left by an exception)
    wall = jit.wall
    n = model.num_timesteps
    venv.close()
    return {"ppo_sps": n / wall, "ppo_rollout_sps": n / timer.jit.wall, "ppo_steps": n,
            "ppo_wall_seconds": wall, "ppo_jit_seconds_excluded": jit.seconds, "ppo_jit_compiles": jit.compiles}


#: ``batched_sps``' kinds of external actions: zeros (coasting straight: nothing crashes, the worlds stay
#: full), uniform in [-0.3, 0.3] and uniform in [-1, 1] (an untrained policy's output: vehicles crash or leave
#: the road and are removed, so a world runs on with fewer agents until its episode ends)
BATCHED_ACTIONS = ("zero", "small", "uniform")


def batched_sps(vehicles: int = 20, worlds: int = 16, steps: int = 100, expert: bool = False, seed: int = 0,
                config: dict | None = None, actions: str = "zero", warmup: int = 0, policy=None) -> dict:
    """Agent-steps per second of :class:`icv_envs.vector.BatchedWorlds`:
    ``worlds`` HighwayFormation worlds of ``vehicles`` agents each, stepped
    together in this process. ``expert=False``: actions come from outside
    (policy inference is not included) and the expert is never computed;
    ``expert=True``: the expert's action is computed for every agent every
    step and fed back. Auto-resets are included. Per CPU second (process
    time) and per wall second, with the world-steps per CPU second and the
    live agents per world on average (agent-steps count live agents only).
    ``config`` is merged into the worlds' env config.

    The external actions (``actions``, :data:`BATCHED_ACTIONS`; fixed seed)
    decide how many agents stay alive, and so the agent-steps a world-step
    yields: ``"zero"`` (the default; coasting, the worlds stay full),
    ``"small"`` (uniform in ``[-0.3, 0.3]``; ``random_actions=True`` until
    stop 43) and ``"uniform"`` (in ``[-1, 1]``, an untrained policy: at stop
    43 the 16 worlds of 20 held about 6 live agents on average, 32k-33k
    agent-steps per CPU s against 113k with zeros, for a world-step that
    costs about as much). ``warmup`` batch steps run before the timed
    ``steps`` (with random actions the first seconds of an episode still
    have most agents alive: time past them, over several episodes).
    ``policy``: a callable ``policy(obs, mask) -> actions (worlds, K, 2)``
    (a trained policy's, e.g. ``scripts/bench_batched_trained.py``'s) acts
    instead; the CPU and wall time of its calls are measured apart and left
    out of the figures (``policy_cpu_seconds``). ``expert`` and ``policy``
    take the external actions' place, so either with another ``actions``
    than the default is an error, and so are both together.

    Steady state: the same run (same seed, same steps) is made twice and
    only the second is timed. The first loads every compiled kernel the
    run reaches from numba's cache (about 60 ms at the first step and
    about 25 ms more at the first collision, whenever it comes), a cost
    paid once per process that was 20-25% of the timed figure of 100
    batch steps before stop 38."""
    from icv_envs.vector import BatchedWorlds

    if actions not in BATCHED_ACTIONS:
        raise ValueError(f"actions = {actions!r}; allowed: {list(BATCHED_ACTIONS)}")
    check_flag("expert", expert)
    if (expert or policy is not None) and actions != "zero":
        raise ValueError(f"actions = {actions!r} with {'expert=True' if expert else 'a policy'}, which acts instead; "
                         f"allowed: the default 'zero'")
    if expert and policy is not None:
        raise ValueError("expert=True and a policy: allowed: one of them (or neither: external actions)")
    if policy is not None and not callable(policy):
        raise ValueError(f"policy = {policy!r}; allowed: a callable policy(obs, mask) -> actions")
    for name, v, lo in (("vehicles", vehicles, 1), ("worlds", worlds, 1), ("steps", steps, 1), ("seed", seed, 0),
                        ("warmup", warmup, 0)):
        check_int(name, v, lo)
    check_config(config)
    if config and "vehicles_count" in config and config["vehicles_count"] != vehicles:
        raise ValueError(f"config['vehicles_count'] = {config['vehicles_count']!r} clashes with vehicles = "
                         f"{vehicles!r}; allowed: the vehicle count given once, as vehicles")
    bound = {"small": 0.3, "uniform": 1.0}.get(actions)
    cfg = {"vehicles_count": int(vehicles), "initial_position": None, **(config or {})}
    for timed in (False, True):
        bw = BatchedWorlds(worlds, config=cfg, seed=seed, expert=expert)
        obs, mask = bw.reset()
        acts = np.zeros((worlds, bw.K, 2), dtype=np.float32)
        rng = np.random.default_rng(seed)
        agent_steps = 0
        policy_cpu = policy_wall = 0.0
        for i in range(warmup + steps):
            if i == warmup:
                c0, t0 = time.process_time(), time.perf_counter()
            if expert:
                acts = bw.expert_actions
            elif policy is not None:
                p0, q0 = time.process_time(), time.perf_counter()
                acts = policy(obs, mask)
                if i >= warmup:
                    policy_cpu += time.process_time() - p0
                    policy_wall += time.perf_counter() - q0
            elif bound is not None:
                acts = rng.uniform(-bound, bound, size=(worlds, bw.K, 2)).astype(np.float32)
            if i >= warmup:
                agent_steps += int(bw.mask.sum())
            obs, _, _, _, mask, _ = bw.step(acts)
        cpu = time.process_time() - c0 - policy_cpu
        wall = time.perf_counter() - t0 - policy_wall
        bw.close()
    return {"worlds": int(worlds), "vehicles_per_world": int(vehicles), "expert": bool(expert),
            "actions": "expert" if expert else "policy" if policy is not None else actions,
            "agent_steps": agent_steps, "agent_steps_per_cpu_s": agent_steps / cpu,
            "agent_steps_per_wall_s": agent_steps / wall, "world_steps_per_cpu_s": worlds * steps / cpu,
            "live_agents_per_world": agent_steps / (worlds * steps), "policy_cpu_seconds": policy_cpu}


def bench_train(vehicles: int = 20, env_steps: int = 2000, ppo_steps: int = 4096, seed: int = 0,
                reference: bool = True, echo=None, batched: bool = True) -> dict:
    """Measure this package's single-agent env and (``reference=True``)
    highway-fast-v0, alone and inside PPO; returns one JSON-able dict."""
    for name, v in (("vehicles", vehicles), ("env_steps", env_steps), ("ppo_steps", ppo_steps)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{name} = {v!r} is invalid; allowed: an integer >= 1")
    ids = [ICV_ID] + ([REFERENCE_ID] if reference else [])
    rows = {}
    for env_id in ids:
        row = {"env": env_id}
        row.update(env_sps(env_id, vehicles, env_steps, seed))
        row.update(ppo_sps(env_id, vehicles, ppo_steps, seed))
        rows[env_id] = row
        if echo is not None:
            echo(f"{env_id:32s} env {row['env_sps']:8.1f} steps/s   PPO {row['ppo_sps']:7.1f} steps/s "
                 f"(rollouts {row['ppo_rollout_sps']:7.1f} steps/s)")
            jit_s = row["env_jit_seconds_excluded"] + row["ppo_jit_seconds_excluded"]
            if jit_s > 0:
                jit_n = row["env_jit_compiles"] + row["ppo_jit_compiles"]
                echo(f"{'':32s} " + jit_note(jit_s, jit_n, "these timed windows"))
    icv = rows[ICV_ID]
    res = {"bench": "rl-train", "vehicles": int(vehicles), "icv_envs": icv}
    if batched:
        # 16 worlds: one batch step is 16 env steps of 20 agents; env_steps / 20 batch steps (100 by
        # default) time about as many world steps as the env alone; random actions: three times as many
        # after as many untimed, past the first seconds of the episodes, in which most agents still live
        n = max(2, env_steps // 20)
        for key, ex, kind, steps, warmup, what, bar in (
                ("batched_learned_actions", False, "zero", n, 0, "external zero actions", "; bar 200,000"),
                ("batched_expert_actions", True, "zero", n, 0, "the expert's actions", "; bar 100,000"),
                ("batched_untrained_actions", False, "uniform", 3 * n, n,
                 "external uniform random actions, an untrained policy", "")):
            res[key] = b = batched_sps(vehicles, expert=ex, seed=seed, steps=steps, actions=kind, warmup=warmup)
            if echo is not None:
                echo(f"batched worlds ({b['worlds']} x {vehicles} agents, {what}): "
                     f"{b['agent_steps_per_cpu_s']:,.0f} agent-steps per CPU s "
                     f"({b['agent_steps_per_wall_s']:,.0f} per wall s; {b['live_agents_per_world']:.1f} live agents "
                     f"per world on average, {b['world_steps_per_cpu_s']:,.0f} world-steps per CPU s){bar}")
        if reference:
            # highway-fast-v0 controls one vehicle: one agent-step per env step
            res["highway_fast_v0_agent_steps_per_s"] = rows[REFERENCE_ID]["env_sps"]
    if reference:
        ref = rows[REFERENCE_ID]
        res["highway_fast_v0"] = ref
        res["env_speedup"] = icv["env_sps"] / ref["env_sps"]
        res["ppo_speedup"] = icv["ppo_sps"] / ref["ppo_sps"]
        res["ppo_rollout_speedup"] = icv["ppo_rollout_sps"] / ref["ppo_rollout_sps"]
        res["sim_speedup"] = icv["env_sim_seconds_per_second"] / ref["env_sim_seconds_per_second"]
    res["platform"] = platform_info()
    return res


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m icv_envs.rl.bench", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--vehicles", type=int, default=20)
    p.add_argument("--env-steps", type=int, default=2000)
    p.add_argument("--ppo-steps", type=int, default=4096)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-reference", action="store_true", help="skip highway-fast-v0")
    p.add_argument("--out", default=None, help="also write DIR/bench_rl.json")
    args = p.parse_args(argv)
    try:
        res = bench_train(args.vehicles, args.env_steps, args.ppo_steps, args.seed, not args.no_reference,
                          echo=lambda s: print(s, flush=True))
    except ValueError as exc:
        print(f"icv-envs bench: error: {exc}", file=sys.stderr)
        return 2
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "bench_rl.json").write_text(json.dumps(res, indent=2))
    print(json.dumps(res))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
