"""Batched worlds for training: ``B`` independent worlds stepped together in
one process, arrays in and arrays out.

* :class:`IcvVectorEnv` -- a Gymnasium ``VectorEnv`` (1.2-1.4 API) over the
  single-agent envs (``icv_envs/HighwayFormation-v0``, ...): ``obs (B, V,
  F)``, ``actions (B, 2)``, per-world auto-reset in Gymnasium's
  ``NEXT_STEP`` (default, as ``SyncVectorEnv``) or ``SAME_STEP`` mode
  (``metadata["autoreset_mode"]``; in ``SAME_STEP`` the last observation of
  a finished episode is ``infos["final_obs"][b]`` where
  ``infos["_final_obs"][b]``), per-world seeding (``reset(seed=s)`` seeds
  world ``b`` with ``s + b``, as Gymnasium does; later auto-resets continue
  each world's own generator). :meth:`IcvVectorEnv.to_sb3` gives a
  Stable-Baselines3 ``VecEnv`` over the same worlds.
* :class:`BatchedWorlds` -- the multi-agent envs in a fixed-K slot layout:
  slot ``k`` of world ``b`` is ``possible_agents[k]``; ``obs (B, K, V, F)``,
  ``actions (B, K, 2)`` (``(B, K)`` integers with ``DiscreteMetaAction``:
  the batch's spaces are the worlds' own, per slot, bounds and dtypes kept),
  ``rewards``/``terminated``/``truncated (B, K)`` and
  ``mask (B, K)`` (True where the slot holds a live agent whose next action
  is used; observations of empty slots are zeros and their actions are
  ignored). A world whose episode is over
  (:func:`icv_envs.rl.envs.episode_finished`: the time is up, or no agent is
  left and none is due; on the open roads a world may be empty for a while)
  is reset in the same step (its
  slots' last observations in ``info["final_obs"]``, ``info["reset"][b]``
  True); world ``b``'s episodes are seeded from
  ``numpy.random.SeedSequence(seed).spawn(B)[b]``.

Decisions, as a vectorised RL simulator would take them: worlds never
interact and are stepped in a fixed order, so a batch is bit-identical to
``B`` separate envs with the same seeds; the batch owns its output arrays and
returns copies (``copy=True``, Gymnasium's default) or views refreshed in
place (``copy=False``). The worlds are stepped one after the other in this
process: every world is the vectorised core of :mod:`icv_envs.sim` with its
own formation layer, so the batch removes the per-process and per-env
Python layers (wrappers, dicts for the single-agent case) but not the
per-world step. One stage runs over all worlds at once (from stop 46): the
formation experts, asked after every world has stepped (``expert=True``)
and before the worlds step when their action type starts from the
expert's action (``FormationResidual``), in one pass
(``IcvAgentsEnv.expert_actions_many``); each world gets exactly its own
expert's actions and lane-change plans, so the batch stays bit-identical
to separate envs.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from icv_envs._args import check_config, check_flag, check_int
from icv_envs._ufuncs import clip as uclip
from icv_envs.envs._kernels import scatter_expert_rows, scatter_world_rows
from icv_envs.sim._kernels import id_range
from icv_envs.envs.actions import ContinuousAction, FormationResidual
from icv_envs.rl.envs import episode_finished

__all__ = ["IcvVectorEnv", "BatchedWorlds"]


def _plain_continuous(at) -> bool:
    """Whether action type ``at`` turns actions into controls by clipping
    them to [-1, 1] and nothing else: :class:`ContinuousAction` itself, its
    ``controls`` not replaced on the instance (a subclass such as
    ``FormationResidual`` adds the expert's action)."""
    return type(at) is ContinuousAction and "controls" not in at.__dict__


def _asks_expert(at) -> bool:
    """Whether action type ``at`` asks the expert at the start of every step
    (:class:`FormationResidual` itself: its controls are the expert's action
    plus the residual)."""
    return type(at) is FormationResidual and "controls" not in at.__dict__


def _slot_spaces(obs_space, act_space, B: int, K: int) -> tuple:
    """The batch's ``(observation_space, action_space)`` over ``(B, K)``
    slots from one agent's spaces, their bounds and dtypes kept (an
    unnormalised observation is unbounded; empty slots hold zeros, which
    every observation space of these envs contains): a ``Box`` per slot, or
    ``MultiDiscrete`` for a ``Discrete`` action. Other spaces are refused."""
    def box(sp):
        shape = (B, K) + sp.shape
        return spaces.Box(np.broadcast_to(sp.low, shape), np.broadcast_to(sp.high, shape), shape, dtype=sp.dtype)

    if not isinstance(obs_space, spaces.Box):
        raise ValueError(f"observation space {obs_space}; allowed for the slot layout: a Box")
    if isinstance(act_space, spaces.Box):
        act = box(act_space)
    elif isinstance(act_space, spaces.Discrete):
        act = spaces.MultiDiscrete(np.full((B, K), act_space.n), dtype=np.int64, start=np.full((B, K), act_space.start))
    else:
        raise ValueError(f"action space {act_space}; allowed for the slot layout: a Box or a Discrete")
    return box(obs_space), act


class IcvVectorEnv(VectorEnv):
    """``num_envs`` single-agent icv_envs worlds as one Gymnasium VectorEnv."""

    def __init__(self, env_id: str = "icv_envs/HighwayFormation-v0", num_envs: int = 8, config: dict | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, copy: bool = True) -> None:
        import icv_envs  # noqa: F401  (registers the ids)

        if env_id not in icv_envs.GYM_IDS:
            raise ValueError(f"env_id {env_id!r} is not a single-agent icv_envs env; allowed: {sorted(icv_envs.GYM_IDS)}")
        self.num_envs = check_int("num_envs", num_envs, 1)
        try:
            mode = AutoresetMode(autoreset_mode) if isinstance(autoreset_mode, str) else autoreset_mode
        except ValueError:
            mode = None
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"autoreset_mode = {autoreset_mode!r}; allowed: AutoresetMode.NEXT_STEP or SAME_STEP "
                             f"(or the strings 'NextStep', 'SameStep')")
        self.autoreset_mode = mode
        self.metadata = {"autoreset_mode": mode, "render_modes": []}
        self.copy = check_flag("copy", copy)
        config = check_config(config)
        self.envs = [gym.make(env_id, config=dict(config)).unwrapped for _ in range(self.num_envs)]
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        B = self.num_envs
        self._obs = np.zeros((B,) + self.single_observation_space.shape, dtype=np.float32)
        self._rew = np.zeros(B, dtype=np.float64)
        self._term = np.zeros(B, dtype=bool)
        self._trunc = np.zeros(B, dtype=bool)
        self._step_infos: list[dict] = [{} for _ in range(B)]
        self._autoreset = np.zeros(B, dtype=bool)
        self.env_id = env_id

    def _out(self, a):
        return a.copy() if self.copy else a

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        B = self.num_envs
        if seed is None or (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)):
            seeds = [None if seed is None else check_int("seed", seed, 0) + b for b in range(B)]
        elif isinstance(seed, (list, tuple, np.ndarray)):
            seeds = [None if s is None else check_int(f"seed[{b}]", s, 0) for b, s in enumerate(seed)]
            if len(seeds) != B:
                raise ValueError(f"{len(seeds)} seeds for {B} worlds; pass one int or one seed per world")
        else:
            raise ValueError(f"seed = {seed!r}; allowed: None, an integer >= 0 (world b gets seed + b) or a list of "
                             f"{B} integers >= 0 or None")
        infos: dict[str, Any] = {}
        for b, env in enumerate(self.envs):
            self._obs[b], info = env.reset(seed=seeds[b], options=options)
            infos = self._add_info(infos, info, b)
        self._autoreset[:] = False
        return self._out(self._obs), infos

    def step(self, actions):
        acts = np.asarray(actions)
        shape = (self.num_envs,) + tuple(self.single_action_space.shape)  # ((B, 2); (B,) for discrete actions)
        if acts.shape != shape:
            raise ValueError(f"actions have shape {acts.shape}; allowed: {shape}")
        # every world's info aggregated as Gymnasium's SyncVectorEnv does (key -> (B, ...) array plus the
        # "_key" mask; until stop 45 only "expert_action" was kept); the last step's info of each world is
        # kept for the SB3 adapter (its per-world infos)
        infos: dict[str, Any] = {}
        for b, env in enumerate(self.envs):
            if self.autoreset_mode == AutoresetMode.NEXT_STEP and self._autoreset[b]:
                self._obs[b], info = env.reset()
                self._rew[b], self._term[b], self._trunc[b] = 0.0, False, False
                self._step_infos[b] = info
            else:
                self._obs[b], self._rew[b], self._term[b], self._trunc[b], info = env.step(acts[b])
                self._step_infos[b] = info
                if self.autoreset_mode == AutoresetMode.SAME_STEP and (self._term[b] or self._trunc[b]):
                    infos = self._add_info(infos, {"final_obs": self._obs[b].copy(), "final_info": info}, b)
                    self._obs[b], info = env.reset()
            infos = self._add_info(infos, info, b)
        self._autoreset = self._term | self._trunc
        return self._out(self._obs), self._rew.copy(), self._term.copy(), self._trunc.copy(), infos

    def close_extras(self, **kwargs) -> None:
        for env in getattr(self, "envs", []):
            env.close()

    def to_sb3(self):
        """A Stable-Baselines3 ``VecEnv`` over these worlds (SB3's own
        conventions: same-step reset, ``infos[b]["terminal_observation"]``,
        ``infos[b]["TimeLimit.truncated"]``)."""
        return _Sb3Adapter(self)


