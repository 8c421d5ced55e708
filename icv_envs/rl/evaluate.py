"""Evaluate a policy on an env of this package and report the env's metrics.

    evaluate(env, policy, episodes=5, seed=0, config=None, out=None) -> dict
    python -m icv_envs.rl.evaluate --env ID --policy P --episodes N --seed S [--config JSON] [--out DIR]

``policy`` is ``"expert"`` (the formation expert's ``infos[agent]["expert_action"]``),
``"zero"`` (coast straight), ``"random"`` (uniform, seeded) or the path of a
model written by ``baselines/ppo_single.py``, ``ppo_shared.py`` or
``bc_expert.py`` (its directory or its ``model.zip``).

The env decides how the policy drives:

* a PettingZoo env (``icv_envs/highway_formation-v0``, ``highway_formation_v0``):
  every agent is driven by the policy (``mode: "all-agents"``); the natural
  place for the multi-agent models (``ppo_shared``, ``bc_expert``);
* a Gymnasium id (``icv_envs/HighwayFormation-v0``): the policy drives the ego
  and the formation expert drives every other ICV (``mode: "ego"``); the
  natural place for ``ppo_single`` models.

Both envs have the same per-agent spaces, so any model runs in either mode
(cross-evaluation); the result records the model's ``algo`` and training env.
A model whose spaces differ from the env's raises ``ValueError`` naming both.

Episode ``k`` (0-based) is reset with seed ``seed + k``. With ``config=None``
a saved model's training config (from its ``run.json``) is used, otherwise
the env's defaults; an explicit ``config`` replaces it (use ``scenario`` to
pick one of free, lane-drop, lane-change, off-ramp, on-ramp).

Returned metrics (definitions in :mod:`icv_envs.experiments.metrics`), over
all episodes: ``collisions``, ``exited``, ``left_road``, ``vehicles`` summed;
``mean_speed``, ``speed_fluctuation``, ``sim_seconds`` averaged; ``min_gap`` the
smallest; ``episode_return`` the mean over episodes of the summed reward of
all agents (``all-agents``) or of the ego (``ego``), with
``episode_return_std``; ``episode_length`` the mean number of policy steps;
and ``per_episode``, the env's metrics of each episode.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from icv_envs.rl.envs import EnvSpec, make_gym_env, make_parallel_env, parse_config, resolve_env
from icv_envs.rl.models import json_safe

__all__ = ["evaluate", "main", "build_parser", "add_arguments", "run", "NAMED_POLICIES"]

NAMED_POLICIES = ("expert", "zero", "random")


def _check_int(name, v, lo):
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
        raise ValueError(f"{name} = {v!r} is invalid; allowed: an integer >= {lo}")
    return int(v)


def _load_policy(policy):
    """``(name, LoadedModel | None)``."""
    if isinstance(policy, str) and policy in NAMED_POLICIES:
        return policy, None
    if not isinstance(policy, (str, Path)) or str(policy) == "":
        raise ValueError(f"policy {policy!r} is invalid; allowed: {', '.join(NAMED_POLICIES)} or a model path")
    from icv_envs.rl.models import load_model

    return str(policy), load_model(policy)


def evaluate(env_id_or_module, policy, episodes: int = 5, seed: int = 0, config: dict | None = None,
             out=None, deterministic: bool = True) -> dict:
    """Run ``episodes`` episodes (seeds ``seed``, ``seed + 1``, ...) and return
    the metrics dict (see the module docstring); with ``out``, also write
    ``out/eval.json``."""
    spec = resolve_env(env_id_or_module)
    episodes = _check_int("episodes", episodes, 1)
    seed = _check_int("seed", seed, 0)
    if config is not None and not isinstance(config, dict):
        raise ValueError(f"config must be a dict or None, got {type(config).__name__}")
    name, model = _load_policy(policy)
    if config is None:
        config = dict(model.meta.get("config") or {}) if model is not None else {}
    t0 = time.perf_counter()
    if spec.kind == "pettingzoo":
        per_episode = _run_parallel(spec, name, model, episodes, seed, config, deterministic)
    else:
        per_episode = _run_gym(spec, name, model, episodes, seed, config, deterministic)
    res = _aggregate(per_episode)
    res.update({
        "env": spec.id,
        "env_kind": spec.kind,
        "mode": "all-agents" if spec.kind == "pettingzoo" else "ego",
        "policy": name,
        "algo": model.algo if model is not None else name,
        "trained_on": (model.meta.get("env") if model is not None else None),
        "episodes": episodes,
        "seed": seed,
        "config": config,
        "deterministic": bool(deterministic),
        "wall_seconds": time.perf_counter() - t0,
        "per_episode": per_episode,
    })
    res = json_safe(res)
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "eval.json").write_text(json.dumps(res, indent=2))
    return res


def _run_parallel(spec: EnvSpec, name, model, episodes, seed, config, deterministic) -> list[dict]:
    env = make_parallel_env(spec, config)
    try:
        a0 = env.possible_agents[0]
        if model is not None:
            model.check_spaces(spec.id, env.observation_space(a0), env.action_space(a0))
        rng = np.random.default_rng(seed)
        act_space = env.action_space(a0)
        rows = []
        for ep in range(episodes):
            obs, infos = env.reset(seed=seed + ep)
            total, steps = 0.0, 0
            while env.agents:
                agents = list(env.agents)
                if name == "expert":
                    if all("expert_action" in infos.get(a, {}) for a in agents):
                        actions = {a: infos[a]["expert_action"] for a in agents}
                    else:
                        ex = env.expert_actions()
                        actions = {a: ex[a] for a in agents}
                elif name == "zero":
                    actions = {a: np.zeros(act_space.shape, dtype=np.float32) for a in agents}
                elif name == "random":
                    u = rng.uniform(act_space.low, act_space.high, (len(agents), *act_space.shape))
                    actions = {a: u[i].astype(np.float32) for i, a in enumerate(agents)}
                else:
                    acts = model.act(np.stack([obs[a] for a in agents]), deterministic)
                    actions = {a: acts[i] for i, a in enumerate(agents)}
                obs, rew, term, trunc, infos = env.step(actions)
                total += float(sum(rew.values()))
                steps += 1
            m = dict(env.metrics())
            m.update({"seed": seed + ep, "episode_return": total, "episode_length": steps})
            rows.append(m)
        return rows
    finally:
        env.close()


def _run_gym(spec: EnvSpec, name, model, episodes, seed, config, deterministic) -> list[dict]:
    env = make_gym_env(spec, config)
    try:
        if model is not None:
            model.check_spaces(spec.id, env.observation_space, env.action_space)
        rng = np.random.default_rng(seed)
        space = env.action_space
        rows = []
        for ep in range(episodes):
            obs, info = env.reset(seed=seed + ep)
            total, steps, done = 0.0, 0, False
            while not done:
                if name == "expert":
                    action = info.get("expert_action")
                    if action is None:
                        action = np.zeros(space.shape, dtype=np.float32)
                elif name == "zero":
                    action = np.zeros(space.shape, dtype=np.float32)
                elif name == "random":
                    action = rng.uniform(space.low, space.high).astype(np.float32)
                else:
                    action = model.act(obs[None], deterministic)[0]
                obs, r, terminated, truncated, info = env.step(action)
                total += float(r)
                steps += 1
                done = terminated or truncated
            m = dict(env.unwrapped.metrics())
            m.update({"seed": seed + ep, "episode_return": total, "episode_length": steps})
            rows.append(m)
        return rows
    finally:
        env.close()


def _aggregate(rows: list[dict]) -> dict:
    def col(k):
        return [r[k] for r in rows if r.get(k) is not None]

    gaps = col("min_gap")
    ret = np.array(col("episode_return"), dtype=float)
    res = {
        "collisions": int(sum(col("collisions"))),
        "mean_speed": float(np.mean(col("mean_speed"))),
        "speed_fluctuation": float(np.mean(col("speed_fluctuation"))),
        "min_gap": float(min(gaps)) if gaps else None,
        "exited": int(sum(col("exited"))),
        "left_road": int(sum(col("left_road"))),
        "vehicles": int(sum(col("vehicles"))),
        "episode_return": float(ret.mean()),
        "episode_return_std": float(ret.std()),
        "episode_length": float(np.mean(col("episode_length"))),
        "sim_seconds": float(np.mean(col("sim_seconds"))),
    }
    return res


# ---------------------------------------------------------------------- CLI
def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The ``evaluate`` arguments (for wiring as ``icv-envs evaluate``)."""
    p.add_argument("--env", required=True,
                   help="Gymnasium id (ego mode) or PettingZoo id / module (all agents), e.g. "
                        "icv_envs/HighwayFormation-v0, icv_envs/highway_formation-v0, highway_formation_v0")
    p.add_argument("--policy", default="expert",
                   help="expert, zero, random, or a model directory / model.zip from baselines/")
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--seed", type=int, default=0, help="episode k is reset with seed + k")
    p.add_argument("--config", default=None,
                   help="JSON object (or .json file) of env config; default: the model's training config")
    p.add_argument("--out", default=None, help="also write DIR/eval.json")
    p.add_argument("--stochastic", action="store_true", help="sample model actions instead of the mean")
    return p


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="icv-envs evaluate", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    return add_arguments(p)


def run(args: argparse.Namespace) -> int:
    """Run parsed arguments; prints one JSON line; ``ValueError`` on bad input."""
    config = parse_config(args.config) if args.config else None
    res = evaluate(args.env, args.policy, args.episodes, args.seed, config, args.out,
                   deterministic=not args.stochastic)
    print(json.dumps(res))
    return 0


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except ValueError as exc:
        print(f"icv-envs evaluate: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
