"""PettingZoo parallel API over a core env of this package (every ICV an agent)."""

from __future__ import annotations

import numpy as np
from pettingzoo import ParallelEnv
from pettingzoo.utils.agent_selector import AgentSelector
from pettingzoo.utils.conversions import parallel_to_aec_wrapper

from icv_envs._ufuncs import count_nonzero
from icv_envs.envs._config import check_reset_options

__all__ = ["CoreParallelEnv", "OpenRoadAECWrapper", "module_functions"]


class CoreParallelEnv(ParallelEnv):
    """Thin PettingZoo layer: ``core_cls`` is a highway-env ``AbstractEnv``
    subclass of this package exposing ``ma_reset`` / ``ma_step``.

    ``max_cycles`` (PettingZoo's meaning): after that many ``step`` calls
    every agent still live is truncated and the episode is over (the
    config's ``duration`` still applies; whichever comes first)."""

    core_cls = None
    metadata = {"name": "icv_env", "render_modes": ["human", "rgb_array"], "is_parallelizable": True, "render_fps": 10}

    def __init__(self, render_mode: str | None = None, max_cycles: int | None = None, **config) -> None:
        if max_cycles is not None and (isinstance(max_cycles, bool) or not isinstance(max_cycles, (int, np.integer))
                                       or max_cycles < 1):
            raise ValueError(f"max_cycles = {max_cycles!r}; allowed: None (the config's duration ends the episode) "
                             f"or an integer >= 1")
        self.max_cycles = None if max_cycles is None else int(max_cycles)
        self._cycles = 0
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

    @property
    def agents(self) -> list[str]:
        """The live agents (PettingZoo's attribute). After :meth:`step_rows`
        the names are made from its ids when first read (a training loop
        on arrays never asks for them: 459 names a step on the ring)."""
        a = self._agents
        if a is None:
            a = self._agents = self.core._names(self._agents_vid.tolist())
        return a

    @agents.setter
    def agents(self, value: list[str]) -> None:
        self._agents = value

    @property
    def num_agents(self) -> int:
        a = self._agents
        return len(self._agents_vid) if a is None else len(a)

    def observation_space(self, agent):
        return self._obs_space

    def action_space(self, agent):
        return self._act_space

    def reset(self, seed: int | None = None, options: dict | None = None):
        check_reset_options(options)
        if options and "config" in options:
            # validate first, then apply: a rejected config leaves the env as it was (until stop 45 a config
            # changing the spaces was applied before it was rejected, and every later reset failed)
            n, obs_space, act_space = self.core.preview_config(options["config"])
            if n != len(self.possible_agents):
                raise ValueError(
                    f"options['config'] gives {n} possible agents, this env has {len(self.possible_agents)}: a "
                    f"PettingZoo env's possible_agents are fixed at construction (on the open-road envs they follow "
                    f"duration, vgr/throughput unless max_vehicles is set); create a new env, or set max_vehicles"
                )
            if obs_space != self._obs_space or act_space != self._act_space:
                raise ValueError(f"options['config'] changes the spaces (observation {self._obs_space} -> {obs_space}, "
                                 f"action {self._act_space} -> {act_space}); a PettingZoo env's spaces are fixed at "
                                 f"construction: create a new env")
        # (the core gets the config only: the options were checked here, once)
        obs, infos = self.core.ma_reset(seed=seed, options=None if not options or "config" not in options
                                        else {"config": options["config"]})
        if list(self.core.possible_agents) != self.possible_agents:
            raise ValueError("options['config'] (or core.configure()) may not change the number of possible agents of a "
                             "PettingZoo env")
        if self.core.observation_space is not self._obs_space or self.core.action_space is not self._act_space:
            raise ValueError("options['config'] (or core.configure()) may not change the observation or action space of "
                             "a PettingZoo env (its spaces are fixed at construction)")
        self._cycles = 0
        self.agents = list(obs)
        return obs, infos

    def _check_steppable(self) -> None:
        """A step needs a reset first, and an episode not yet over (after it,
        the core still holds the vehicles and would name them live agents
        without actions)."""
        if self.core.world is None:
            raise RuntimeError("call reset() before step()")
        if not self.agents and self.episode_over:
            raise RuntimeError("the episode is over (its time is up and every agent was reported done): call reset()")

    def step(self, actions: dict):
        self._check_steppable()
        obs, rew, term, trunc, infos = self.core.ma_step(actions)
        self._cycles += 1
        if self._cycles_up:
            trunc = {a: not term[a] for a in obs}
        if any(term.values()) or any(trunc.values()):
            self.agents = [a for a in obs if not (term[a] or trunc[a])]
        else:  # nobody done (most steps): every key, in order (two C-level scans, a third of the loop's time)
            self.agents = list(obs)
        return obs, rew, term, trunc, infos

    def step_rows(self, actions):
        """:meth:`step` with arrays in and out: ``actions (n, 2)`` for the
        continuous action types, ``(n,)`` integers for ``DiscreteMetaAction``,
        one row per live vehicle in ascending id order
        (``core.world``'s rows); returns the core's
        :class:`~icv_envs.envs.agents_step.StepRows` (the agents and values of
        :meth:`step`'s dicts, no infos) and updates ``agents`` as
        :meth:`step` does."""
        self._check_steppable()
        return self._rows_done(self.core.ma_step_rows(actions))

    def _step_controls(self, controls):
        """:meth:`step_rows` from checked and clipped plain continuous
        actions (``core._ma_step_controls``: a batch that checked all its
        worlds' actions at once)."""
        if self.core.world is None:
            raise RuntimeError("call reset() before step()")
        return self._rows_done(self.core._ma_step_controls(controls))

    def _rows_done(self, out):
        """The bookkeeping of :meth:`step` after an array step: the cycle
        count, PettingZoo's ``max_cycles`` rule, the live agents."""
        self._cycles += 1
        if self._cycles_up:
            out = out._replace(truncated=~out.terminated)
        if count_nonzero(out.terminated) or count_nonzero(out.truncated):
            live = out.vid[~(out.terminated | out.truncated)]
        else:  # (everyone stays, most steps: the counts first, a copy as the selection makes; stop 51)
            live = out.vid.copy()
        self._agents, self._agents_vid = None, live  # the names when asked (``agents``)
        return out

    @property
    def _cycles_up(self) -> bool:
        """``max_cycles`` steps taken: PettingZoo's rule, the episode is over
        and every agent not terminated is truncated (:meth:`step` and
        :meth:`step_rows` apply it to their dicts and arrays)."""
        return self.max_cycles is not None and self._cycles >= self.max_cycles

    @property
    def episode_over(self) -> bool:
        """True once the episode's time is up (``duration`` seconds, or
        ``max_cycles`` steps). On an open road (vehicles arriving at a rate)
        ``agents`` can be empty for a while before that: ``step({})`` then
        just advances time."""
        c = self.core
        if self._cycles_up:
            return True
        return c.world is None or c.world.time >= float(c.config["duration"]) - 1e-9

    def state(self) -> np.ndarray:
        return self.core.global_state(self.possible_agents)

    def render(self):
        return self.core.render()

    def close(self) -> None:
        self.core.close()

    def expert_actions(self) -> dict:
        """The expert's (the env method's controller's) action for every live
        agent: rows of a copy, the caller's to change (the env keeps its own)."""
        ex = self.core.expert_actions().copy()
        return dict(zip(self.core._names_of(self.core._vehicles().vid), ex))

    def metrics(self, **kwargs) -> dict:
        return self.core.metrics(**kwargs)