def _sb3_vecenv_base():
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv as _V

    return _V


class _Sb3Adapter:  # made a real SB3 VecEnv subclass on first use (SB3 is an optional extra)
    def __new__(cls, venv: IcvVectorEnv):
        base = _sb3_vecenv_base()

        class IcvSb3VecEnv(base):
            def __init__(self, venv):
                if venv.autoreset_mode != AutoresetMode.SAME_STEP:
                    venv.autoreset_mode = AutoresetMode.SAME_STEP
                    venv.metadata["autoreset_mode"] = AutoresetMode.SAME_STEP
                self.venv = venv
                super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
                self._actions = None
                self._seed = None

            def reset(self):
                obs, _ = self.venv.reset(seed=self._seed)
                self._seed = None
                return obs

            def step_async(self, actions):
                self._actions = np.asarray(actions)

            def step_wait(self):
                obs, rew, term, trunc, infos = self.venv.step(self._actions)
                dones = term | trunc
                # each world's own info of the step (the final step's for a world that ended), as SB3's
                # DummyVecEnv passes it (until stop 45 only SB3's two keys)
                out = [dict(i) for i in self.venv._step_infos]
                for b in range(self.num_envs):  # (every step, as DummyVecEnv sets it)
                    out[b]["TimeLimit.truncated"] = bool(trunc[b] and not term[b])
                for b in np.flatnonzero(dones):
                    out[b]["terminal_observation"] = infos["final_obs"][b]
                return obs, rew.astype(np.float32), dones, out

            def seed(self, seed=None):
                self._seed = seed
                return [None if seed is None else seed + b for b in range(self.num_envs)]

            def close(self):
                self.venv.close()

            def get_attr(self, attr_name, indices=None):
                return [getattr(self.venv.envs[i], attr_name) for i in self._idx(indices)]

            def set_attr(self, attr_name, value, indices=None):
                for i in self._idx(indices):
                    setattr(self.venv.envs[i], attr_name, value)

            def env_method(self, method_name, *args, indices=None, **kwargs):
                return [getattr(self.venv.envs[i], method_name)(*args, **kwargs) for i in self._idx(indices)]

            def env_is_wrapped(self, wrapper_class, indices=None):
                return [False for _ in self._idx(indices)]

            def _idx(self, indices):
                if indices is None:
                    return range(self.num_envs)
                return [indices] if isinstance(indices, int) else list(indices)

        return IcvSb3VecEnv(venv)


