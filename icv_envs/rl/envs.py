"""Resolve an env name to a Gymnasium id or a PettingZoo module, and build it.

Accepted names:

* Gymnasium ids of this package (:data:`icv_envs.GYM_IDS`), e.g.
  ``icv_envs/HighwayFormation-v0``: single-agent (one learned ego among
  expert-driven ICVs);
* PettingZoo ids (:data:`icv_envs.PETTINGZOO_IDS`), e.g.
  ``icv_envs/highway_formation-v0``, or the module's name in any of the forms
  ``highway_formation_v0``, ``icv_envs.highway_formation_v0``,
  ``icv_envs.envs.highway_formation_v0``: every ICV an agent.

Anything else raises ``ValueError`` listing the known names.
"""

from __future__ import annotations

import importlib
import json
from dataclasses import dataclass
from pathlib import Path

import icv_envs

__all__ = ["EnvSpec", "resolve_env", "known_envs", "make_gym_env", "make_parallel_env", "parse_config"]


@dataclass(frozen=True)
class EnvSpec:
    kind: str  # "gym" or "pettingzoo"
    id: str  # canonical id (Gymnasium id or PettingZoo id)
    module: str | None = None  # PettingZoo: the module with parallel_env()

    @property
    def is_multi_agent(self) -> bool:
        return self.kind == "pettingzoo"


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


def make_gym_env(spec: EnvSpec | str, config: dict | None = None, render_mode: str | None = None):
    """``gym.make(id, config=config)`` for a Gymnasium id of this package."""
    import gymnasium as gym

    spec = resolve_env(spec)
    if spec.kind != "gym":
        raise ValueError(f"env {spec.id!r} is a PettingZoo env; a Gymnasium id is needed here: "
                         f"{', '.join(sorted(icv_envs.GYM_IDS))}")
    return gym.make(spec.id, config=dict(config or {}), render_mode=render_mode)


def make_parallel_env(spec: EnvSpec | str, config: dict | None = None, render_mode: str | None = None):
    """``module.parallel_env(**config)`` for a PettingZoo env of this package."""
    spec = resolve_env(spec)
    if spec.kind != "pettingzoo":
        raise ValueError(f"env {spec.id!r} is a Gymnasium env; a PettingZoo env is needed here: "
                         f"{', '.join(sorted(icv_envs.PETTINGZOO_IDS))}")
    module = importlib.import_module(spec.module)
    return module.parallel_env(render_mode=render_mode, **dict(config or {}))


def parse_config(text) -> dict:
    """``--config`` value: a JSON object, or the path of a JSON file holding one
    (None or empty: ``{}``)."""
    if text is None or text == "":
        return {}
    if isinstance(text, dict):
        return dict(text)
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
