"""Ray RLlib adapter for the PettingZoo parallel envs of this package.

RLlib's :class:`ray.rllib.env.wrappers.pettingzoo_env.ParallelPettingZooEnv`
almost fits; :class:`IcvParallelPettingZooEnv` subclasses it and fixes what
does not:

* ``possible_agents``: RLlib builds it (and ``agents``, and the space dicts)
  from ``set(env.agents)`` after one reset, so its order is arbitrary and an
  agent absent at the first reset (a later on-ramp spawn) has no space. Here
  they come from the env's ``possible_agents``, in order, with
  ``observation_spaces`` / ``action_spaces`` for every possible agent.
* ``render()``: RLlib calls ``par_env.render(self.render_mode)``; PettingZoo's
  ``render()`` takes no mode (the mode is fixed at construction). Here
  ``render()`` calls ``par_env.render()``.
* ``agents``: updated after every reset / step (RLlib's wrapper never
  updates it): the env's live agents plus those that finished in the last
  step. RLlib's env check (``check_multiagent_environments``) requires every
  key of a step's dicts to be in ``agents``, while PettingZoo drops an agent
  from ``agents`` on the step that terminates or truncates it.
* episode end: RLlib's wrapper sets ``__all__`` to ``all(flags.values())``
  separately for terminations and truncations, so a last step where some
  agents crash and the rest are truncated ends the episode on neither flag,
  and RLlib steps an env with no agents once more. Here the episode is over
  when the env has no live agents (what :class:`icv_envs.rl.ParallelVecEnv`
  uses too): ``truncated["__all__"]`` if time ran out or any agent of the
  last step was truncated, else ``terminated["__all__"]``. Per-agent flags
  are passed through unchanged (RLlib bootstraps truncated agents).

Agents joining mid-episode (on-ramp spawns) and leaving (crash, exit, end of
road) need nothing more: RLlib's ``MultiAgentEpisode`` handles agents that
appear and finish at any step.

:func:`evaluate_checkpoint` runs a policy saved by ``baselines/rllib_shared.py``
(its run directory, its ``checkpoint/`` or the RLModule directory) on the
PettingZoo env, every agent driven by the policy's mean action, and returns
the metrics of :func:`icv_envs.rl.evaluate.evaluate`; :func:`load_rllib_policy`
gives the policy as ``act(obs_batch) -> actions``. Neither needs
``ray.init()``.

Needs ``pip install "ray[rllib]"`` (``pip install -e ".[rllib]"``); importing
this module without Ray raises ``ImportError`` saying so.
"""

from __future__ import annotations

try:
    import gymnasium as gym
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
except ImportError as exc:  # pragma: no cover - depends on the extra
    raise ImportError(f"icv_envs.rl.rllib_compat needs Ray RLlib: pip install \"ray[rllib]\" ({exc})") from exc

import json
import time
from pathlib import Path

import numpy as np

from icv_envs.rl.envs import make_parallel_env, resolve_env

__all__ = ["ENV_NAME", "IcvParallelPettingZooEnv", "evaluate_checkpoint", "load_rllib_policy", "make_rllib_env"]

ENV_NAME = "icv_envs_pettingzoo"  # the name make_rllib_env is registered under by baselines/rllib_shared.py


class IcvParallelPettingZooEnv(ParallelPettingZooEnv):
    """RLlib ``MultiAgentEnv`` over a PettingZoo parallel env of this package
    (see the module docstring for what differs from RLlib's wrapper)."""

    def __init__(self, env) -> None:
        super().__init__(env)  # resets env once (unseeded), as RLlib's wrapper does
        self.possible_agents = list(env.possible_agents)
        self._agent_ids = set(self.possible_agents)
        self.agents = list(env.agents)
        self.observation_spaces = {a: env.observation_space(a) for a in self.possible_agents}
        self.action_spaces = {a: env.action_space(a) for a in self.possible_agents}
        self.observation_space = gym.spaces.Dict(self.observation_spaces)  # old API stack
        self.action_space = gym.spaces.Dict(self.action_spaces)
        self.render_mode = getattr(env, "render_mode", None)

    def reset(self, *, seed=None, options=None):
        obs, infos = self.par_env.reset(seed=seed, options=options)
        self.agents = list(self.par_env.agents)
        return obs, dict(infos or {})

    def step(self, action_dict):
        obs, rew, term, trunc, infos = self.par_env.step(action_dict)
        term, trunc = dict(term), dict(trunc)
        live = set(self.par_env.agents) | set(obs)
        self.agents = [a for a in self.possible_agents if a in live]
        over = not self.par_env.agents
        time_up = bool(getattr(self.par_env, "episode_over", False))
        truncated = over and (time_up or any(trunc.values()))
        term["__all__"] = over and not truncated
        trunc["__all__"] = truncated
        return obs, rew, term, trunc, infos

    def render(self):
        return self.par_env.render()