class BatchedWorlds:
    """``num_worlds`` multi-agent worlds in the fixed-K slot layout (see the
    module docstring). ``env``: ``"highway_formation"``, ``"highway_ramps"``
    or ``"intersection"``; ``config``: the PettingZoo env's keyword
    arguments; ``expert``: also return the expert's action for every slot
    (``info["expert_actions"]``, ``(B, K, 2)``, zeros in empty slots).
    Continuous actions (``ContinuousAction``, ``FormationResidual``) are
    ``(B, K, 2)``; ``DiscreteMetaAction``'s are ``(B, K)`` integers
    (``action_space`` a ``MultiDiscrete``); both step each world through its
    array path (``ParallelEnv.step_rows``), not its dicts. Without ``expert``
    the worlds never compute the expert: unless ``config``
    says otherwise, ``expert_driven_check`` is False, so every vehicle is
    policy-driven (learned actions are never equal to the expert's anyway;
    the comparison cost a quarter of a 20-agent step)."""

    ENVS = ("highway_formation", "highway_ramps", "intersection")
    # the worlds' experts asked together (IcvAgentsEnv.expert_actions_many, from stop 46); the tests
    # set it False on an instance to compare with asking each world's expert_actions()
    _expert_many = True

    def __init__(self, num_worlds: int = 8, env: str = "highway_formation", config: dict | None = None,
                 seed: int = 0, expert: bool = False, copy: bool = True) -> None:
        import importlib

        if env not in self.ENVS:
            raise ValueError(f"env = {env!r}; allowed: {list(self.ENVS)}")
        self.num_worlds = B = check_int("num_worlds", num_worlds, 1)
        self.expert = check_flag("expert", expert)
        self.copy = check_flag("copy", copy)
        seed = check_int("seed", seed, 0)
        cfg = check_config(config, "the env's keyword arguments")
        cfg.setdefault("expert_in_info", False)  # the batch asks the expert once per step itself
        # without ``expert`` the batch never computes the expert: no action is compared with it
        # (every vehicle policy-driven, see the envs' ``expert_driven_check``)
        cfg.setdefault("expert_driven_check", self.expert)
        mod = importlib.import_module(f"icv_envs.envs.{env}_v0")
        self.envs = [mod.parallel_env(**cfg) for _ in range(B)]
        self.possible_agents = list(self.envs[0].possible_agents)
        self.K = K = len(self.possible_agents)
        self.slot_of = {a: k for k, a in enumerate(self.possible_agents)}
        # vehicle id -> slot (agents are ``icv_<vid>``), for the array path
        ids = [int(a[4:]) for a in self.possible_agents]
        self._slot_of_vid = np.full(max(ids) + 1 if ids else 0, -1, dtype=np.int64)
        self._slot_of_vid[ids] = np.arange(K)
        self._lut_dense = bool((self._slot_of_vid >= 0).all())  # (possible agents icv_0 .. icv_<K-1>: always)
        # slot k holds vehicle k (possible agents icv_0 .. icv_<K-1> in order: always): ids are their slots
        self._lut_identity = self._lut_dense and bool(np.array_equal(self._slot_of_vid, np.arange(K)))
        self.single_observation_space = self.envs[0].observation_space(self.possible_agents[0])
        self.single_action_space = self.envs[0].action_space(self.possible_agents[0])
        obs_shape = self.single_observation_space.shape
        self.observation_space, self.action_space = _slot_spaces(self.single_observation_space,
                                                                 self.single_action_space, B, K)
        # discrete actions (DiscreteMetaAction): ``actions (B, K)``, integers
        self._discrete = isinstance(self.single_action_space, spaces.Discrete)
        self._act_shape = (B, K) + tuple(self.single_action_space.shape)
        self._seeds = np.random.SeedSequence(seed).spawn(B)
        self._episode = np.zeros(B, dtype=np.int64)
        self.obs = np.zeros((B, K) + obs_shape, dtype=np.float32)
        self._obs_flat = self.obs.reshape(B, K, -1)  # (a view: each slot's observation flattened, for the scatter)
        self.mask = np.zeros((B, K), dtype=bool)
        self.rewards = np.zeros((B, K), dtype=np.float64)
        self.terminated = np.zeros((B, K), dtype=bool)
        self.truncated = np.zeros((B, K), dtype=bool)
        self.expert_actions = np.zeros((B, K, 2), dtype=np.float32)
        self.final_obs = np.zeros((B, K) + obs_shape, dtype=np.float32)

    def episode_seed(self, b: int, episode: int) -> int:
        """The seed of world ``b``'s ``episode``-th episode."""
        return int(np.random.SeedSequence(self._seeds[b].entropy, spawn_key=self._seeds[b].spawn_key + (episode,))
                   .generate_state(1)[0])

    def _slots(self, agents) -> np.ndarray:
        so = self.slot_of
        return np.fromiter((so[a] for a in agents), dtype=np.int64, count=len(agents))

    def _slots_of_vid(self, vid: np.ndarray, ascending: bool = False) -> np.ndarray:
        """Slots of vehicle ids ``vid`` (``ascending``: sorted, as a world's
        rows are); an error names the ids that have none (beyond the slot
        table or not a possible agent)."""
        lut = self._slot_of_vid
        if not len(vid):
            return np.zeros(0, dtype=np.int64)
        lo, hi = (int(vid[0]), int(vid[-1])) if ascending else id_range(np.asarray(vid, dtype=np.int64))
        if hi < len(lut) and lo >= 0:
            if self._lut_identity:  # (read only by the callers)
                return vid
            k = lut[vid]
            if self._lut_dense:  # every id in the table has a slot
                return k
        else:
            inside = (vid >= 0) & (vid < len(lut))
            k = np.full(len(vid), -1, dtype=np.int64)
            k[inside] = lut[vid[inside]]
        if int(k.min()) < 0:
            bad = vid[k < 0]
            more = f" (and {len(bad) - 5} more)" if len(bad) > 5 else ""
            raise ValueError(f"vehicles {bad[:5].tolist()}{more} are not among possible_agents; the slot layout "
                             f"needs every agent in possible_agents")
        return k

    def _reset_world(self, b: int) -> None:
        env = self.envs[b]
        obs, _ = env.reset(seed=self.episode_seed(b, int(self._episode[b])))
        if list(env.possible_agents) != self.possible_agents:
            raise ValueError("the number of possible agents changed between episodes; the slot layout needs a fixed K")
        self._episode[b] += 1
        self.obs[b] = 0.0
        self.mask[b] = False
        if obs:
            k = self._slots(list(obs))
            self.obs[b, k] = np.stack(list(obs.values()))
            self.mask[b, self._slots(env.agents)] = True

    def _fill_experts(self) -> None:
        """``expert_actions`` of every world from its current state, the
        worlds' experts asked together (``IcvAgentsEnv.expert_actions_many``:
        plain formation experts in one pass, from stop 46; the same actions as
        asking each world's ``expert_actions()``, bit for bit)."""
        if not self.expert:
            return
        live = []
        for b, env in enumerate(self.envs):
            if env.num_agents:  # (the count, without making the names after step_rows)
                live.append(b)
            else:
                self.expert_actions[b] = 0.0
        cores = [self.envs[b].core for b in live]
        acts = type(cores[0]).expert_actions_many(cores) if self._expert_many and cores else \
            [core.expert_actions() for core in cores]
        for b, core, ex in zip(live, cores, acts):
            scatter_expert_rows(self.expert_actions, b, self._slots_of_vid(core._vehicles().vid, ascending=True), ex)

    def _out(self, a):
        return a.copy() if self.copy else a

    def reset(self):
        """Reset every world; returns ``(obs, mask)``."""
        for b in range(self.num_worlds):
            self._reset_world(b)
        self._fill_experts()
        return self._out(self.obs), self._out(self.mask)

    def step(self, actions):
        """``actions (B, K, 2)`` (``(B, K)`` integers for discrete actions); returns ``obs, rewards, terminated,
        truncated, mask, info`` (``info["reset"] (B,)``, ``info["final_obs"]``
        and with ``expert`` ``info["expert_actions"]``)."""
        acts = np.asarray(actions)
        if acts.shape != self._act_shape:
            raise ValueError(f"actions have shape {acts.shape}; allowed: {self._act_shape}")
        if self._discrete:  # checked, then as integers (empty slots: the space's first action, ignored)
            acts = self._check_discrete(acts).astype(np.int64)
        elif acts.dtype.kind in "fiu":
            acts = acts.astype(np.float64, copy=False)
        else:
            raise ValueError(f"actions have dtype {acts.dtype}; allowed: real numbers (float or int)")
        fin = np.isfinite(acts)
        finite = np.count_nonzero(fin) == fin.size
        if not finite:  # (the count first; the live slots' rows only then)
            bad = ~fin.reshape(fin.shape[:2] + (-1,)).all(axis=-1) & self.mask
            if np.count_nonzero(bad):
                b, k = np.argwhere(bad)[0]
                raise ValueError(f"action of world {b} slot {k} ({self.possible_agents[k]}) = {acts[b, k].tolist()} "
                                 f"holds NaN or inf; allowed: finite values in [-1, 1]")
        # every action finite: clipped once for the batch, and each world whose
        # action type is plain continuous steps from its rows (the values its
        # own check and clip would give; from stop 43); the type is asked per
        # world and step (a reset may bring another one with the same space)
        ctl = uclip(acts, -1.0, 1.0) if finite and not self._discrete else None
        self.rewards[:] = 0.0
        self.terminated[:] = False
        self.truncated[:] = False
        reset = np.zeros(self.num_worlds, dtype=bool)
        if self._expert_many:
            # worlds whose step starts by asking their expert (FormationResidual): asked together here,
            # in the state each step starts from (each step then reads its kept answer; from stop 46)
            ask = [env.core for env in self.envs if _asks_expert(env.core._act_type) and env.core._vehicles().n]
            if len(ask) > 1:
                type(ask[0]).expert_actions_many(ask)
        K = self.K
        for b, env in enumerate(self.envs):
            # every world through its array path (the same agents and values as the dicts; discrete
            # actions too from stop 45, which went through the per-agent dicts)
            if ctl is not None and _plain_continuous(env.core._act_type):
                vid = env.core._vehicles().vid
                if self._lut_identity and len(vid) == K and vid[-1] == K - 1:
                    # every slot on the road, in order (sorted distinct ids 0 .. K-1): world b's rows of the
                    # batch's fresh clipped array as they are (from stop 50; the slots' gather gave a copy
                    # of the same values, which the step only reads)
                    out = env._step_controls(ctl[b])
                else:
                    out = env._step_controls(ctl[b, self._slots_of_vid(vid, ascending=True)])
            else:
                out = env.step_rows(acts[b, self._slots_of_vid(env.core._vehicles().vid, ascending=True)])
            n = len(out.vid)
            # (compiled: envs/_kernels.scatter_world_rows, the slot assignments in one call)
            scatter_world_rows(self._obs_flat, self.mask, self.rewards, self.terminated, self.truncated, b,
                               self._slots_of_vid(out.vid), out.obs.reshape(n, self._obs_flat.shape[2]),
                               out.rewards, out.terminated, out.truncated)
            if episode_finished(env):
                self.final_obs[b] = self.obs[b]
                self.truncated[b] |= self.mask[b]
                reset[b] = True
                self._reset_world(b)
        self._fill_experts()
        info = {"reset": reset, "final_obs": self._out(self.final_obs)}
        if self.expert:
            info["expert_actions"] = self._out(self.expert_actions)
        return (self._out(self.obs), self.rewards.copy(), self.terminated.copy(), self.truncated.copy(),
                self._out(self.mask), info)

    def _check_discrete(self, acts: np.ndarray) -> np.ndarray:
        """Discrete actions: every live slot's an integer (or an integer-valued
        float) in the action space's range; an error names the first bad
        world and slot. Returns them with every value that is not one (in
        empty slots only, which are ignored) set to the space's first action."""
        sp = self.single_action_space
        lo, hi = int(sp.start), int(sp.start) + int(sp.n) - 1
        if acts.dtype.kind in "iu":
            ok = (acts >= lo) & (acts <= hi)
        elif acts.dtype.kind == "f":
            with np.errstate(invalid="ignore"):
                ok = np.isfinite(acts) & (acts == np.round(acts)) & (acts >= lo) & (acts <= hi)
        else:
            raise ValueError(f"actions have dtype {acts.dtype}; allowed: integers in [{lo}, {hi}]")
        bad = ~ok & self.mask
        if np.count_nonzero(bad):
            b, k = np.argwhere(bad)[0]
            raise ValueError(f"action of world {b} slot {k} ({self.possible_agents[k]}) = {acts[b, k]!r} is invalid; "
                             f"allowed: an integer in [{lo}, {hi}]")
        return np.where(ok, acts, lo)  # (the bad values are in empty slots only)

    def close(self) -> None:
        for env in self.envs:
            env.close()
