"""A fixed set of ``K`` agent slots over a PettingZoo env of this package.

On the open roads (HighwayRamps, Intersection) vehicles arrive and leave all
episode long; MARL libraries mostly want a fixed agent set (SuperSuit's
vector envs assert ``agents == possible_agents``, RLlib's stock
``ParallelPettingZooEnv`` takes its agent ids from the first reset, TorchRL's
``PettingZooWrapper`` builds fixed-size groups). :class:`SlotParallelEnv`
presents any env of the package as ``K`` agents ``slot_0 .. slot_{K-1}``,
every one of them in ``agents`` from ``reset`` until the episode ends:

* **Assignment.** A vehicle that appears takes the lowest free slot and keeps
  it until it leaves (crash, exit, end of road); its final transition (last
  observation, reward, the env's flags as ``info["vehicle_terminated"]`` /
  ``info["vehicle_truncated"]``) is reported in the slot, which is free from
  the next step on and is then reused by the next vehicle that needs one.
* **Empty slots** (the placeholders) observe zeros (never a real observation:
  row 0's presence is 1 for a vehicle in the Kinematics layout), get reward 0,
  and their action is ignored; ``info["active"]`` is False and, with
  ``DiscreteMetaAction``, ``info["action_mask"]`` allows IDLE only (TorchRL's
  ``PettingZooWrapper`` reads it into the group's ``action_mask``).
  ``info["acted"]`` says whether the slot's action of this step drove a vehicle,
  i.e. whether its transition (reward) is real.
* **Episode end.** Slots never terminate mid-episode (PettingZoo would require
  them to leave ``agents``); when the env's episode is over (``duration``,
  ``max_cycles``, or a closed road with no vehicles left nor due) every slot is
  truncated at once. A slot is a persistent agent whose vehicles succeed one
  another, so a learner that bootstraps across a hand-over (SB3 via SuperSuit,
  RLlib) values a slot by the return of its future vehicles; learners that
  want per-vehicle episodes cut the bootstrap at ``info["vehicle_done"]``
  (:class:`icv_envs.rl.ParallelVecEnv` does per-vehicle episodes for SB3).
* **Overflow.** If more vehicles are alive than ``K``, the ones without a slot
  are driven by the env's expert (the wrapped env runs with
  ``missing_action="expert"``) and take a slot, oldest first, as soon as one
  frees; ``overflow_vehicle_steps`` counts those vehicle-steps (0 in a run
  means every vehicle was the learner's) and ``placeholder_fraction`` the
  share of empty slot-steps. A slot left out of the actions dict is also
  driven by the expert; a key that is not a slot is an error.

``K`` (:func:`slot_count`, from the config, not one per possible arrival):

* HighwayFormation: ``vehicles_count + len(spawns)``, a hard bound (every
  vehicle could be on the road at once);
* HighwayRamps and Intersection: an M/G/inf estimate. Arrivals come at the
  rate ``lam`` (ramps: ``vgr * ramps``; intersection: ``throughput / 3600``)
  and stay for the free-flow trip time ``W`` (ramps: the mean, over on-ramps
  and allowed exits, of the distance from the spawn point to the end of the
  off-ramp at the formation speed; intersection: spawn point to the end of
  the departure lane along the mean path through the box at the desired
  speed). At time ``t`` into the episode (after ``warmup``) the mean number
  alive is ``m = lam * min(t, W)``; with arrivals in batches of ``b``
  (intersection: ``formation_size``; ramps: 1) the count's standard deviation
  is ``sqrt(b m)``. ``K = ceil(m_peak + z sqrt(b m_peak))`` with
  ``m_peak = lam * min(duration + warmup, W)`` and ``z = 1`` (one standard
  deviation: at steady state the placeholders are about ``sigma / (m + sigma)``
  of the slot-steps, and the count exceeds ``K``, handing the extra vehicles to
  the expert, in roughly one step in six under the normal approximation);
  capped by the env's possible agents. Delays (queues at the intersection,
  merges) lengthen the real trip time, so congestion shows up as overflow.
  Pass ``slots=`` to choose ``K`` yourself, ``z=`` to change the margin.

The placeholder share also counts the ramp-up at the start of an episode (the
roads start empty): configure ``warmup`` (intersection) to start in steady
state. ``module(name)`` gives a PettingZoo-style module (``parallel_env``,
``env``, ``raw_env``) of the slot layout, e.g. for ``pettingzoo.test``.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from icv_envs.rl.envs import episode_finished, make_parallel_env, resolve_env

__all__ = ["SlotParallelEnv", "VehicleEpisodes", "slot_count", "slot_parallel_env", "vehicle_slots_env", "module"]


def _trip_time_ramps(c: dict) -> float:
    L, sp = float(c["road_length"]), float(c["ramp_spacing"])
    n = int(c["ramps"])
    exits = list(range(n)) if c["exit_choices"] is None else [int(e) for e in c["exit_choices"]]
    v = float(c["formation"]["speed"])
    vr = float(c["ramp_speed"])
    total = 0.0
    for k in range(n):
        spawn = float(c["first_on_ramp"]) + k * sp - float(c["on_ramp_approach"]) + 5.0
        merge_end = float(c["first_on_ramp"]) + k * sp + float(c["merge_length"])
        for e in exits:
            end = float(c["first_off_ramp"]) + e * sp + float(c["diverge_length"]) + float(c["off_ramp_length"])
            d = (end - merge_end) % L
            if d < float(c["diverge_length"]) + float(c["off_ramp_length"]):
                d += L  # the exit lies in the merge: once round
            total += (merge_end - spawn) / vr + d / v
    return total / (n * len(exits))


def _trip_time_intersection(core) -> float:
    c = core.config
    lay = core.layout
    lengths = np.asarray(lay.L, dtype=np.float64)
    path = float(lengths[lengths > 0].mean()) if np.any(lengths > 0) else 2.0 * lay.box_half
    dist = (lay.R3 - lay.box_half) + path + float(c["departure_length"])
    return dist / float(c["desired_speed"])


def _check_z(z) -> None:
    """``z``, the margin of :func:`slot_count` in standard deviations above the mean: a finite real >= 0."""
    if isinstance(z, (bool, np.bool_)) or not isinstance(z, (int, float, np.integer, np.floating)) \
            or not math.isfinite(z) or z < 0:
        raise ValueError(f"z = {z!r}; allowed: a finite number >= 0 (the slot margin in standard deviations "
                         f"above the mean number of vehicles alive)")


def _check_actions(actions, allowed: list, what: str) -> None:
    """``actions`` must be a dict whose keys are all in ``allowed`` (``what`` names them)."""
    if not isinstance(actions, dict):
        raise ValueError(f"actions must be a dict {{name: action}}, got {type(actions).__name__}; "
                         f"allowed names: {what} {allowed}")
    allowed_set = set(allowed)
    unknown = [a for a in actions if a not in allowed_set]
    if unknown:
        raise ValueError(f"actions for names that are not {what}: {unknown}; allowed: {allowed}")


def slot_count(par_env, z: float = 1.0) -> int:
    """``K`` for the PettingZoo env ``par_env`` (see the module docstring)."""
    _check_z(z)
    core = par_env.core
    c = core.config
    P = len(par_env.possible_agents)
    name = type(core).__name__
    if name == "HighwayFormationEnv":
        return max(1, min(P, int(c["vehicles_count"]) + len(c["spawns"])))
    if name == "HighwayRampsEnv":
        lam, W, b = float(c["vgr"]) * int(c["ramps"]), _trip_time_ramps(c), 1.0
        horizon = float(c["duration"])
    elif name == "IntersectionEnv":
        lam, W, b = float(c["throughput"]) / 3600.0, _trip_time_intersection(core), float(c["formation_size"])
        horizon = float(c["duration"]) + float(c["warmup"])
    else:
        return max(1, P)
    m = lam * min(horizon, W)
    return max(1, min(P, int(math.ceil(m + z * math.sqrt(b * m)))))


class SlotParallelEnv(ParallelEnv):
    """``K`` fixed agents over ``env`` (a PettingZoo parallel env of this
    package, built with ``missing_action="expert"``); see the module docstring."""

    def __init__(self, env, slots: int | None = None, z: float = 1.0) -> None:
        _check_z(z)
        core = env.core
        if core.config["missing_action"] != "expert":
            raise ValueError("SlotParallelEnv needs the env built with missing_action='expert' (vehicles without a "
                             f"slot are driven by the expert); got missing_action={core.config['missing_action']!r}")
        if slots is None:
            slots = slot_count(env, z)
        if isinstance(slots, bool) or not isinstance(slots, (int, np.integer)) or slots < 1:
            raise ValueError(f"slots = {slots!r}; allowed: None (derived from the config) or an integer >= 1")
        self.env = env
        self.K = int(slots)
        self.possible_agents = [f"slot_{i}" for i in range(self.K)]
        self.agents: list[str] = []
        self.render_mode = env.render_mode
        self.metadata = dict(env.metadata, name=f"{env.metadata['name']}_slots")
        self._obs_space = env.observation_space(env.possible_agents[0])
        self._act_space = env.action_space(env.possible_agents[0])
        self.observation_spaces = {a: self._obs_space for a in self.possible_agents}
        self.action_spaces = {a: self._act_space for a in self.possible_agents}
        self.state_space = core.state_space_for(self.K)
        self._discrete = isinstance(self._act_space, spaces.Discrete)
        self._zero_obs = np.zeros(self._obs_space.shape, dtype=self._obs_space.dtype)
        self.slot_steps = self.placeholder_steps = self.overflow_vehicle_steps = 0

    # ------------------------------------------------------------- PettingZoo
    def observation_space(self, agent):
        return self._obs_space

    def action_space(self, agent):
        return self._act_space

    @property
    def core(self):
        return self.env.core

    @property
    def placeholder_fraction(self) -> float:
        """Share of slot-steps since construction whose action drove no vehicle."""
        return self.placeholder_steps / self.slot_steps if self.slot_steps else 0.0

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self._slot = [None] * self.K  # vehicle agent name per slot
        self._waiting: list[str] = []  # vehicles without a slot, oldest first
        self._assign([a for a in obs], set())
        self.agents = list(self.possible_agents)
        o = {s: obs[v] if v is not None else self._zero_obs for s, v in zip(self.possible_agents, self._slot)}
        self._raw_infos = infos
        i = {s: self._info(v, infos, acted=False, done=(False, False)) for s, v in zip(self.possible_agents, self._slot)}
        return o, i

    def _assign(self, new: list[str], finished: set[str]) -> None:
        """Give free slots to waiting vehicles (oldest first), then to new ones."""
        free = [i for i, v in enumerate(self._slot) if v is None]
        queue = [v for v in self._waiting if v not in finished] + [v for v in new if v not in finished]
        self._waiting = []
        for v in queue:
            if free:
                self._slot[free.pop(0)] = v
            else:
                self._waiting.append(v)

    def _info(self, v, infos, acted: bool, done: tuple) -> dict:
        raw = infos.get(v, {}) if v is not None else {}
        ex = raw.get("expert_action")
        info = {
            "active": v is not None and not (done[0] or done[1]),
            "acted": bool(acted),
            "vehicle": int(v[4:]) if v is not None else -1,
            "vehicle_done": bool(done[0] or done[1]),
            "vehicle_terminated": bool(done[0]),
            "vehicle_truncated": bool(done[1]),
            "crashed": bool(raw.get("crashed", False)),
            "expert_action": np.asarray(ex if ex is not None else np.zeros(2), dtype=np.float32),
        }
        if self._discrete:
            info["action_mask"] = self.core._act_type.action_mask(meaningful=info["active"])
        return info

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("the episode is over: call reset()")
        _check_actions(actions, self.possible_agents, "slots")
        live = set(self.env.agents)
        act, acted = {}, [False] * self.K
        for i, (s, v) in enumerate(zip(self.possible_agents, self._slot)):
            if v is not None and v in live and s in actions:
                act[v] = actions[s]
                acted[i] = True
        self.overflow_vehicle_steps += sum(1 for v in self._waiting if v in live)
        obs, rew, term, trunc, infos = self.env.step(act)
        self._raw_infos = infos
        o, r, te, tr, inf = {}, {}, {}, {}, {}
        finished = {a for a in obs if term[a] or trunc[a]}
        freed = []
        for i, (s, v) in enumerate(zip(self.possible_agents, self._slot)):
            if v is not None and v in obs:
                o[s], r[s] = obs[v], float(rew[v])
                inf[s] = self._info(v, infos, acted[i], (bool(term[v]), bool(trunc[v])))
                if v in finished:
                    freed.append(i)
            else:
                o[s], r[s] = self._zero_obs, 0.0
                inf[s] = self._info(None, infos, False, (False, False))
            te[s], tr[s] = False, False
        held = set(self._slot) | set(self._waiting)
        self._assign([a for a in obs if a not in held], finished)
        self.slot_steps += self.K
        self.placeholder_steps += self.K - sum(acted)
        # the newly assigned vehicles' first observations replace empty slots' zeros
        for i, v in enumerate(self._slot):
            s = self.possible_agents[i]
            if v is not None and not inf[s]["active"] and i not in freed and v in obs:
                o[s] = obs[v]
                inf[s] = self._info(v, infos, False, (False, False))
        for i in freed:  # free from the next step on
            self._slot[i] = None
        if episode_finished(self.env):
            tr = {s: True for s in self.possible_agents}
            self.agents = []
        return o, r, te, tr, inf

    def state(self) -> np.ndarray:
        """The core env's global state, one row per slot (zeros for empty slots)."""
        return self.core.global_state([v if v is not None else "" for v in self._slot])

    def render(self):
        return self.env.render()

    def close(self) -> None:
        self.env.close()

    def slot_vehicles(self) -> list:
        """The vehicle agent name in each slot (None: empty)."""
        return list(self._slot)


