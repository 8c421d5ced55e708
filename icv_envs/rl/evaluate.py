"""Evaluate a policy on an env of this package and report the env's metrics.

    evaluate(env, policy, episodes=5, seed=0, config=None, out=None) -> dict
    python -m icv_envs.rl.evaluate --env ID --policy P --episodes N --seed S [--config JSON] [--out DIR]

``policy`` is one of

* ``"expert"``: the env's expert, ``infos[agent]["expert_action"]``, under the
  env's default method (highway formation: the formation expert; highway
  ramps: ``formation``; intersection: ``multi-vp``), or under the ``method``
  an explicit ``config`` names;
* a reference method, which sets the env's config ``method`` and drives with
  that method's controller (the ``expert_action`` in the infos):
  ``idm`` and ``lane-lp`` on the highway-ramps env (``formation`` is its
  expert), ``single-vp`` and ``fcfs`` on the intersection env (``multi-vp``
  is its expert). A reference on an env that does not have it, or a
  ``config`` naming another ``method``, raises ``ValueError``
  (:data:`REFERENCE_POLICIES`);
* ``"zero"`` (coast straight), ``"random"`` (uniform, seeded); with
  ``DiscreteMetaAction`` ``zero`` is the IDLE action and ``random`` uniform
  over the actions, while ``expert`` and the reference methods (continuous
  ``expert_action``) raise ``ValueError``;
* the path of a model written by ``baselines/ppo_single.py``,
  ``ppo_shared.py`` or ``bc_expert.py`` (its directory or its ``model.zip``).

The env decides how the policy drives:

* a PettingZoo env (``icv_envs/highway_formation-v0``, ``highway_formation_v0``,
  ``icv_envs/highway_ramps-v0``, ``icv_envs/intersection-v0``,
  ``intersection_v0``, ...): every agent is driven by the policy
  (``mode: "all-agents"``); the natural place for the multi-agent models
  (``ppo_shared``, ``bc_expert``). The episode runs until its time is up
  (on the open roads vehicles keep arriving, so ``agents`` can be empty for
  a while: the env is then stepped with no actions), or on the
  highway-formation env until no agent is left and none is due;
* a Gymnasium id (``icv_envs/HighwayFormation-v0``, ``icv_envs/HighwayRamps-v0``,
  ``icv_envs/Intersection-v0``): the policy drives the ego and the env's
  expert drives every other vehicle (``mode: "ego"``); the natural place for
  ``ppo_single`` models.

The Gymnasium and PettingZoo forms of one env have the same per-agent spaces,
so any model runs in either mode (cross-evaluation); the result records the
model's ``algo`` and training env. A model whose spaces differ from the
env's (e.g. a highway model, observation ``(8, 13)``, on the intersection,
``(8, 14)``) raises ``ValueError`` naming both.

Episode ``k`` (0-based) is reset with seed ``seed + k``. With ``config=None``
a saved model's training config (from its ``run.json``) is used, otherwise
the env's defaults; an explicit ``config`` replaces it (use ``scenario`` to
pick one of free, lane-drop, lane-change, off-ramp, on-ramp).

Returned metrics (definitions in :mod:`icv_envs.experiments.metrics` and the
env modules), over all episodes: ``collisions``, ``exited``, ``left_road``,
``vehicles`` (highway envs) summed; ``mean_speed``, ``speed_fluctuation``, ``sim_seconds``
averaged; ``min_gap`` the smallest (None on the intersection, which does not
report it); ``episode_return`` the mean over episodes of the summed reward of
all agents (``all-agents``) or of the ego (``ego``), with
``episode_return_std``; ``episode_length`` the mean number of policy steps;
the env-specific metrics where the env reports them: ``lost``, ``spawned``,
``remaining``, ``queued``, ``not_spawned``, ``crashed_removed``,
``missed_exits``, ``wrong_exits``, ``cleared`` summed (``lost`` is a
bookkeeping check that must be 0), ``achieved_throughput`` (veh/h) averaged,
``mean_delay`` and ``mean_travel_time`` averaged over the episodes where a
vehicle cleared the box (None if none did); ``method``, the method whose
controller ``expert_action`` is (None on the highway-formation env, whose
expert is the formation expert); and ``per_episode``, the env's metrics of
each episode.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from gymnasium import spaces

from icv_envs._args import check_flag, check_int
from icv_envs.envs.highway_ramps import METHODS as _RAMP_METHODS
from icv_envs.envs.intersection import METHODS as _INTERSECTION_METHODS
from icv_envs.rl.envs import (EnvSpec, episode_finished, make_gym_env, make_parallel_env, parse_config,
                              resolve_env)
from icv_envs.rl.models import json_safe

__all__ = ["evaluate", "main", "build_parser", "add_arguments", "run", "NAMED_POLICIES", "REFERENCE_POLICIES",
           "EXPERT_METHODS", "policy_names"]

NAMED_POLICIES = ("expert", "zero", "random")
# env family -> the reference methods that can be named as a policy (each sets config["method"])
# (the envs' own method lists, so a method added to an env is a policy here too)
REFERENCE_POLICIES = {
    "highway_formation": (),
    "highway_ramps": tuple(_RAMP_METHODS),
    "intersection": tuple(_INTERSECTION_METHODS),
}
# env family -> the method "expert" stands for (None: the env has no method key)
EXPERT_METHODS = {"highway_formation": None, "highway_ramps": "formation", "intersection": "multi-vp"}
_ALL_REFERENCES = tuple(dict.fromkeys(m for ms in REFERENCE_POLICIES.values() for m in ms))
_SUM_KEYS = ("lost", "spawned", "cleared", "remaining", "queued", "not_spawned", "crashed_removed", "missed_exits",
             "wrong_exits")
_MEAN_KEYS = ("achieved_throughput", "mean_delay", "mean_travel_time")


def policy_names(env) -> list[str]:
    """The named policies ``env`` accepts (a model path is accepted too)."""
    return list(NAMED_POLICIES) + list(REFERENCE_POLICIES[resolve_env(env).family])


def _reference_config(spec: EnvSpec, name: str, config: dict) -> dict:
    """``config`` with ``method`` set for a reference policy name; ``ValueError``
    for a reference the env does not have, or a conflicting ``method``."""
    family = spec.family
    allowed = REFERENCE_POLICIES[family]
    if name not in allowed:
        where = [f for f, ms in REFERENCE_POLICIES.items() if name in ms]
        refs = ", ".join(allowed) if allowed else "none (its expert is the formation expert)"
        raise ValueError(
            f"policy {name!r} is a reference method of the {' / '.join(where)} env, not of env {spec.id!r} "
            f"({family}); allowed policies there: {', '.join(NAMED_POLICIES)}, reference methods: {refs}, "
            f"or a model path"
        )
    if config.get("method", name) != name:
        raise ValueError(f"policy {name!r} sets config method {name!r}, but config has method "
                         f"{config['method']!r}; drop the config key or use policy 'expert'")
    return dict(config, method=name)


def _check_drives(name: str, act_type) -> None:
    """The expert and the reference methods drive with the env's ``expert_action``
    (``[u_a, u_s]``): ``ValueError`` for an action type that has no form of it."""
    if (name == "expert" or name in _ALL_REFERENCES) and act_type.expert_action(np.zeros(2)) is None:
        raise ValueError(f"policy {name!r} drives with the env's continuous expert action [u_a, u_s], which action "
                         f"type {act_type.name!r} cannot take; allowed with {act_type.name}: zero, random or a "
                         f"model path")


def _random_actions(rng, space, n: int) -> np.ndarray:
    """``n`` uniform actions of ``space`` (continuous: float32 in ``[low, high]``)."""
    if isinstance(space, spaces.Discrete):
        return space.start + rng.integers(space.n, size=n)
    return rng.uniform(space.low, space.high, (n, *space.shape)).astype(np.float32)


def _load_policy(policy):
    """``(name, LoadedModel | None)``."""
    if isinstance(policy, str) and (policy in NAMED_POLICIES or policy in _ALL_REFERENCES):
        return policy, None
    if not isinstance(policy, (str, Path)) or str(policy) == "":
        raise ValueError(f"policy {policy!r} is invalid; allowed: {', '.join(NAMED_POLICIES + _ALL_REFERENCES)} "
                         f"(the reference methods on their envs) or a model path")
    from icv_envs.rl.models import load_model

    return str(policy), load_model(policy)


def evaluate(env_id_or_module, policy, episodes: int = 5, seed: int = 0, config: dict | None = None,
             out=None, deterministic: bool = True) -> dict:
    """Run ``episodes`` episodes (seeds ``seed``, ``seed + 1``, ...) and return
    the metrics dict (see the module docstring); with ``out``, also write
    ``out/eval.json``."""
    spec = resolve_env(env_id_or_module)
    episodes = check_int("episodes", episodes, 1)
    seed = check_int("seed", seed, 0)
    if config is not None and not isinstance(config, dict):
        raise ValueError(f"config must be a dict or None, got {type(config).__name__}")
    check_flag("deterministic", deterministic)
    name, model = _load_policy(policy)
    if config is None:
        config = dict(model.meta.get("config") or {}) if model is not None else {}
    config = dict(config)
    if name in _ALL_REFERENCES:
        config = _reference_config(spec, name, config)
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
        "method": per_episode[0].get("method", EXPERT_METHODS[spec.family]) if per_episode else None,
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
        _check_drives(name, env.core._act_type)
        rows = []
        for ep in range(episodes):
            obs, infos = env.reset(seed=seed + ep)
            total, steps = 0.0, 0
            while not episode_finished(env):
                agents = list(env.agents)
                if not agents:  # open road: nobody on it now, more vehicles due
                    actions = {}
                elif name == "expert" or name in _ALL_REFERENCES:
                    # (the expert's [u_a, u_s] in the env's action type: FormationResidual's is the zero
                    # residual; until stop 45 the raw [u_a, u_s] was sent as the residual, not the expert)
                    to_action = env.core._act_type.expert_action
                    if all("expert_action" in infos.get(a, {}) for a in agents):
                        actions = {a: to_action(infos[a]["expert_action"]) for a in agents}
                    else:
                        ex = env.expert_actions()
                        actions = {a: to_action(ex[a]) for a in agents}
                elif name == "zero":
                    actions = {a: env.core._act_type.idle_action() for a in agents}
                elif name == "random":
                    u = _random_actions(rng, act_space, len(agents))
                    actions = {a: u[i] for i, a in enumerate(agents)}
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
        _check_drives(name, env.unwrapped._act_type)
        rows = []
        for ep in range(episodes):
            obs, info = env.reset(seed=seed + ep)
            total, steps, done = 0.0, 0, False
            while not done:
                if name == "expert" or name in _ALL_REFERENCES:
                    core = env.unwrapped
                    action = info.get("expert_action")
                    if action is None:  # (expert_in_info False: from the expert itself; it drove zeros until stop 45)
                        row = core._ego_row()
                        action = core.expert_actions()[row] if row >= 0 else np.zeros(2, dtype=np.float32)
                    action = core._act_type.expert_action(action)
                elif name == "zero":
                    action = env.unwrapped._act_type.idle_action()
                elif name == "random":  # (a batch of one: the same draws as rng.uniform(low, high))
                    action = _random_actions(rng, space, 1)[0]
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
        "episode_return": float(ret.mean()),
        "episode_return_std": float(ret.std()),
        "episode_length": float(np.mean(col("episode_length"))),
        "sim_seconds": float(np.mean(col("sim_seconds"))),
    }
    for k in ("vehicles",) + _SUM_KEYS:  # where the env reports them
        if any(k in r for r in rows):
            res[k] = int(sum(col(k)))
    for k in _MEAN_KEYS:
        if any(k in r for r in rows):
            vals = col(k)
            res[k] = float(np.mean(vals)) if vals else None
    return res


# ---------------------------------------------------------------------- CLI
def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The ``evaluate`` arguments (for wiring as ``icv-envs evaluate``)."""
    p.add_argument("--env", required=True,
                   help="Gymnasium id (ego mode) or PettingZoo id / module (all agents), e.g. "
                        "icv_envs/HighwayFormation-v0, icv_envs/highway_formation-v0, highway_formation_v0, "
                        "highway_ramps_v0, icv_envs/intersection-v0, intersection_v0")
    p.add_argument("--policy", default="expert",
                   help="expert, zero, random, a reference method (idm, lane-lp on the highway-ramps env; "
                        "single-vp, fcfs on the intersection env), or a model directory / model.zip from baselines/")
    p.add_argument("--episodes", type=int, default=5, help="number of episodes (default 5)")
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
