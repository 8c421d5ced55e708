"""A PettingZoo parallel env whose agents join and leave, as an SB3 ``VecEnv``
for ONE shared policy.

Layout
------
One VecEnv slot per entry of ``possible_agents``, for each of ``n_copies``
independent copies of the env: ``num_envs = n_copies * len(possible_agents)``
and slot ``i`` is agent ``possible_agents[i % P]`` of copy ``i // P``
(:meth:`ParallelVecEnv.slot_agent`). Every agent must share one observation
space and one action space (one policy drives them all).

Masking (absent agents)
-----------------------
A slot whose agent is absent -- not yet spawned, or already departed
(crashed, exited, left the road) -- is *inactive*:

* its observation is all zeros (for this package's envs a real observation is
  never all zeros: row 0 column 0, the observer's presence, is 1);
* its action is ignored (not passed to the env);
* its reward is 0;
* it reports ``done=True`` on every step while it is absent, with
  ``infos[i]["active"] = False`` and no ``terminal_observation``;
* :attr:`ParallelVecEnv.active` (bool array, one per slot) says which slots
  hold a live agent in the observations just returned, i.e. whose next action
  will be used.

``infos[i]["active"]`` says whether slot ``i``'s transition was real: the
agent was live when the action was chosen, the action was applied and the
reward is the env's. Real transitions also carry the env's own info dict for
the agent (``expert_action``, ``rewards`` components, ...) and
``infos[i]["agent"]``.

Why inactive slots report ``done=True``: SB3's PPO stores every slot of every
step in its rollout buffer, inactive ones included, and GAE bootstraps each
step from the value of the slot's next observation unless the step is done. A
``done=False`` placeholder would chain the zero observation to the first
observation of an agent that spawns later into the slot (its value would leak
into the placeholder's advantage) and vice versa. With ``done=True`` every
placeholder step is a one-step episode with reward 0 and no bootstrap: its
return is 0, the value net learns V(zeros) = 0, and its advantage
``-V(zeros)`` tends to 0, so the placeholders add (nearly) zero policy
gradient. What remains: they take rollout-buffer space (a fraction equal to
the fraction of absent slot-steps, small for the default scenarios, where
every agent is present from the start) and they enter PPO's advantage
normalisation statistics and minibatches. SB3's ``num_timesteps`` (and
``total_timesteps``) counts slot-steps, placeholders included. A departing
agent's own last step is ``done=True`` with its terminal observation, and the
first observation of a spawned agent follows a ``done=True`` step, so it is an
episode start: no value ever crosses an absence. Early in training, when most
agents crash within a few steps and one survivor keeps the episode going,
placeholders can fill most of the buffer; :attr:`ParallelVecEnv.placeholder_fraction`
reports the share of placeholder slot-steps so far. Do not wrap the adapter in
SB3's ``VecMonitor``: it would count every placeholder step as an episode (the
adapter already reports ``infos[i]["episode"]`` for real agent-episodes).

Termination and truncation
--------------------------
When an agent terminates or is truncated, its slot reports ``done=True``
exactly once with ``infos[i]["terminal_observation"]`` (the agent's final
observation) and ``infos[i]["TimeLimit.truncated"] = truncated and not
terminated``, so SB3 bootstraps the value on truncation (SuperSuit reports
truncation as termination, which cuts the bootstrap). The same step carries
``infos[i]["episode"] = {"r": return, "l": length, "t": seconds}`` (what SB3's
``Monitor`` would add), so ``ep_rew_mean`` / ``ep_len_mean`` are per agent.
If a truncated agent's final observation is all zeros (this package's env
returns zeros for a vehicle that drove off the end of the road), the agent's
previous observation is used as ``terminal_observation`` and
``infos[i]["terminal_observation_substituted"] = True``: bootstrapping from a
zero observation would bootstrap from the placeholder value, not from the
agent's state.

Open roads
----------
On the highway-ramps and intersection envs vehicles keep arriving until the
time is up, so ``env.agents`` can be empty in mid-episode (all vehicles have
left, the next ones are not due yet). The adapter then steps that copy with
no actions (``env.step({})``) inside the same VecEnv step until an agent
appears or the episode is over (:func:`icv_envs.rl.envs.episode_finished`):
no VecEnv step is spent on a copy without agents, and an agent appearing
during those steps starts its slot's episode as any spawn does. Those env
steps are counted in :attr:`ParallelVecEnv.empty_env_steps`.

Episode end and seeding
-----------------------
When a copy's episode is over (:func:`icv_envs.rl.envs.episode_finished`: no
agents left and, on the open roads, the time is up) it is reset at once and
the slots get the new episode's first observations (the terminal ones are in
``terminal_observation``, as with SB3's ``DummyVecEnv``). Episode ``e`` of copy
``c`` is reset with seed ``base_seed + c + n_copies * e`` (all distinct);
:meth:`ParallelVecEnv.seed` sets ``base_seed`` and restarts ``e`` at 0 on the
next :meth:`reset`, which SB3 calls when ``PPO(seed=...)`` starts learning: a
seeded run is reproducible. Without a seed, a base seed is drawn from
``numpy.random`` at the first reset (which SB3 seeds too).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from icv_envs.rl.envs import episode_finished

__all__ = ["ParallelVecEnv"]

_ENV_ATTRS = ("possible_agents", "observation_space", "action_space", "reset", "step")


def _check_seed(seed) -> int | None:
    """A base seed: None or an integer (not a bool) >= 0."""
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise ValueError(f"seed = {seed!r}; allowed: None or an integer >= 0")
    return None if seed is None else int(seed)


def _check_index(name: str, v, n: int) -> int:
    """An index: an integer (not a bool) in ``0 .. n - 1``."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v < n:
        raise ValueError(f"{name} = {v!r}; allowed: an integer in 0 .. {n - 1}")
    return int(v)