def slot_parallel_env(name, config: dict | None = None, slots: int | None = None, z: float = 1.0,
                      max_cycles: int | None = None, render_mode: str | None = None) -> SlotParallelEnv:
    """:class:`SlotParallelEnv` over the PettingZoo env ``name`` (id or module
    name) with ``config`` (``missing_action`` is set to ``"expert"``)."""
    _check_z(z)
    cfg = dict(config or {})
    if cfg.get("missing_action", "expert") != "expert":
        raise ValueError(f"missing_action = {cfg['missing_action']!r}; the slot layout needs 'expert'")
    cfg["missing_action"] = "expert"
    spec = resolve_env(name)
    par = make_parallel_env(spec, dict(cfg, **({"max_cycles": max_cycles} if max_cycles is not None else {})),
                            render_mode=render_mode)
    return SlotParallelEnv(par, slots=slots, z=z)


class VehicleEpisodes:
    """Per-vehicle episodes on the ``K`` slots of a :class:`SlotParallelEnv`,
    for learners that want one episode per vehicle (SB3 through
    :class:`icv_envs.rl.ParallelVecEnv`).

    The slot layout keeps every slot in ``agents`` until the env's episode
    ends and reports a vehicle's departure only in ``info["vehicle_done"]``
    (PettingZoo forbids agents leaving and coming back). This view is the
    other reading of the same slots: ``agents`` are the slots that hold a
    live vehicle; a slot's agent *terminates* or is *truncated* with its
    vehicle (the env's own flags, ``info["vehicle_terminated"]`` /
    ``info["vehicle_truncated"]``), leaves ``agents``, and appears again when
    the next vehicle is given the slot (an episode start). Empty slots are
    absent, not zeros. So ``ParallelVecEnv(lambda: VehicleEpisodes(...))``
    has ``K`` VecEnv slots instead of one per possible arrival (the open roads'
    placeholders fall from 98-99% to the slot layout's share), and no value is
    bootstrapped across a hand-over from one vehicle to the next.

    Vehicles that find every slot taken are driven by the env's expert (the
    slot layout's overflow) and are not part of the learner's data. This is a
    training adapter with the ``ParallelEnv`` calls ParallelVecEnv makes
    (``reset``, ``step``, ``agents``, ``possible_agents``, the spaces,
    ``episode_over``, ``core``); it is not a PettingZoo env (an agent that
    terminated comes back), so PettingZoo's API test does not apply to it.
    """

    def __init__(self, slot_env: SlotParallelEnv) -> None:
        if not isinstance(slot_env, SlotParallelEnv):
            raise TypeError(f"VehicleEpisodes needs a SlotParallelEnv; got {type(slot_env).__name__}")
        self.slot_env = slot_env
        self.possible_agents = list(slot_env.possible_agents)
        self.agents: list[str] = []
        self.metadata = slot_env.metadata
        self.render_mode = slot_env.render_mode
        self._over = True

    def observation_space(self, agent):
        return self.slot_env.observation_space(agent)

    def action_space(self, agent):
        return self.slot_env.action_space(agent)

    @property
    def core(self):
        return self.slot_env.core

    @property
    def episode_over(self) -> bool:
        return self._over

    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, infos = self.slot_env.reset(seed=seed, options=options)
        self._over = False
        self.agents = [s for s in self.possible_agents if infos[s]["active"]]
        return {s: obs[s] for s in self.agents}, {s: infos[s] for s in self.agents}

    def step(self, actions: dict):
        if self._over:
            raise RuntimeError("the episode is over: call reset()")
        _check_actions(actions, self.agents, "agents (the slots holding a live vehicle)")
        before = set(self.agents)
        obs, rew, _te, tr, infos = self.slot_env.step(actions)
        o, r, te, trn, inf = {}, {}, {}, {}, {}
        agents = []
        for s in self.possible_agents:
            info = infos[s]
            if s in before:  # the slot's vehicle acted: its transition, maybe its last
                o[s], r[s], inf[s] = obs[s], float(rew[s]), info
                te[s] = bool(info["vehicle_terminated"])
                trn[s] = bool(info["vehicle_truncated"]) or (bool(tr[s]) and not te[s])
                if not (te[s] or trn[s]):
                    agents.append(s)
            elif info["active"]:  # a vehicle was given the empty slot: its first observation
                o[s], r[s], inf[s] = obs[s], 0.0, info
                te[s], trn[s] = False, bool(tr[s])
                if not trn[s]:
                    agents.append(s)
        self._over = not self.slot_env.agents
        self.agents = [] if self._over else agents
        return o, r, te, trn, inf

    def render(self):
        return self.slot_env.render()

    def close(self) -> None:
        self.slot_env.close()


