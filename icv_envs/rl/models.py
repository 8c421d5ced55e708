"""The model format of the ``baselines/`` scripts and its loader.

Every script writes, into its ``--out`` directory,

* ``model.zip``: a Stable-Baselines3 PPO model (``PPO.load``-able). The
  behaviour-cloning baseline stores its network as the actor of an SB3 PPO
  ``MlpPolicy`` too (the mean of the Gaussian is the cloned action), so the
  three baselines load the same way and a BC model can be fine-tuned with PPO;
* ``run.json``: ``{"algo": "ppo_single" | "ppo_shared" | "bc_expert",
  "env": <canonical id>, "env_kind": "gym" | "pettingzoo", "config": {...},
  "observation_shape": [...], "action_shape": [...], "args": {...},
  "train": {...}, "eval": {...}}``; enough to rebuild the env.

:func:`load_model` accepts the directory, the ``model.zip`` path, or the path
without ``.zip``; ``run.json`` next to the model is optional (without it the
model counts as a generic SB3 model).

**Ensembles** (``algo: "ensemble"``, written by :func:`write_ensemble`): a
directory with only a ``run.json`` naming member model directories
(``"members"``, relative to the ensemble's directory or absolute). It acts
by the mean of its members' deterministic actions (continuous actions:
the plain average of independently trained regressors, which lowers the
variance between training seeds), or for discrete actions by soft voting
(the action of largest mean probability over the members; ties go to the
lowest action index). Every member must have the same
env, config and spaces.
"""

from __future__ import annotations

import json
import math
import os
import platform
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["LoadedModel", "LoadedEnsemble", "load_model", "resolve_model_path", "write_ensemble",
           "ensemble_member_dirs", "write_run_json", "json_safe", "platform_info"]

ALGOS = ("ppo_single", "ppo_shared", "bc_expert", "ensemble")


def resolve_model_path(path) -> tuple[Path, Path | None]:
    """``(model.zip, run.json or None)`` for a model directory or file;
    ``ValueError`` if there is no model there."""
    p = Path(path)
    if p.is_dir():
        z = p / "model.zip"
        if not z.is_file() and _is_ensemble(p):
            return p / "run.json", p / "run.json"
        if not z.is_file():
            raise ValueError(f"policy directory {str(p)!r} holds no model.zip; allowed: expert, zero, random, or a "
                             f"directory / model.zip written by baselines/ppo_single.py, ppo_shared.py or "
                             f"bc_expert.py")
    elif p.is_file():
        z = p
    elif p.with_name(p.name + ".zip").is_file():
        z = p.with_name(p.name + ".zip")
    else:
        raise ValueError(f"policy {str(path)!r} is neither a known policy nor an existing path; allowed: expert, zero, "
                         f"random, or a directory / model.zip written by baselines/ppo_single.py, ppo_shared.py or "
                         f"bc_expert.py")
    meta = z.parent / "run.json"
    return z, meta if meta.is_file() else None


@dataclass
class LoadedModel:
    """A saved policy: ``act(obs_batch) -> actions`` (deterministic by default)."""

    path: Path
    model: object
    meta: dict = field(default_factory=dict)

    @property
    def algo(self) -> str:
        return str(self.meta.get("algo", "sb3"))

    @property
    def observation_space(self):
        return self.model.observation_space

    @property
    def action_space(self):
        return self.model.action_space

    def act(self, obs: np.ndarray, deterministic: bool = True) -> np.ndarray:
        """Actions for a batch of observations ``(n, *obs_shape)``, clipped to
        the action space."""
        obs = np.asarray(obs, dtype=np.float32)
        if len(obs) == 0:
            return np.zeros((0, *self.action_space.shape), dtype=np.float32)
        actions, _ = self.model.predict(obs, deterministic=deterministic)
        return np.asarray(actions, dtype=np.float32).reshape(len(obs), *self.action_space.shape)

    def check_spaces(self, env_name: str, obs_space, act_space) -> None:
        """``ValueError`` naming both if the model was built for other spaces."""
        mo, ma = tuple(self.observation_space.shape or ()), tuple(self.action_space.shape or ())
        eo, ea = tuple(obs_space.shape or ()), tuple(act_space.shape or ())
        if mo != eo or ma != ea or type(self.action_space).__name__ != type(act_space).__name__:
            raise ValueError(
                f"model {str(self.path)!r} was built for observation shape {mo} and action space "
                f"{type(self.action_space).__name__}{ma}, but env {env_name!r} (with this config) has observation "
                f"shape {eo} and action space {type(act_space).__name__}{ea}"
            )