class ParallelVecEnv(VecEnv):
    """SB3 ``VecEnv`` over ``n_copies`` PettingZoo parallel envs, one slot per
    possible agent (see the module docstring for the semantics).

    :param env_fn: builds one PettingZoo ``ParallelEnv`` (a new instance per call)
    :param n_copies: independent env copies
    :param seed: base seed (see :meth:`seed`); None: drawn at the first reset
    """

    def __init__(self, env_fn: Callable[[], Any], n_copies: int = 1, seed: int | None = None) -> None:
        if isinstance(n_copies, bool) or not isinstance(n_copies, (int, np.integer)) or n_copies < 1:
            raise ValueError(f"n_copies = {n_copies!r}; allowed: an integer >= 1")
        seed = _check_seed(seed)
        if not callable(env_fn):
            raise ValueError(f"env_fn = {env_fn!r}; allowed: a callable that builds a PettingZoo ParallelEnv")
        self.envs = []
        for _ in range(int(n_copies)):
            env = env_fn()
            if not all(hasattr(env, a) for a in _ENV_ATTRS):
                raise ValueError(f"env_fn returned {env!r}; allowed: a PettingZoo ParallelEnv (with "
                                 f"{', '.join(_ENV_ATTRS)})")
            self.envs.append(env)
        if len({id(e) for e in self.envs}) != len(self.envs):
            raise ValueError("env_fn returned the same env instance twice; it must build a new env per call")
        self.possible_agents = list(self.envs[0].possible_agents)
        if not self.possible_agents:
            raise ValueError("the env has no possible agents")
        for e in self.envs[1:]:
            if list(e.possible_agents) != self.possible_agents:
                raise ValueError("all env copies must have the same possible_agents")
        a0 = self.possible_agents[0]
        obs_space = self.envs[0].observation_space(a0)
        act_space = self.envs[0].action_space(a0)
        for a in self.possible_agents:
            if self.envs[0].observation_space(a) != obs_space or self.envs[0].action_space(a) != act_space:
                raise ValueError(f"agent {a!r} has other spaces than {a0!r}; one shared policy needs equal spaces")
        if not isinstance(obs_space, gym.spaces.Box):
            raise ValueError(f"observation space {obs_space} is not a Box")
        self.n_copies = len(self.envs)
        self.n_agents = len(self.possible_agents)
        self._slot_index = {a: k for k, a in enumerate(self.possible_agents)}
        super().__init__(self.n_copies * self.n_agents, obs_space, act_space)

        n = self.num_envs
        self._zero_obs = np.zeros(obs_space.shape, dtype=obs_space.dtype)
        self._obs = np.zeros((n, *obs_space.shape), dtype=obs_space.dtype)
        self.active = np.zeros(n, dtype=bool)  # slots holding a live agent in the last returned observations
        self._ret = np.zeros(n, dtype=np.float64)
        self._len = np.zeros(n, dtype=np.int64)
        self._t_start = np.full(n, time.perf_counter())
        self._actions: np.ndarray | None = None
        self._base_seed = seed
        self._episode = [0] * self.n_copies
        self._restart_episodes = True
        self.slot_steps = 0  # slot-steps stepped so far
        self.placeholder_steps = 0  # of which placeholders (inactive slots)
        self.empty_env_steps = 0  # env steps of copies without agents (open roads), taken inside VecEnv steps

    @property
    def placeholder_fraction(self) -> float:
        """Share of the slot-steps so far whose slot was inactive (a placeholder)."""
        return self.placeholder_steps / self.slot_steps if self.slot_steps else 0.0

    # ------------------------------------------------------------------ slots
    def slot(self, copy: int, agent: str) -> int:
        """The slot index of ``agent`` in env copy ``copy``."""
        try:
            k = self._slot_index.get(agent)
        except TypeError:  # unhashable
            k = None
        if k is None:
            raise ValueError(f"agent = {agent!r}; allowed: one of the possible agents {self.possible_agents}")
        return _check_index("copy", copy, self.n_copies) * self.n_agents + k

    def slot_agent(self, i: int) -> tuple[int, str]:
        """``(copy, agent)`` of slot ``i``."""
        i = _check_index("i", i, self.num_envs)
        return i // self.n_agents, self.possible_agents[i % self.n_agents]

    def episode_seed(self, copy: int, episode: int) -> int:
        """The reset seed of episode ``episode`` of copy ``copy``."""
        return int(self._base_seed) + copy + self.n_copies * episode

    # ------------------------------------------------------------------ seeding
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Set the base seed; the next :meth:`reset` restarts every copy at
        episode 0 (copy ``c`` gets ``seed + c``). Returns the first-episode
        seed of each slot."""
        seed = _check_seed(seed)
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max - 1_000_000, dtype=np.int64))
        self._base_seed = seed
        self._restart_episodes = True
        return [self.episode_seed(i // self.n_agents, 0) for i in range(self.num_envs)]

    # ------------------------------------------------------------------ reset
    def _reset_copy(self, c: int, options: dict | None = None) -> None:
        env = self.envs[c]
        kwargs = {"options": options} if options else {}
        obs, infos = env.reset(seed=self.episode_seed(c, self._episode[c]), **kwargs)
        if list(env.possible_agents) != self.possible_agents:
            raise ValueError("an env reset changed possible_agents; the slot layout must stay fixed")
        base = c * self.n_agents
        self._obs[base:base + self.n_agents] = 0
        self.active[base:base + self.n_agents] = False
        for k in range(self.n_agents):
            self.reset_infos[base + k] = {}
        live = set(env.agents)
        for a, o in obs.items():
            if a not in live:
                continue
            i = self.slot(c, a)
            self._obs[i] = o
            self.active[i] = True
            self.reset_infos[i] = dict(infos.get(a, {}))
        now = time.perf_counter()
        self._ret[base:base + self.n_agents] = 0.0
        self._len[base:base + self.n_agents] = 0
        self._t_start[base:base + self.n_agents] = now
        self._advance_empty(c)
        if not env.agents:
            raise ValueError("an episode of the env has no agents at all; the adapter needs at least one")

    def _advance_empty(self, c: int) -> None:
        """Step copy ``c`` with no actions while it has no live agents and its
        episode goes on (open roads); agents appearing get their slots."""
        env = self.envs[c]
        while not env.agents and not episode_finished(env):
            obs, _rew, _term, _trunc, infos = env.step({})
            self.empty_env_steps += 1
            now = time.perf_counter()
            for a in env.agents:  # appeared during this step and still live
                i = self.slot(c, a)
                self._obs[i] = obs[a]
                self.active[i] = True
                self._ret[i] = 0.0
                self._len[i] = 0
                self._t_start[i] = now
                self.reset_infos[i] = dict(infos.get(a, {}))

    def reset(self) -> VecEnvObs:
        """Reset every copy (seeded, see :meth:`seed`) and return the first
        observations (zeros for agents absent at the start)."""
        if self._base_seed is None:
            self.seed(None)
        if self._restart_episodes:
            self._episode = [0] * self.n_copies
            self._restart_episodes = False
        else:  # a new episode of every copy
            self._episode = [e + 1 for e in self._episode]
        for c in range(self.n_copies):
            self._reset_copy(c, self._options[c * self.n_agents])
        self._reset_options()
        self._reset_seeds()
        return self._obs.copy()

    # ------------------------------------------------------------------ step
    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        if actions.ndim == 0 or actions.shape[0] != self.num_envs:
            raise ValueError(f"actions have shape {actions.shape}; expected ({self.num_envs}, ...) (one row per slot)")
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._actions = self._actions, None
        n = self.num_envs
        self.slot_steps += n
        self.placeholder_steps += int(n - self.active.sum())
        rewards = np.zeros(n, dtype=np.float32)
        dones = np.zeros(n, dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(n)]
        for c, env in enumerate(self.envs):
            base = c * self.n_agents
            live = list(env.agents)
            obs, rew, term, trunc, env_infos = env.step({a: actions[self.slot(c, a)] for a in live})
            prev_obs = self._obs[base:base + self.n_agents].copy()
            for k, a in enumerate(self.possible_agents):
                i = base + k
                was_active = bool(self.active[i])
                info: dict[str, Any] = {"agent": a, "active": was_active}
                infos[i] = info
                present = a in obs
                ended = present and bool(term.get(a, False) or trunc.get(a, False))
                if was_active:
                    if present:
                        info.update(env_infos.get(a, {}))
                        info["active"] = True
                        r = float(rew.get(a, 0.0))
                    else:  # vanished without a termination flag: end the slot's episode
                        info["vanished"] = True
                        r = 0.0
                        ended = True
                    rewards[i] = r
                    self._ret[i] += r
                    self._len[i] += 1
                    if ended:
                        terminated = bool(term.get(a, not present))
                        truncated = bool(trunc.get(a, False))
                        final = obs[a] if present else prev_obs[k]
                        final = np.asarray(final, dtype=self.observation_space.dtype)
                        if truncated and not terminated and not final.any():
                            final = prev_obs[k]
                            info["terminal_observation_substituted"] = True
                        dones[i] = True
                        info["terminal_observation"] = final.copy()
                        info["TimeLimit.truncated"] = truncated and not terminated
                        info["episode"] = {"r": float(self._ret[i]), "l": int(self._len[i]),
                                           "t": round(time.perf_counter() - self._t_start[i], 6)}
                        self._obs[i] = self._zero_obs
                        self.active[i] = False
                    else:
                        self._obs[i] = obs[a]
                else:
                    # placeholder transition: zero reward, done, no bootstrap
                    dones[i] = True
                    info["TimeLimit.truncated"] = False
                    if present and not ended:  # the agent spawned during this step
                        self._obs[i] = obs[a]
                        self.active[i] = True
                        self._ret[i] = 0.0
                        self._len[i] = 0
                        self._t_start[i] = time.perf_counter()
                        self.reset_infos[i] = dict(env_infos.get(a, {}))
                        info["spawned"] = True
                    else:
                        self._obs[i] = self._zero_obs
            if not env.agents:  # open road: skip the time without agents (may end the episode)
                self._advance_empty(c)
            if episode_finished(env):  # the episode of this copy is over: start the next one
                self._episode[c] += 1
                self._reset_copy(c)
                for k in range(self.n_agents):
                    infos[base + k]["episode_reset"] = True
        return self._obs.copy(), rewards, dones, infos

    # ------------------------------------------------------------------ misc
    def close(self) -> None:
        for env in self.envs:
            env.close()

    def _copies(self, indices: VecEnvIndices) -> list[int]:
        """Distinct env copies of the slots ``indices``, in order."""
        seen: list[int] = []
        for i in self._get_indices(indices):
            c = int(i) // self.n_agents
            if c not in seen:
                seen.append(c)
        return seen

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The attribute of the env copy of each slot in ``indices``."""
        return [getattr(self.envs[int(i) // self.n_agents], attr_name) for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the attribute once on each env copy that holds a slot in ``indices``."""
        for c in self._copies(indices):
            setattr(self.envs[c], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        """Call the method once per env copy holding a slot in ``indices``;
        returns one result per slot (slots of one copy share its result)."""
        results = {c: getattr(self.envs[c], method_name)(*method_args, **method_kwargs) for c in self._copies(indices)}
        return [results[int(i) // self.n_agents] for i in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        """Whether each slot's env copy is (or wraps, through ``.env``) an
        instance of ``wrapper_class``."""
        def wrapped(env) -> bool:
            seen = set()
            while env is not None and id(env) not in seen:
                if isinstance(env, wrapper_class):
                    return True
                seen.add(id(env))
                env = getattr(env, "env", None)
            return False

        flags = [wrapped(e) for e in self.envs]
        return [flags[int(i) // self.n_agents] for i in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """One frame per slot (the frame of its env copy)."""
        if self.render_mode != "rgb_array":
            return [None] * self.num_envs
        frames = [e.render() for e in self.envs]
        return [frames[i // self.n_agents] for i in range(self.num_envs)]