def vehicle_slots_env(name, config: dict | None = None, slots: int | None = None, z: float = 1.0) -> VehicleEpisodes:
    """:class:`VehicleEpisodes` over :func:`slot_parallel_env` ``(name, config, slots, z)``."""
    return VehicleEpisodes(slot_parallel_env(name, config, slots=slots, z=z))


def module(name, config: dict | None = None, slots: int | None = None, z: float = 1.0) -> SimpleNamespace:
    """A PettingZoo-style module of the slot layout of ``name``: ``parallel_env``,
    ``raw_env`` (AEC, converted) and ``env`` (AEC with the order-enforcing wrapper)."""
    from pettingzoo.utils.conversions import parallel_to_aec_wrapper
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper

    _check_z(z)

    def parallel_env(render_mode=None, max_cycles=None, **kw):
        return slot_parallel_env(name, {**(config or {}), **kw}, slots=slots, z=z, max_cycles=max_cycles,
                                 render_mode=render_mode)

    def raw_env(render_mode=None, max_cycles=None, **kw):
        return parallel_to_aec_wrapper(parallel_env(render_mode=render_mode, max_cycles=max_cycles, **kw))

    def env(render_mode=None, max_cycles=None, **kw):
        return OrderEnforcingWrapper(raw_env(render_mode=render_mode, max_cycles=max_cycles, **kw))

    return SimpleNamespace(parallel_env=parallel_env, raw_env=raw_env, env=env)
