"""Resolve an env name to a Gymnasium id or a PettingZoo module, and build it.

Accepted names:

* Gymnasium ids of this package (:data:`icv_envs.GYM_IDS`), e.g.
  ``icv_envs/HighwayFormation-v0``: single-agent (one learned ego among
  expert-driven ICVs);
* PettingZoo ids (:data:`icv_envs.PETTINGZOO_IDS`), e.g.
  ``icv_envs/highway_formation-v0``, or the module's name in any of the forms
  ``highway_formation_v0``, ``icv_envs.highway_formation_v0``,
  ``icv_envs.envs.highway_formation_v0``: every ICV an agent.

Anything else raises ``ValueError`` listing the known names. The three env
families (:func:`env_family`) are ``highway_formation``
(``icv_envs/HighwayFormation-v0``, ``icv_envs/highway_formation-v0``,
``highway_formation_v0``), ``highway_ramps`` (``icv_envs/HighwayRamps-v0``,
``icv_envs/highway_ramps-v0``, ``highway_ramps_v0``) and ``intersection``
(``icv_envs/Intersection-v0``, ``icv_envs/intersection-v0``,
``intersection_v0``).

:func:`episode_finished` says when a PettingZoo episode of these envs is
over: on the open roads (ramps, intersection) vehicles keep arriving, so an
empty ``agents`` list alone does not end it; the time limit does.
"""

from __future__ import annotations

import importlib
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import icv_envs

__all__ = ["EnvSpec", "resolve_env", "known_envs", "make_gym_env", "make_parallel_env", "parse_config",
           "env_family", "episode_finished", "step_until_agents"]


@dataclass(frozen=True)
class EnvSpec:
    kind: str  # "gym" or "pettingzoo"
    id: str  # canonical id (Gymnasium id or PettingZoo id)
    module: str | None = None  # PettingZoo: the module with parallel_env()

    @property
    def is_multi_agent(self) -> bool:
        return self.kind == "pettingzoo"

    @property
    def family(self) -> str:
        """``highway_formation``, ``highway_ramps`` or ``intersection``."""
        return env_family(self)


def env_family(spec) -> str:
    """The env family of a name or :class:`EnvSpec`: the core module's name,
    ``highway_formation``, ``highway_ramps`` or ``intersection``."""
    spec = resolve_env(spec)
    if spec.kind == "gym":
        module = icv_envs.GYM_IDS[spec.id].split(":", 1)[0]
        return module.rsplit(".", 1)[-1]
    short = spec.module.rsplit(".", 1)[-1]
    return short[:-3] if short.endswith("_v0") else short


def known_envs() -> list[str]:
    """Every accepted name, Gymnasium ids first."""
    names = sorted(icv_envs.GYM_IDS)
    for pz_id, module in sorted(icv_envs.PETTINGZOO_IDS.items()):
        names += [pz_id, module.rsplit(".", 1)[-1]]
    return names


def resolve_env(name) -> EnvSpec:
    """The :class:`EnvSpec` of ``name`` (see the module docstring)."""
    if isinstance(name, EnvSpec):
        return name
    if not isinstance(name, str) or not name:
        raise ValueError(f"env {name!r} is not a string; known envs: {', '.join(known_envs())}")
    if name in icv_envs.GYM_IDS:
        return EnvSpec("gym", name)
    for pz_id, module in icv_envs.PETTINGZOO_IDS.items():
        short = module.rsplit(".", 1)[-1]
        if name in (pz_id, module, short, f"icv_envs.{short}"):
            return EnvSpec("pettingzoo", pz_id, module)
    raise ValueError(f"unknown env {name!r}; known envs: {', '.join(known_envs())}")


def _check_config(config) -> dict:
    """``config`` as a new dict: None or a dict (a mapping) of env config."""
    if config is not None and not isinstance(config, Mapping):
        raise ValueError(f"config = {config!r}; allowed: None or a dict of env config")
    return dict(config or {})


def make_gym_env(spec: EnvSpec | str, config: dict | None = None, render_mode: str | None = None):
    """``gym.make(id, config=config)`` for a Gymnasium id of this package."""
    import gymnasium as gym

    spec = resolve_env(spec)
    config = _check_config(config)
    if spec.kind != "gym":
        raise ValueError(f"env {spec.id!r} is a PettingZoo env; a Gymnasium id is needed here: "
                         f"{', '.join(sorted(icv_envs.GYM_IDS))}")
    return gym.make(spec.id, config=config, render_mode=render_mode)


def make_parallel_env(spec: EnvSpec | str, config: dict | None = None, render_mode: str | None = None):
    """``module.parallel_env(**config)`` for a PettingZoo env of this package."""
    spec = resolve_env(spec)
    config = _check_config(config)
    if spec.kind != "pettingzoo":
        raise ValueError(f"env {spec.id!r} is a Gymnasium env; a PettingZoo env is needed here: "
                         f"{', '.join(sorted(icv_envs.PETTINGZOO_IDS))}")
    module = importlib.import_module(spec.module)
    return module.parallel_env(render_mode=render_mode, **config)


def episode_finished(env) -> bool:
    """Whether the episode of a PettingZoo env of this package is over: live
    agents remain -> no; the time is up (``env.episode_over``) -> yes; no live
    agents -> yes unless more vehicles are still due (scheduled ``spawns`` of
    the highway-formation env; on the open roads, ramps and intersection,
    arrivals keep coming until the time is up). Envs without ``episode_over``
    end when ``agents`` is empty."""
    n = getattr(env, "num_agents", None)  # (PettingZoo's len(agents); ours counts without making the names)
    if n is None:  # (a wrapper without it)
        n = len(env.agents)
    if n:
        return False
    over = getattr(env, "episode_over", None)
    if over is None or over:
        return True
    core = getattr(env, "core", None)
    pending = getattr(core, "_pending_spawns", None)
    if pending is not None:  # highway formation: a closed road with scheduled spawns
        return not pending
    return False


def step_until_agents(env) -> list[tuple]:
    """While ``env`` has no live agents and its episode is not over
    (:func:`episode_finished`), advance it with ``step({})``. Returns the
    step results ``(obs, rewards, terms, truncs, infos)`` of those steps (the
    last holds the observations of the agents that appeared)."""
    results = []
    while not env.agents and not episode_finished(env):
        results.append(env.step({}))
    return results


def parse_config(text) -> dict:
    """``--config`` value: a JSON object, or the path of a JSON file holding one
    (None or empty: ``{}``); also a dict (copied) or a ``pathlib.Path`` of a JSON file."""
    if text is None or text == "":
        return {}
    if isinstance(text, dict):
        return dict(text)
    if isinstance(text, os.PathLike):
        p = Path(text)
        if not p.is_file():
            raise ValueError(f"--config file {str(p)!r} does not exist")
        src = p.read_text()
    elif not isinstance(text, str):
        raise ValueError(f"--config = {text!r}; allowed: None, a dict, a JSON object string, or the path of a "
                         f".json file")
    else:
        src = text
        p = Path(text)
        if not text.lstrip().startswith("{") and p.suffix == ".json":
            if not p.is_file():
                raise ValueError(f"--config file {text!r} does not exist")
            src = p.read_text()
    try:
        cfg = json.loads(src)
    except json.JSONDecodeError as exc:
        raise ValueError(f"--config is not valid JSON (or a path to a .json file): {exc}") from None
    if not isinstance(cfg, dict):
        raise ValueError(f"--config must be a JSON object, got {text!r}")
    return cfg