class OpenRoadAECWrapper(parallel_to_aec_wrapper):
    """PettingZoo's parallel-to-AEC conversion for an open road: when every
    agent has left but the episode's time is not up (``agents`` momentarily
    empty, vehicles still to arrive), the AEC env keeps stepping the parallel
    env with no actions until an agent appears or the episode ends, instead
    of ending the episode (``agent_iter()`` stops only when it is over); an
    agent that arrives in the last step, already truncated, takes its dead
    step without an action it never had."""

    def reset(self, seed=None, options=None):
        super().reset(seed=seed, options=options)
        self._skip_empty()

    def step(self, action):
        a = self.agent_selection
        if (self.terminations.get(a) or self.truncations.get(a)) and a not in self._actions:
            # an agent that arrived in the episode's last step, already
            # truncated: it never acted, and PettingZoo's conversion deletes
            # the action it stored for it (a KeyError until stop 45)
            self._actions[a] = None
        super().step(action)
        self._skip_empty()

    def _skip_empty(self) -> None:
        par = self.env
        while not self.agents and not par.episode_over:
            obss, rews, terms, truncs, infos = par.step({})
            if not obss:
                continue
            self._observations = dict(obss)
            self.terminations = dict(terms)
            self.truncations = dict(truncs)
            self.infos = dict(infos)
            self.rewards = dict(rews)
            self._cumulative_rewards = dict(rews)
            live = set(par.agents)
            self.agents = par.agents + [a for a in sorted(obss, key=str) if a not in live]
            self._actions = {}
            if par.agents:
                self._agent_selector = AgentSelector(par.agents)
                self.agent_selection = self._agent_selector.reset()
            else:
                self.agent_selection = self.agents[0]
            self._deads_step_first()


def module_functions(parallel_cls):
    """PettingZoo's module layout for ``parallel_cls``: ``(parallel_env,
    raw_env, env)``, the parallel env, the unwrapped AEC env converted from
    it (:class:`OpenRoadAECWrapper`), and the AEC env with PettingZoo's
    order-enforcing wrapper."""
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper

    def parallel_env(render_mode: str | None = None, **config):
        """The parallel env (PettingZoo's ``parallel_env()``)."""
        return parallel_cls(render_mode=render_mode, **config)

    def raw_env(render_mode: str | None = None, **config):
        """The AEC env without wrappers (converted from the parallel env)."""
        return OpenRoadAECWrapper(parallel_env(render_mode=render_mode, **config))

    def env(render_mode: str | None = None, **config):
        """The AEC env with PettingZoo's order-enforcing wrapper."""
        return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **config))

    return parallel_env, raw_env, env
