"""PettingZoo parallel API over a core env of this package (every ICV an agent)."""

from __future__ import annotations

import numpy as np
from pettingzoo import ParallelEnv

__all__ = ["CoreParallelEnv"]


class CoreParallelEnv(ParallelEnv):
    """Thin PettingZoo layer: ``core_cls`` is a highway-env ``AbstractEnv``
    subclass of this package exposing ``ma_reset`` / ``ma_step``."""

    core_cls = None
    metadata = {"name": "icv_env", "render_modes": ["human", "rgb_array"], "is_parallelizable": True, "render_fps": 10}

    def __init__(self, render_mode: str | None = None, **config) -> None:
        self.render_mode = render_mode
        self.core = self.core_cls(config, render_mode=render_mode)
        self.core._ma_mode = True
        self.possible_agents = list(self.core.possible_agents)
        self.agents: list[str] = []
        self._obs_space = self.core.observation_space
        self._act_space = self.core.action_space
        self.observation_spaces = {a: self._obs_space for a in self.possible_agents}
        self.action_spaces = {a: self._act_space for a in self.possible_agents}
        self.state_space = self.core.state_space_for(len(self.possible_agents))

    def observation_space(self, agent):
        return self._obs_space

    def action_space(self, agent):
        return self._act_space

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, infos = self.core.ma_reset(seed=seed, options=options)
        if list(self.core.possible_agents) != self.possible_agents:
            raise ValueError("options['config'] may not change the number of possible agents of a PettingZoo env")
        self.agents = list(obs)
        return obs, infos

    def step(self, actions: dict):
        if self.core.world is None:
            raise RuntimeError("call reset() before step()")
        obs, rew, term, trunc, infos = self.core.ma_step(actions)
        self.agents = [a for a in obs if not (term[a] or trunc[a])]
        return obs, rew, term, trunc, infos

    @property
    def episode_over(self) -> bool:
        """True once the episode's time is up. On an open road (vehicles
        arriving at a rate) ``agents`` can be empty for a while before that:
        ``step({})`` then just advances time."""
        c = self.core
        return c.world is None or c.world.time >= float(c.config["duration"]) - 1e-9

    def state(self) -> np.ndarray:
        return self.core.global_state(self.possible_agents)

    def render(self):
        return self.core.render()

    def close(self) -> None:
        self.core.close()

    def expert_actions(self) -> dict:
        """The expert's (the env method's controller's) action for every live agent."""
        ex = self.core.expert_actions()
        return dict(zip([f"icv_{v}" for v in self.core.world.traffic.vid.tolist()], ex))

    def metrics(self, **kwargs) -> dict:
        return self.core.metrics(**kwargs)


def module_functions(parallel_cls):
    """PettingZoo's module layout for ``parallel_cls``: ``(parallel_env,
    raw_env, env)``, the parallel env, the unwrapped AEC env converted from
    it, and the AEC env with PettingZoo's order-enforcing wrapper."""
    from pettingzoo.utils.conversions import parallel_to_aec_wrapper
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper

    def parallel_env(render_mode: str | None = None, **config):
        """The parallel env (PettingZoo's ``parallel_env()``)."""
        return parallel_cls(render_mode=render_mode, **config)

    def raw_env(render_mode: str | None = None, **config):
        """The AEC env without wrappers (converted from the parallel env)."""
        return parallel_to_aec_wrapper(parallel_env(render_mode=render_mode, **config))

    def env(render_mode: str | None = None, **config):
        """The AEC env with PettingZoo's order-enforcing wrapper."""
        return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **config))

    return parallel_env, raw_env, env
