"""What every environment of this package shares: a highway-env
:class:`~highway_env.envs.common.abstract.AbstractEnv` whose vehicles are all
agents, driven through one action space.

Subclasses provide the simulation (``_reset``, the hooks of the shared step:
``_new_events``, ``_controls``, ``_before_physics``, ``_after_frames``,
``_react``, ``_departed``, ``_after_removal``, ``_spawn_late``,
``_truncations``), the builders of what agents receive (``_features``,
``_rewards_rows``, ``_ma_infos``), the vehicle arrays (:meth:`_vehicles`,
anything with ``n``, ``crashed`` and a sorted ``vid``), the observation
columns (``OBS_FEATURES``), ``_sync_render_road`` and the viewer
(:meth:`_make_viewer`), and for the observation types the feature scales
(``_obs_scales``) and neighbour search (``_neighbours``). This class holds the
parts that are the same for all: the observation / action types and their
spaces (:mod:`icv_envs.envs.observations`, :mod:`icv_envs.envs.actions`), the multi-agent step (``ma_step``:
action checks and conversion; ``_ma_advance``: physics, the world's
reaction, observations, rewards, infos, departures, removals, spawns and the
expert's labels, in that order), ``ma_reset``, the expert cache and
rendering. The multi-agent step itself is
:class:`icv_envs.envs.agents_step.AgentsStep` (a mixin, from stop 43); its
array -> PettingZoo dict edge (the action check, the per-agent dicts, the
expert labels) is :class:`icv_envs.envs.dict_edge.DictEdge`; the Gymnasium single-ego
``reset``/``step`` over the same step is :class:`icv_envs.envs.ego.EgoEnv`.
"""

from __future__ import annotations

import copy

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from highway_env.envs.common.abstract import AbstractEnv

from icv_envs.envs.actions import action_factory, check_actions
from icv_envs.envs.agents_step import AgentsStep, StepRows
from icv_envs.envs.dict_edge import DictEdge
from icv_envs.envs.ego import EgoEnv
from icv_envs.envs.observations import observation_factory
from icv_envs.policies.formation_expert_many import compute_many

__all__ = ["IcvAgentsEnv", "StepRows", "check_actions"]