def _is_ensemble(d: Path) -> bool:
    try:
        return json.loads((d / "run.json").read_text()).get("algo") == "ensemble"
    except (OSError, json.JSONDecodeError, AttributeError):
        return False


class LoadedEnsemble(LoadedModel):
    """Members' mean deterministic action, or soft vote for discrete actions (module docstring)."""

    def __init__(self, path: Path, members: list, meta: dict) -> None:
        super().__init__(path, members[0].model, meta)
        self.members = members

    def act(self, obs: np.ndarray, deterministic: bool = True) -> np.ndarray:
        if not deterministic:
            raise ValueError(f"ensemble {str(self.path)!r} acts by its members' mean action; deterministic=False "
                             f"is not defined for it (allowed: deterministic=True)")
        obs = np.asarray(obs, dtype=np.float32)
        if type(self.action_space).__name__ == "Discrete":
            if len(obs) == 0:
                return np.zeros(0, dtype=np.int64)
            import torch

            probs = 0.0
            with torch.no_grad():
                for m in self.members:
                    t, _ = m.model.policy.obs_to_tensor(obs)
                    probs = probs + m.model.policy.get_distribution(t).distribution.probs.cpu().numpy()
            return np.argmax(probs, axis=1).astype(np.int64)
        acts = [m.act(obs, True) for m in self.members]
        return np.mean(acts, axis=0, dtype=np.float64).astype(np.float32)


def ensemble_member_dirs(ensemble_dir, meta: dict) -> list[Path]:
    """The member directories named in an ensemble's ``run.json`` (relative to ``ensemble_dir`` or absolute)."""
    return [Path(n) if Path(n).is_absolute() else Path(ensemble_dir) / n for n in meta.get("members") or []]


def _check_member(run_json: Path, name, d: Path) -> None:
    """``ValueError`` naming the ensemble member ``name`` (directory ``d``) unless it is a saved model."""
    if d.is_dir():
        if (d / "model.zip").is_file():
            return
        why = "is itself an ensemble" if _is_ensemble(d) else "holds no model.zip"
    elif d.is_file() or d.with_name(d.name + ".zip").is_file():
        return
    else:
        why = "does not exist"
    where = "" if str(d) == str(name) else f" ({str(d)!r})"
    raise ValueError(f"{str(run_json)!r}: ensemble member {name!r}{where} {why}; allowed: the directory (or "
                     f"model.zip) of a single model written by the baselines/ scripts")


def _load_ensemble(run_json: Path, meta: dict) -> LoadedEnsemble:
    names = meta.get("members")
    if not isinstance(names, list) or len(names) < 2:
        raise ValueError(f"{str(run_json)!r}: an ensemble needs a list of at least two member directories "
                         f"under 'members', got {names!r}")
    members = []
    for n, d in zip(names, ensemble_member_dirs(run_json.parent, meta)):
        _check_member(run_json, n, d)
        m = load_model(d)
        if isinstance(m, LoadedEnsemble):
            raise ValueError(f"{str(run_json)!r}: member {n!r} is itself an ensemble; allowed: single models")
        members.append(m)
    first = members[0]
    if type(first.action_space).__name__ not in ("Box", "Discrete"):
        raise ValueError(f"{str(run_json)!r}: an ensemble averages continuous actions or votes on discrete ones; "
                         f"member {names[0]!r} has {type(first.action_space).__name__} actions "
                         f"(allowed: Box, Discrete)")
    for n, m in zip(names[1:], members[1:]):
        same = (m.meta.get("env") == first.meta.get("env") and m.meta.get("config") == first.meta.get("config")
                and m.observation_space.shape == first.observation_space.shape
                and m.action_space.shape == first.action_space.shape
                and type(m.action_space).__name__ == type(first.action_space).__name__
                and getattr(m.action_space, "n", None) == getattr(first.action_space, "n", None))
        if not same:
            raise ValueError(f"{str(run_json)!r}: member {n!r} differs from {names[0]!r} in env, config or spaces "
                             f"(env {m.meta.get('env')!r} vs {first.meta.get('env')!r}); allowed: members trained "
                             f"on one env and config")
    return LoadedEnsemble(run_json, members, meta)


