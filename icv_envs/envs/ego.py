"""The Gymnasium single-agent face of every environment (``gym.make``): one
ego vehicle takes the action, every other vehicle follows the environment's
expert, through the same multi-agent step (``_ma_advance``) the PettingZoo
envs use. A mixin of :class:`icv_envs.envs.base.IcvAgentsEnv`, whose
``configure``, ``define_spaces``, ``_reset``, ``_vehicles``,
``_observe_rows``, ``_ma_infos``, ``_label_infos``, ``expert_actions`` and
action type it uses; ``_ego_vid`` (the ego's vehicle id) is set by each
env's ``_reset``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from icv_envs.envs._config import check_reset_options

__all__ = ["EgoEnv"]


class EgoEnv:
    """Gymnasium ``reset`` / ``step`` of :class:`~icv_envs.envs.base.IcvAgentsEnv` for one ego (module docstring)."""

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self._reset_world(seed, options)
        obs, info = self._ego_obs_info()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def _reset_world(self, seed: int | None, options: dict | None) -> None:
        """:meth:`reset` up to the new world, without the ego's observation
        and info (the multi-agent reset builds every agent's instead, from
        stop 43: it discarded the ego's)."""
        check_reset_options(options)
        gym.Env.reset(self, seed=seed, options=options)
        if options and "config" in options:
            self.configure(options["config"])
        else:
            self._check_config_edits()
        # the observation and action types of the config as it is now, as
        # highway-env's reset rebuilds them: a config changed by reset's
        # options or by configure() since (before stop 42, configure() then
        # reset() kept the old types: a new perception distance or action
        # type was accepted and ignored). Spaces are created once: keep the
        # same objects (and their seeded RNGs) unless the config changes them
        old = (self.observation_space, self.action_space)
        self.define_spaces()
        # (the same object when the types were kept: no comparison, whose
        # bounds test costs tens of microseconds a reset)
        if old[0] is not None and old[0] is not self.observation_space and old[0] == self.observation_space:
            self.observation_space = old[0]
        if old[1] is not None and old[1] is not self.action_space and old[1] == self.action_space:
            self.action_space = old[1]
        self.possible_agents = [f"icv_{i}" for i in range(self._n_possible_agents())]
        self.update_metadata()
        self.time = self.steps = 0
        self.done = False
        self._act_type.reset()
        self._reset()

    def _ego_row(self) -> int:
        veh = self._vehicles()
        r = int(np.searchsorted(veh.vid, self._ego_vid))
        return r if r < veh.n and veh.vid[r] == self._ego_vid else -1

    def _ego_obs_info(self):
        r = self._ego_row()
        if r < 0:
            return np.zeros(self.observation_space.shape, dtype=np.float32), {}
        obs = self._observe_rows(np.array([r]))[0]
        a = f"icv_{self._ego_vid}"
        infos = self._ma_infos([a], np.array([r]), {})
        if self.config["expert_in_info"]:
            self._label_infos(infos, self._vehicles().vid[[r]], self.expert_actions()[[r]])
        info = infos[a]
        return obs, info

    def step(self, action):
        """Single-agent step: ``action`` drives the ego, every other vehicle
        follows the environment's expert."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        if self._ego_done:
            raise RuntimeError("the ego's episode has ended (terminated or truncated): call reset()")
        act = self._act_type.check(action, "the ego")
        veh = self._vehicles()
        acts = self.expert_actions().astype(np.float64).copy() if veh.n else np.zeros((0, 2))
        r = self._ego_row()
        if r >= 0:
            acts[r] = self._act_type.controls(np.array([r]), [act])[0]
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