class IcvAgentsEnv(EgoEnv, AgentsStep, DictEdge, AbstractEnv):
    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}
    OBS_FEATURES: tuple = ()

    def __init__(self, config: dict | None = None, render_mode: str | None = None, **kwargs) -> None:
        # highway-env's AbstractEnv.__init__ without its final reset(): an env
        # is usable after reset() only (Gymnasium's contract), so step() and
        # render() before it raise "call reset() before ..."
        if kwargs:  # (gym.make(id, duration=5): Python's own TypeError did not say where config goes)
            raise TypeError(f"unknown keyword argument(s) {sorted(kwargs)}; the env takes config={{...}} and "
                            f"render_mode, as highway-env's: gym.make(id, config={{{next(iter(sorted(kwargs)))!r}: "
                            f"...}})")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is invalid; allowed: {self.metadata['render_modes']} or None")
        self.world = None
        self.expert = None
        self._ma_mode = False
        self._expert_cache = None
        self.render_mode = render_mode
        self.viewer = None
        self._record_video_wrapper = None
        self.enable_auto_render = False
        self.config = self.default_config()
        self.configure(config)
        self._render_due = False
        self.road = None
        self.controlled_vehicles = []
        self.action_type = None
        self.action_space = None
        self.observation_type = None
        self.observation_space = None
        self.define_spaces()
        self.time = 0
        self.steps = 0
        self.done = False
        self.possible_agents: list[str] = [f"icv_{i}" for i in range(self._n_possible_agents())]

    # ------------------------------------------------------------------ config
    #: attributes derived from the config by ``_validate_config`` (restored with it)
    _CONFIG_DERIVED: tuple = ()

    def configure(self, config: dict | None) -> None:
        """Apply ``config`` on top of the current config and validate the
        result; on an error the previous config is kept (so a failed
        ``reset(options={"config": ...})`` leaves the env as it was)."""
        saved = copy.deepcopy(self.config)
        derived = {k: self.__dict__[k] for k in self._CONFIG_DERIVED if k in self.__dict__}
        try:
            self._apply_config(config)
            self._validate_config()
        except BaseException:
            self.config = saved
            for k in self._CONFIG_DERIVED:
                self.__dict__.pop(k, None)
            self.__dict__.update(derived)
            raise
        self._config_checked = copy.deepcopy(self.config)

    def _check_config_edits(self) -> None:
        """Validate a config edited in place since it was last validated
        (``env.config["lanes_count"] = 3`` then ``reset()``, highway-env's
        habit: until stop 45 such an edit skipped every check, a 9-lane road
        was built); an unchanged config is not validated again."""
        try:
            same = self.config == self.__dict__.get("_config_checked")
        except (ValueError, TypeError):  # (an array among the values: compare by validating)
            same = False
        if not same:
            self.configure({})

    def preview_config(self, config: dict | None) -> tuple:
        """Validate ``config`` as :meth:`configure` would, without applying it;
        returns ``(n, observation_space, action_space)``: the number of
        possible agents and the spaces a reset with it would give. Everything
        the trial sets (the derived attributes, the spaces and the types,
        the checked config) is put back as it was."""
        saved = copy.deepcopy(self.config)  # (configure updates the config dict in place)
        before = dict(self.__dict__)
        try:
            self.configure(config)
            n = self._n_possible_agents()
            self.define_spaces()
            return n, self.observation_space, self.action_space
        finally:
            self.__dict__.clear()
            self.__dict__.update(before)
            self.config = saved

    def _apply_config(self, config: dict | None) -> None:
        AbstractEnv.configure(self, config)

    def _validate_config(self) -> None:
        raise NotImplementedError

    def _n_possible_agents(self) -> int:
        """The number of possible agents, from the config alone."""
        raise NotImplementedError

    def __getstate__(self) -> dict:
        # the viewer holds pygame surfaces (not picklable); a copy draws anew
        state = dict(self.__dict__)
        state["viewer"] = None
        state["_record_video_wrapper"] = None
        state["enable_auto_render"] = False
        return state

    # ------------------------------------------------------------- subclasses
    def _vehicles(self):
        """The vehicle arrays of the current world (``n``, sorted ``vid``)."""
        raise NotImplementedError

    def _make_viewer(self):
        raise NotImplementedError

    # ------------------------------------------------------------------ spaces
    def _spaces_key(self) -> str:
        import json

        c = self.config
        return json.dumps([c["observation"], c["action"], c["speed_range"]], sort_keys=True, default=repr)

    def _validate_spaces_config(self) -> None:
        """Build the observation and action types once, so that a bad
        ``observation`` / ``action`` config raises at ``configure`` time."""
        observation_factory(self, self.config["observation"])
        action_factory(self, self.config["action"])

    def define_spaces(self) -> None:
        """The observation / action types of ``config`` (see
        :mod:`icv_envs.envs.observations`, :mod:`icv_envs.envs.actions`);
        rebuilt only when their config changes, so the spaces stay the same
        objects across resets."""
        key = self._spaces_key()
        if getattr(self, "_spaces_built_for", None) != key:
            self._obs_type = observation_factory(self, self.config["observation"])
            self._act_type = action_factory(self, self.config["action"])
            self._spaces_built_for = key
        self.observation_type = self._obs_type
        self.action_type = self._act_type
        self.observation_space = self._obs_type.space_
        self.action_space = self._act_type.space

    def state_space_for(self, n_slots: int) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (n_slots, len(self.OBS_FEATURES)), dtype=np.float32)

    # ------------------------------------------------------------ observations
    PERCEPTION_DISTANCE = 150.0  # default of the Kinematics option perception_distance [m]

    def _check_action(self, action, who: str = "agent"):
        return self._act_type.check(action, who)


    def _obs_scales(self) -> tuple[np.ndarray, np.ndarray]:
        """Normalisation scales of the features ``(absolute, relative)``."""
        raise NotImplementedError

    def _neighbours(self, rows: np.ndarray, F: np.ndarray, K: int, pd: float):
        """``(sel, present)``: for each observer row, the traffic rows of its
        up-to-``K`` nearest vehicles within ``pd`` (nearest first) and which of
        the columns hold one."""
        raise NotImplementedError

    def _wrap_dx(self, dx):
        """Longitudinal differences as the observer sees them (round a ring)."""
        return dx

    def _wrap_period(self) -> float | None:
        """``-1.0`` when :meth:`_wrap_dx` is the identity, the ring's length
        when it folds onto ``[-L/2, L/2)`` as ``RoadLayout.wrap`` does, or
        ``None`` for any other fold (the observation then takes its array
        path)."""
        return -1.0 if type(self)._wrap_dx is IcvAgentsEnv._wrap_dx else None

    def _post_rows(self, rows: np.ndarray, crashed_now: np.ndarray) -> tuple:
        """The step's rewards, their components and observations of every
        vehicle (``rows``: all of them, in order) from the state after the
        physics and the world's reaction: the feature rows once
        (:meth:`_features`), then :meth:`_rewards_rows` and
        :meth:`_observe_rows` over them. An env may compute the three in one
        pass when its hooks are its own (``HighwayFormationEnv``)."""
        F = self._features() if len(rows) else np.zeros((0, len(self.OBS_FEATURES)))
        rew, parts = self._rewards_rows(rows, crashed_now, F)
        return rew, parts, self._observe_rows(rows, F)

    def _observe_rows(self, rows: np.ndarray, F: np.ndarray | None = None) -> np.ndarray:
        """Observations of the vehicles at traffic ``rows`` (the observation type's layout)."""
        rows = np.asarray(rows, dtype=np.int64)
        if len(rows) and F is None:
            F = self._features()
        return self._obs_type.observe_rows(rows, F)

    def _names(self, vids: list) -> list:
        """Agent names ``icv_<vid>`` of vehicle ids ``vids`` (non-negative
        ints): the strings of ``possible_agents`` (``possible_agents[i]`` is
        ``icv_<i>`` by construction), new ones for ids beyond it. A lookup
        per agent instead of formatting one (a quarter of the time)."""
        pa = self.possible_agents
        if not vids or max(vids) < len(pa):
            return list(map(pa.__getitem__, vids))
        return [f"icv_{v}" for v in vids]

    def _names_of(self, vid: np.ndarray) -> list:
        """:meth:`_names` of an id array, kept for that array object (id
        arrays are replaced when vehicles come or go, never written in
        place): a step asks for the names of one set of vehicles two or
        three times (the caller's ``expert_actions()``, the action check,
        the dicts; from stop 52). The list is shared: read it, do not
        change it."""
        kept = self.__dict__.get("_names_kept")
        if kept is not None and kept[0] is vid and kept[1] is self.possible_agents:
            return kept[2]
        names = self._names(vid.tolist())
        self._names_kept = (vid, self.possible_agents, names)
        return names

    # ------------------------------------------------------------------ expert
    def _expert_key(self) -> tuple:
        """What the expert's actions depend on: the world, its clock and the
        set of vehicles (ids are never reused, so a removal plus a spawn in
        the same step changes the key even when the count does not)."""
        w = self.world
        return id(w), w.time, self._vehicles().vid.tobytes()

    def expert_actions(self) -> np.ndarray:
        """The expert's (the env method's controller's) normalised actions for
        every vehicle now (rows in vehicle order), computed once per state and
        returned read-only (the env's own copy: until stop 45 a caller adding
        noise to it in place changed what the env then applied as the expert's;
        copy it to modify it)."""
        if self.world is None:
            raise RuntimeError("call reset() before expert_actions()")
        key = self._expert_key()
        ex = self._kept_expert(key)
        if ex is None:
            ex = self._keep_expert(key, self.expert.compute(self.world).astype(np.float32))
        return ex

    def _kept_expert(self, key: tuple):
        """The expert's actions kept for the state ``key`` (:meth:`_expert_key`), or None."""
        c = self._expert_cache
        return c[1] if c is not None and c[0] == key else None

    def _keep_expert(self, key: tuple, ex: np.ndarray) -> np.ndarray:
        """Keep ``ex`` (float32) as the expert's actions for the state ``key``, read-only; returns it."""
        ex.setflags(write=False)
        self._expert_cache = (key, ex)
        return ex

    @staticmethod
    def expert_actions_many(envs: list) -> list[np.ndarray]:
        """``[env.expert_actions() for env in envs]``, the same arrays and
        the same state afterwards bit for bit, the experts not yet asked in
        the current state computed together where they can be
        (:func:`icv_envs.policies.formation_expert_many.compute_many`: plain
        formation experts of equal parameters on equal roads, one pass for
        all; from stop 46, for :class:`icv_envs.vector.BatchedWorlds`)."""
        todo, seen = [], set()
        for env in envs:
            if env.world is None:
                raise RuntimeError("call reset() before expert_actions()")
            key = env._expert_key()
            if env._kept_expert(key) is None and id(env) not in seen:
                seen.add(id(env))  # (an env listed twice is asked once)
                todo.append((env, key))
        if todo:
            acts = compute_many([env.expert for env, _ in todo], [env.world for env, _ in todo], dtype=np.float32)
            for (env, key), ex in zip(todo, acts):
                env._keep_expert(key, ex)
        return [env._expert_cache[1] for env in envs]

    # -------------------------------------------------------------- rendering
    # highway-env's ``road`` (its Road with a view of every vehicle) and
    # ``controlled_vehicles`` (so ``vehicle``, the ego's view) are for its
    # renderer and for users who read them: a reset builds them for the new
    # world when one of them is first read (from stop 52: at every reset
    # before, a quarter of a reset's time, 0.24 of 0.94 ms on a 20-vehicle
    # world, which training's many resets paid without rendering). They
    # show the state when they are read after a reset and when rendered.
    def _render_road_due(self) -> None:
        """After a reset: build highway-env's road for the new world when
        ``road`` or ``controlled_vehicles`` is next read."""
        self._render_due = True

    def _render_sync_due(self) -> None:
        if self.__dict__.get("_render_due"):
            self._render_due = False
            self._sync_render_road(force=True)

    @property
    def road(self):
        self._render_sync_due()
        return self.__dict__.get("_road")

    @road.setter
    def road(self, value) -> None:
        self.__dict__["_road"] = value

    @property
    def controlled_vehicles(self) -> list:
        self._render_sync_due()
        return self.__dict__.get("_controlled_vehicles", [])

    @controlled_vehicles.setter
    def controlled_vehicles(self, value) -> None:
        self.__dict__["_controlled_vehicles"] = value

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