def make_rllib_env(env_config: dict | None = None) -> IcvParallelPettingZooEnv:
    """RLlib env creator: ``env_config = {"env": <PettingZoo id or module>,
    "config": {...}, "render_mode": None}`` (all optional; default
    ``icv_envs/highway_formation-v0`` with its default config). Register it
    with ``ray.tune.registry.register_env(ENV_NAME, make_rllib_env)``."""
    env_config = dict(env_config or {})
    par = make_parallel_env(env_config.get("env", "icv_envs/highway_formation-v0"),
                            dict(env_config.get("config") or {}), render_mode=env_config.get("render_mode"))
    return IcvParallelPettingZooEnv(par)


# ---------------------------------------------------------------------- evaluation
MODULE_SUBDIR = Path("learner_group") / "learner" / "rl_module"


def _resolve_run(path, module_id: str) -> tuple[Path, dict]:
    """``(RLModule directory, run.json contents or {})`` of a run directory,
    a checkpoint directory or an RLModule directory."""
    p = Path(path)
    meta = {}
    for candidate in (p / "run.json", p.parent / "run.json"):
        if candidate.is_file():
            meta = json.loads(candidate.read_text())
            break
    for module in (p / "checkpoint" / MODULE_SUBDIR / module_id, p / MODULE_SUBDIR / module_id, p):
        if (module / "module_state.pkl").exists() or (module / "module_state").exists():
            return module, meta
    raise ValueError(f"{str(p)!r} holds no RLlib module {module_id!r}; allowed: a run directory written by "
                     f"baselines/rllib_shared.py, its checkpoint/ directory, or an RLModule directory")


def load_rllib_policy(path, module_id: str = "shared", deterministic: bool = True):
    """``(act, run_meta)``: ``act(obs_batch (n, *obs_shape)) -> actions (n, *act_shape)``
    from the RLModule of a saved run (observations are flattened as the
    ``FlattenObservations`` connector does; actions clipped to the action space)."""
    import torch
    from ray.rllib.core.columns import Columns
    from ray.rllib.core.rl_module.rl_module import RLModule

    module_dir, meta = _resolve_run(path, module_id)
    module = RLModule.from_checkpoint(str(module_dir))
    dist_cls = module.get_inference_action_dist_cls()
    space = module.action_space

    def act(obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        if len(obs) == 0:
            return np.zeros((0, *space.shape), dtype=np.float32)
        with torch.no_grad():
            out = module.forward_inference({Columns.OBS: torch.as_tensor(obs.reshape(len(obs), -1))})
            dist = dist_cls.from_logits(out[Columns.ACTION_DIST_INPUTS])
            a = (dist.to_deterministic() if deterministic else dist).sample().numpy()
        return np.clip(a.reshape(len(obs), *space.shape), space.low, space.high).astype(np.float32)

    return act, meta


def evaluate_checkpoint(path, episodes: int = 5, seed: int = 0, config: dict | None = None, env=None,
                        module_id: str = "shared", deterministic: bool = True) -> dict:
    """Run ``episodes`` episodes (seeds ``seed``, ``seed + 1``, ...) of the
    PettingZoo env with every agent driven by the saved policy; returns the
    metrics dict of :func:`icv_envs.rl.evaluate.evaluate` (``config=None``:
    the run's training config; ``env=None``: the run's env)."""
    from icv_envs.rl.evaluate import _aggregate
    from icv_envs.rl.models import json_safe

    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ValueError(f"episodes = {episodes!r} is invalid; allowed: an integer >= 1")
    act, meta = load_rllib_policy(path, module_id, deterministic)
    spec = resolve_env(env or meta.get("env", "icv_envs/highway_formation-v0"))
    if config is None:
        config = dict(meta.get("config") or {})
    t0 = time.perf_counter()
    par = make_parallel_env(spec, config)
    rows = []
    try:
        for ep in range(int(episodes)):
            obs, _ = par.reset(seed=seed + ep)
            total, steps = 0.0, 0
            while par.agents:
                agents = list(par.agents)
                acts = act(np.stack([obs[a] for a in agents]))
                obs, rew, _, _, _ = par.step({a: acts[i] for i, a in enumerate(agents)})
                total += float(sum(rew.values()))
                steps += 1
            m = dict(par.metrics())
            m.update({"seed": seed + ep, "episode_return": total, "episode_length": steps})
            rows.append(m)
    finally:
        par.close()
    res = _aggregate(rows)
    res.update({"env": spec.id, "env_kind": spec.kind, "mode": "all-agents", "policy": str(path),
                "algo": meta.get("algo", "rllib"), "trained_on": meta.get("env"), "episodes": int(episodes),
                "seed": seed, "config": config, "deterministic": bool(deterministic),
                "wall_seconds": time.perf_counter() - t0, "per_episode": rows})
    return json_safe(res)
