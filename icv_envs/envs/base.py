"""What every environment of this package shares: a highway-env
:class:`~highway_env.envs.common.abstract.AbstractEnv` whose vehicles are all
agents, driven through one action space.

Subclasses provide the simulation (``_reset``, ``_ma_advance``,
``_observe_rows``, ``_ma_infos``, ``expert_actions``, ``_sync_render_road``),
the vehicle arrays (:meth:`_vehicles`, anything with ``n`` and a sorted
``vid``), the observation columns (``OBS_FEATURES``) and the viewer
(:meth:`_make_viewer`). This class holds the parts that are the same for all:
spaces, the Gymnasium single-ego ``reset``/``step``, the multi-agent action
checks of ``ma_step``, and rendering.
"""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from highway_env.envs.common.abstract import AbstractEnv

__all__ = ["IcvAgentsEnv"]


class IcvAgentsEnv(AbstractEnv):
    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}
    OBS_FEATURES: tuple = ()

    def __init__(self, config: dict | None = None, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is invalid; allowed: {self.metadata['render_modes']} or None")
        self.world = None
        self.expert = None
        self._ma_mode = False
        self.possible_agents: list[str] = []
        super().__init__(config, render_mode)

    # ------------------------------------------------------------- subclasses
    def _vehicles(self):
        """The vehicle arrays of the current world (``n``, sorted ``vid``)."""
        raise NotImplementedError

    def _make_viewer(self):
        raise NotImplementedError

    # ------------------------------------------------------------------ spaces
    def define_spaces(self) -> None:
        V = int(self.config["observation"]["vehicles_count"])
        self.observation_space = spaces.Box(-1.0, 1.0, (V, len(self.OBS_FEATURES)), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.observation_type = _ObservationStub(self)
        self.action_type = None

    def state_space_for(self, n_slots: int) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (n_slots, len(self.OBS_FEATURES)), dtype=np.float32)

    # ------------------------------------------------------------- multi-agent
    def _check_action(self, action, who: str = "agent") -> np.ndarray:
        arr = np.asarray(action, dtype=np.float64)
        if arr.shape != (2,):
            raise ValueError(f"action of {who} has shape {arr.shape}; allowed: shape (2,) [acceleration, steering] in [-1, 1]")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"action of {who} = {arr.tolist()} holds NaN or inf; allowed: finite values in [-1, 1]")
        return np.clip(arr, -1.0, 1.0)

    def ma_step(self, actions: dict):
        """Multi-agent step: ``actions`` maps live agent names to actions.
        Actions are clipped to [-1, 1]; a wrong shape or a NaN raises
        ``ValueError`` naming the agent; agents left out raise too unless
        ``missing_action="expert"``."""
        veh = self._vehicles()
        live = [f"icv_{v}" for v in veh.vid.tolist()]
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict {{agent: action}}, got {type(actions).__name__}")
        missing = []
        if len(actions) != len(live) or actions.keys() != set(live):  # the usual case is one set comparison
            live_set = set(live)
            unknown = [a for a in actions if a not in live_set]
            if unknown:
                raise ValueError(f"actions for agents that are not live: {unknown[:5]}; live agents: {live[:5]}...")
            missing = [a for a in live if a not in actions]
        if missing and self.config["missing_action"] == "error":
            raise ValueError(
                f"no action for live agents {missing[:5]} ({len(missing)} missing); pass an action for every agent "
                f"or configure missing_action='expert'"
            )
        acts = np.zeros((veh.n, 2), dtype=np.float64)
        if missing:
            acts[:] = self.expert_actions()
            given = [i for i, a in enumerate(live) if a in actions]
            names = [live[i] for i in given]
        else:
            given, names = slice(None), live
        if names:
            acts[given] = self._check_actions(names, [actions[a] for a in names])
        return self._ma_advance(acts)

    def _check_actions(self, names: list, values: list) -> np.ndarray:
        """All agents' actions checked and converted at once: one array, one
        finiteness check, clipped to [-1, 1]. Anything the fast path cannot
        take as one real ``(n, 2)`` array (a wrong shape, a string, a dict,
        complex or boolean values) goes through :meth:`_check_action` agent by
        agent, whose error names the agent; non-finite values raise naming
        every bad agent."""
        try:
            arr = np.array(values)
        except (ValueError, TypeError):
            arr = None
        if arr is None or arr.shape != (len(names), 2) or arr.dtype.kind not in "fiu":
            arr = np.stack([self._check_action(v, a) for a, v in zip(names, values)])
        else:
            arr = arr.astype(np.float64, copy=False)
        finite = np.isfinite(arr).all(axis=1)
        if not finite.all():
            bad = [names[i] for i in np.flatnonzero(~finite)]
            raise ValueError(
                f"actions of {len(bad)} agent(s) hold NaN or inf: {bad[:10]}"
                f"{' ...' if len(bad) > 10 else ''} (first: {arr[~finite][0].tolist()}); "
                f"allowed: finite values in [-1, 1]"
            )
        return np.clip(arr, -1.0, 1.0)
        return self._ma_advance(acts)

    # ------------------------------------------- array -> PettingZoo dicts
    # The env builds observations, rewards and infos as arrays over its rows;
    # these turn them into the per-agent dicts once, at the API's edge.
    @staticmethod
    def _agent_dicts(agents: list, obs: np.ndarray, rew: np.ndarray, term: np.ndarray, trunc) -> tuple:
        """``(observations, rewards, terminations, truncations)`` dicts from
        row arrays (``trunc`` an array or one bool for all)."""
        observations = dict(zip(agents, obs))
        rewards = dict(zip(agents, np.asarray(rew, dtype=np.float64).tolist()))
        terms = dict(zip(agents, np.asarray(term, dtype=bool).tolist()))
        if np.ndim(trunc) == 0:
            truncs = dict.fromkeys(agents, bool(trunc))
        else:
            truncs = dict(zip(agents, np.asarray(trunc, dtype=bool).tolist()))
        return observations, rewards, terms, truncs

    @staticmethod
    def _info_dicts(agents: list, columns: dict, expert: np.ndarray | None = None, parts: dict | None = None) -> dict:
        """One info dict per agent from per-agent columns (lists aligned with
        ``agents``), the expert's action rows (one copy, one row each) and the
        reward components (``info["rewards"]``)."""
        keys = list(columns)
        vals = [columns[k] for k in keys]
        if expert is not None:
            keys.append("expert_action")
            vals.append(list(np.array(expert, copy=True)))
        pk = list(parts) if parts else []
        vals += [np.asarray(parts[k], dtype=np.float64).tolist() for k in pk]
        return _dict_builder(tuple(keys), tuple(pk))(agents, vals)

    @staticmethod
    def _realign_rows(before_vid: np.ndarray, values: np.ndarray, vid: np.ndarray) -> np.ndarray:
        """``values`` (rows aligned with the sorted ids ``before_vid``) moved
        to the rows of the sorted ids ``vid``; zeros for ids not in
        ``before_vid`` (vehicles that appeared since)."""
        out = np.zeros((len(vid),) + values.shape[1:], dtype=values.dtype)
        if len(before_vid) and len(vid):
            pos = np.minimum(np.searchsorted(before_vid, vid), len(before_vid) - 1)
            ok = before_vid[pos] == vid
            out[ok] = values[pos[ok]]
        return out

    # ------------------------------------------------------- gymnasium (ego)
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        gym.Env.reset(self, seed=seed, options=options)
        if options and "config" in options:
            self.configure(options["config"])
        self.update_metadata()
        self.define_spaces()
        self.time = self.steps = 0
        self.done = False
        self._reset()
        obs, info = self._ego_obs_info()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def _ego_row(self) -> int:
        veh = self._vehicles()
        r = int(np.searchsorted(veh.vid, self._ego_vid))
        return r if r < veh.n and veh.vid[r] == self._ego_vid else -1

    def _ego_obs_info(self):
        r = self._ego_row()
        if r < 0:
            return np.zeros(self.observation_space.shape, dtype=np.float32), {}
        obs = self._observe_rows(np.array([r]))[0]
        info = self._ma_infos([f"icv_{self._ego_vid}"], np.array([r]), {})[f"icv_{self._ego_vid}"]
        return obs, info

    def step(self, action):
        """Single-agent step: ``action`` drives the ego, every other vehicle
        follows the environment's expert."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        if self._ego_done:
            raise RuntimeError("the ego's episode has ended (terminated or truncated): call reset()")
        act = self._check_action(action, "the ego")
        veh = self._vehicles()
        acts = self.expert_actions().astype(np.float64).copy() if veh.n else np.zeros((0, 2))
        r = self._ego_row()
        if r >= 0:
            acts[r] = act
        observations, rewards, terms, truncs, infos = self._ma_advance(acts)
        a = f"icv_{self._ego_vid}"
        obs = observations.get(a, np.zeros(self.observation_space.shape, dtype=np.float32))
        reward = float(rewards.get(a, 0.0))
        terminated = bool(terms.get(a, True))
        truncated = bool(truncs.get(a, False))
        info = infos.get(a, {})
        info["ego_present"] = self._ego_row() >= 0
        if terminated or truncated:
            self._ego_done = True
        return obs, reward, terminated, truncated, info

    # -------------------------------------------------------------- rendering
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.world is None:
            raise RuntimeError("call reset() before render()")
        self._sync_render_road()
        if self.viewer is None:
            self.viewer = self._make_viewer()
        self.enable_auto_render = True
        self.viewer.display()
        if not self.viewer.offscreen:
            self.viewer.handle_events()
        if self.render_mode == "rgb_array":
            return self.viewer.get_image()
        return None

    def _automatic_rendering(self) -> None:
        if self.viewer is not None and self.enable_auto_render:
            if self._record_video_wrapper:
                self._sync_render_road()
                self._record_video_wrapper._capture_frame()
            else:
                self.render()


@functools.lru_cache(maxsize=64)
def _dict_builder(keys: tuple, reward_keys: tuple):
    """A function ``(agents, columns) -> {agent: {key: value, ...}}`` for
    these keys, written as one dict display per agent (about twice as fast
    as ``dict(zip(keys, row))``; CPython builds a literal in one opcode). The
    keys are the envs' own info names, never user input; ``repr`` quotes
    them. ``reward_keys`` go into a nested ``"rewards"`` dict."""
    names = [f"c{i}" for i in range(len(keys) + len(reward_keys))]
    items = [f"{k!r}: {v}" for k, v in zip(keys, names)]
    if reward_keys:
        inner = ", ".join(f"{k!r}: {v}" for k, v in zip(reward_keys, names[len(keys):]))
        items.append(f"'rewards': {{{inner}}}")
    src = (f"lambda agents, cols: {{a: {{{', '.join(items)}}} "
           f"for a, {', '.join(names) + ','} in zip(agents, *cols)}}")
    return eval(src, {})  # noqa: S307 - the source is built from the repr of the envs' constant key names


class _ObservationStub:
    """Stands in for highway-env's observation type where its viewer expects one."""

    def __init__(self, env):
        self.env = env

    def observe(self):  # pragma: no cover - highway-env compatibility
        return self.env._ego_obs_info()[0]

    def space(self):  # pragma: no cover
        return self.env.observation_space