def write_ensemble(out, members) -> Path:
    """An ensemble directory ``out`` of the model directories ``members`` (a
    list or tuple of paths, stored relative to ``out``); the members are
    loaded once to check them before anything is written. ``run.json``
    carries the first member's env, config and spaces. ``out`` must not hold
    a model (``model.zip`` or a model's ``run.json``); an ensemble's
    ``run.json`` there is replaced."""
    if not isinstance(members, (list, tuple)) or not all(isinstance(m, (str, os.PathLike)) for m in members):
        raise ValueError(f"members = {members!r}; allowed: a list or tuple of at least two model directories")
    out = Path(out)
    if (out / "model.zip").exists() or ((out / "run.json").exists() and not _is_ensemble(out)):
        raise ValueError(f"out = {str(out)!r} holds a model (model.zip or its run.json); allowed: a new directory "
                         f"or an ensemble's directory")
    # absolute member paths for the check: ``out`` may not exist yet
    ens = _load_ensemble(out / "run.json", {"algo": "ensemble", "members": [str(Path(m).resolve()) for m in members]})
    out.mkdir(parents=True, exist_ok=True)
    rel = [os.path.relpath(Path(m).resolve(), out.resolve()) for m in members]
    meta = {"algo": "ensemble", "members": rel}
    first = ens.members[0].meta
    meta.update({k: first.get(k) for k in ("env", "env_kind", "env_module", "config", "scenarios",
                                           "observation_shape", "action_shape") if k in first})
    meta["member_algos"] = [m.algo for m in ens.members]
    meta["platform"] = platform_info()
    return write_run_json(out, meta)


def load_model(path) -> LoadedModel:
    """Load a model written by one of the ``baselines/`` scripts (or any SB3
    PPO zip), or an ensemble of such models (:func:`write_ensemble`)."""
    z, meta_path = resolve_model_path(path)
    meta = {}
    if meta_path is not None:
        try:
            meta = json.loads(meta_path.read_text())
        except json.JSONDecodeError as exc:
            raise ValueError(f"{str(meta_path)!r} is not valid JSON: {exc}") from None
    if z == meta_path and meta.get("algo") == "ensemble":
        return _load_ensemble(meta_path, meta)
    try:
        from stable_baselines3 import PPO
    except ImportError as exc:  # pragma: no cover
        raise ValueError(f"loading a model needs stable-baselines3 and torch: pip install torch==2.13.0 && "
                         f"pip install stable-baselines3 ({exc})") from None
    import torch

    torch.set_num_threads(1)
    try:
        model = PPO.load(str(z), device="cpu")
    except Exception as exc:  # noqa: BLE001 - a corrupt or foreign file
        raise ValueError(f"cannot load {str(z)!r} as a Stable-Baselines3 PPO model: "
                         f"{type(exc).__name__}: {exc}") from None
    return LoadedModel(z, model, meta)


def json_safe(obj):
    """Replace NaN/inf by None and numpy scalars/arrays by Python values."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_run_json(out, meta: dict) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    p = out / "run.json"
    p.write_text(json.dumps(json_safe(meta), indent=2))
    return p


def platform_info() -> dict:
    info = {"python": platform.python_version(), "numpy": np.__version__}
    try:
        import stable_baselines3
        import torch

        info.update({"torch": torch.__version__, "stable_baselines3": stable_baselines3.__version__})
    except ImportError:  # pragma: no cover
        pass
    return info
