"""Action types of the environments, highway-env style (``config["action"]["type"]``).

Every env of this package (the Gymnasium ego and every PettingZoo agent)
takes one of these, chosen with ``config["action"] = {"type": ..., <options>}``;
whatever the type, the simulation applies normalised ``[u_a, u_s]`` controls
(:func:`action_to_controls`), held for the
``simulation_frequency / policy_frequency`` substeps of one policy step, and
the comfort reward uses those applied controls.

``ContinuousAction`` (the default)
    ``Box(-1, 1, (2,), float32)``: ``[acceleration, steering]`` as described in
    the module docstrings (``u_a * a_max`` for ``u_a >= 0``, ``-u_a * a_min``
    below, steering ``u_s * max_steering_deg``). No options.

``DiscreteMetaAction``
    ``Discrete(5)``: ``0 LANE_LEFT, 1 IDLE, 2 LANE_RIGHT, 3 FASTER, 4 SLOWER``,
    highway-env's indices. The agent decides, the paper's low-level layer
    drives (:class:`icv_envs.envs.meta_control.MetaController`): a lane
    change is a cubic Bezier curve over ``clip(v * 3 s, ...)`` metres tracked
    by preview (pure-pursuit) steering (paper Sec. 2.2 and 3.4,
    :mod:`icv_envs.formation.bezier`); the speed follows the paper's
    longitudinal feedback law (Sec. 2.2, :mod:`icv_envs.formation.control`)
    with no position reference, ``a = k_v (v - v_target)``, around the target
    speed ``target_speeds[index]``. FASTER / SLOWER move the index by one (as
    highway-env's ``MDPVehicle``); a vehicle's first index is that of the
    target speed nearest its speed. A lane change that is not possible (no
    lane there, a ramp lane outside its merge/diverge segment, inside the
    intersection box, not enough room before the stop line, or one already
    under way) is ignored, like highway-env's. There is no safety layer: the
    agent must keep its distance. Options (highway-env's names):
    ``target_speeds`` (m/s, increasing; default ``speed_range`` in 5 m/s
    steps, which contains the formation speed 25 m/s, the lane speeds 20 and
    25 m/s and, at the intersection, 0 and the desired 10 m/s),
    ``longitudinal`` and ``lateral`` (both True; with one of them False the
    space is ``Discrete(3)``: ``SLOWER, IDLE, FASTER`` or ``LANE_LEFT, IDLE,
    LANE_RIGHT``, highway-env's orders).

``FormationResidual``
    ``Box(-1, 1, (2,), float32)``: a correction ``r`` added to the env's
    expert (the formation expert, or the ``method``'s controller), applied as
    ``clip(expert + bound * r, -1, 1)``; ``r = 0`` is the expert itself. Option
    ``bound`` (a number or ``[bound_accel, bound_steer]`` in (0, 2]; default
    0.25, our choice: a quarter of each range, i.e. at most +0.75 / -1.5 m/s^2
    and +-7.5 deg on top of the expert, a correction rather than an override).

Lane-change reservations.  The expert plans lane changes for every vehicle
(its plans make the ``expert_action`` labels), and a planned lane change
lists the vehicle in its target lane for the other vehicles' controllers (a
turn signal they yield to).  Only a vehicle that carries the plan out holds
that lane: one whose action equals the expert's, or a ``FormationResidual``
agent (the expert's plan is the base of its action); a ``ContinuousAction``
or ``DiscreteMetaAction`` agent off the expert does not (before, 19.9% of
such vehicle-steps on lane-drop held a lane their vehicle was not entering:
``scripts/phantom_reservations.py``).

Anything else, or an option that the type does not have, raises ``ValueError``.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from icv_envs.envs._config import pick_type, real_numbers, typed_options
from icv_envs._ufuncs import clip as uclip


__all__ = ["ACTION_TYPES", "check_actions", "ActionType", "ContinuousAction", "DiscreteMetaAction", "FormationResidual",
           "action_factory", "action_to_controls", "controls_to_action"]


def action_to_controls(action: np.ndarray, a_min=-6.0, a_max=3.0, steer_max=math.radians(30.0)):
    """Map normalised actions ``[u_a, u_s]`` in ``[-1, 1]`` to SI controls.

    Acceleration is piecewise linear so that 0 means coasting: ``u_a >= 0``
    gives ``u_a * a_max`` and ``u_a < 0`` gives ``-u_a * a_min`` (paper Sec.
    2.2 limits, [-6, 3] m/s^2). Steering is ``u_s * steer_max`` (30 deg)."""
    action = uclip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    ua, us = action[..., 0], action[..., 1]
    a = np.where(ua >= 0, ua * a_max, -ua * a_min)
    return a, us * steer_max


def controls_to_action(a, phi, a_min=-6.0, a_max=3.0, steer_max=math.radians(30.0)) -> np.ndarray:
    """Inverse of :func:`action_to_controls` (clipped to the limits)."""
    a = np.asarray(a, dtype=np.float64)
    ua = np.where(a >= 0, a / a_max, -a / a_min)
    return uclip(np.stack([ua, np.asarray(phi) / steer_max], axis=-1), -1.0, 1.0)


def check_actions(actions, agents) -> np.ndarray:
    """The actions of ``agents`` (names, keys of the mapping ``actions``) as a
    ``(len(agents), 2)`` float64 array clipped to [-1, 1].

    Each action must be a real array-like of shape ``(2,)`` with finite
    values: a string, dict, complex, boolean or object value, a wrong shape,
    NaN/inf or a number too large for a float raise ``ValueError`` naming the
    agent and what is allowed."""
    out = np.empty((len(agents), 2), dtype=np.float64)
    allowed = "a real array of shape (2,) [acceleration, steering], finite, clipped to [-1, 1]"
    for i, who in enumerate(agents):
        a = actions[who]
        if isinstance(a, np.ndarray) and a.dtype.kind == "f" and a.shape == (2,):
            arr = a  # the common case
        else:
            if isinstance(a, (str, bytes, dict, set)) or a is None:
                raise ValueError(f"action of {who} = {a!r} ({type(a).__name__}) is invalid; allowed: {allowed}")
            try:
                arr = np.asarray(a)
            except (ValueError, TypeError, OverflowError) as exc:
                raise ValueError(f"action of {who} = {a!r} is invalid ({exc}); allowed: {allowed}") from None
            if arr.dtype.kind not in "iuf":
                raise ValueError(f"action of {who} = {a!r} has dtype {arr.dtype} (kind {arr.dtype.kind!r}); "
                                 f"allowed: {allowed}")
            if arr.shape != (2,):
                raise ValueError(f"action of {who} has shape {arr.shape}; allowed: shape (2,) [acceleration, "
                                 f"steering] in [-1, 1]")
            arr = arr.astype(np.float64)
        if not np.isfinite(arr).all():
            raise ValueError(f"action of {who} = {np.asarray(arr).tolist()} holds NaN or inf; allowed: finite values "
                             f"in [-1, 1]")
        out[i] = arr
    uclip(out, -1.0, 1.0, out=out)
    return out


def _rows(actions) -> np.ndarray:
    """Checked actions as one ``(n, 2)`` array: the batched check already
    gives one (``IcvAgentsEnv._check_actions``); a list of rows is stacked."""
    return actions if isinstance(actions, np.ndarray) else np.stack(actions)


class ActionType:
    """Converts agents' actions into the normalised controls the simulation applies."""

    name = ""
    OPTIONS: dict = {}
    #: does a vehicle driven by this type carry out the expert's lane-change
    #: plan (so that the plan's target lane is reserved for it)?
    carries_expert_plan = False

    def __init__(self, env, config: dict) -> None:
        self.env = env
        self.options = typed_options("action", self.name, self.OPTIONS, config)
        self.space = self._space()

    def _space(self) -> spaces.Space:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget per-vehicle state (called at every env reset)."""

    def check(self, action, who: str = "agent"):
        """The validated action of one agent (raises ``ValueError`` naming ``who``)."""
        raise NotImplementedError

    def check_many(self, values: list, names: list):
        """The validated actions of agents ``names`` (:meth:`check` of each)."""
        return [self.check(v, a) for a, v in zip(names, values)]

    def idle_action(self):
        """The do-nothing action of this type (the ``zero`` policies' and an empty slot's)."""
        raise NotImplementedError

    def controls(self, rows: np.ndarray, actions: list) -> np.ndarray:
        """Normalised ``[u_a, u_s]`` (len(rows), 2) for the vehicles at traffic
        ``rows`` given their checked ``actions``."""
        raise NotImplementedError

    def expert_action(self, expert_row: np.ndarray):
        """The expert's action expressed in this type's space, or None if it has no form there."""
        return None


class ContinuousAction(ActionType):
    name = "ContinuousAction"

    def _space(self):
        return spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)

    def check(self, action, who: str = "agent") -> np.ndarray:
        return check_actions({who: action}, [who])[0]

    def controls(self, rows, actions) -> np.ndarray:
        if not len(rows):
            return np.zeros((0, 2))
        return uclip(_rows(actions), -1.0, 1.0)

    def expert_action(self, expert_row):
        return np.asarray(expert_row, dtype=np.float32)

    def idle_action(self) -> np.ndarray:
        """``[0, 0]``: coast straight (``FormationResidual``: the zero residual, so the expert)."""
        return np.zeros(2, dtype=np.float32)


class FormationResidual(ContinuousAction):
    name = "FormationResidual"
    #: the expert's lane-change plan is carried out (its target lane stays reserved, World._reservations)
    carries_expert_plan = True
    OPTIONS = {"bound": 0.25}

    def __init__(self, env, config: dict) -> None:
        super().__init__(env, config)
        b = self.options["bound"]
        arr = real_numbers(b)
        arr = np.array([np.nan]) if arr is None else arr
        if arr.shape not in ((), (2,)) or not np.all(np.isfinite(arr)) or np.any(arr <= 0) or np.any(arr > 2):
            raise ValueError(f"action bound = {b!r} is invalid; allowed: a number or [bound_accel, bound_steer] "
                             f"in (0, 2]")
        self.bound = np.broadcast_to(arr, (2,)).astype(np.float64)

    def controls(self, rows, actions) -> np.ndarray:
        if not len(rows):
            return np.zeros((0, 2))
        ex = np.asarray(self.env.expert_actions(), dtype=np.float64)[rows]
        return uclip(ex + self.bound * uclip(_rows(actions), -1.0, 1.0), -1.0, 1.0)

    def expert_action(self, expert_row):
        return np.zeros(2, dtype=np.float32)


class DiscreteMetaAction(ActionType):
    name = "DiscreteMetaAction"
    OPTIONS = {"target_speeds": None, "longitudinal": True, "lateral": True}
    ACTIONS_ALL = {0: "LANE_LEFT", 1: "IDLE", 2: "LANE_RIGHT", 3: "FASTER", 4: "SLOWER"}
    ACTIONS_LONGI = {0: "SLOWER", 1: "IDLE", 2: "FASTER"}
    ACTIONS_LAT = {0: "LANE_LEFT", 1: "IDLE", 2: "LANE_RIGHT"}
    #: meta action -> (lane step, speed-index step)
    _EFFECT = {"LANE_LEFT": (-1, 0), "IDLE": (0, 0), "LANE_RIGHT": (1, 0), "FASTER": (0, 1), "SLOWER": (0, -1)}

    def __init__(self, env, config: dict) -> None:
        o = {**self.OPTIONS, **{k: v for k, v in config.items() if k != "type"}}
        for k in ("longitudinal", "lateral"):
            if not isinstance(o[k], (bool, np.bool_)):
                raise ValueError(f"action {k} = {o[k]!r}; allowed: True or False")
        if not (o["longitudinal"] or o["lateral"]):
            raise ValueError("action longitudinal and lateral are both False; allowed: at least one of them True")
        self.actions = (self.ACTIONS_ALL if o["longitudinal"] and o["lateral"]
                        else self.ACTIONS_LONGI if o["longitudinal"] else self.ACTIONS_LAT)
        lo, hi = (float(v) for v in env.config["speed_range"])
        ts = o["target_speeds"]
        if ts is None:
            ts = np.arange(lo, hi + 1e-9, 5.0)
            if ts[-1] < hi - 1e-9:
                ts = np.append(ts, hi)
        arr = real_numbers(ts)
        arr = np.array([np.nan]) if arr is None else arr
        if arr.ndim != 1 or len(arr) < 1 or not np.all(np.isfinite(arr)) or np.any(np.diff(arr) <= 0) \
                or arr[0] < 0 or arr[-1] > hi:
            raise ValueError(f"action target_speeds = {ts!r}; allowed: increasing speeds in [0, v_max = {hi}] m/s")
        self.target_speeds = arr
        self._effects = np.array([self._EFFECT[self.actions[i]] for i in range(len(self.actions))], dtype=np.int64)
        super().__init__(env, config)
        from icv_envs.envs.meta_control import MetaController

        self.controller = MetaController(env, self.target_speeds)

    def _space(self):
        return spaces.Discrete(len(self.actions))

    def reset(self) -> None:
        self.controller.reset()

    def check(self, action, who: str = "agent") -> int:
        arr = np.asarray(action)
        n = len(self.actions)
        ok = arr.size == 1 and arr.ndim <= 1 and (np.issubdtype(arr.dtype, np.integer) or (
            np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and float(arr.reshape(-1)[0]).is_integer()))
        if not ok or not 0 <= int(arr.reshape(-1)[0]) < n:
            raise ValueError(f"action of {who} = {action!r} is invalid; allowed: an integer in [0, {n - 1}] "
                             f"({', '.join(f'{i} {a}' for i, a in self.actions.items())})")
        return int(arr.reshape(-1)[0])

    def check_many(self, values: list, names: list):
        """:meth:`check` of every agent at once when every value is an integer
        scalar (a learner's or the batch's numpy integers) in range: one
        array, the same indices (from stop 45: the per-agent check was a tenth
        of a discrete step); anything else goes through :meth:`check`, whose
        error names the agent."""
        if set(map(type, values)) <= _INT_SCALARS:
            try:
                arr = np.fromiter(values, dtype=np.int64, count=len(values))
            except OverflowError:
                arr = None
            if arr is not None and (not len(arr) or (int(arr.min()) >= 0 and int(arr.max()) < len(self.actions))):
                return arr
        return super().check_many(values, names)

    def controls(self, rows, actions) -> np.ndarray:
        if not len(rows):
            return np.zeros((0, 2))
        eff = self._effects[np.asarray(actions, dtype=np.int64)]
        return self.controller.controls(np.asarray(rows), eff[:, 0], eff[:, 1])

    def action_mask(self, meaningful: bool = True) -> np.ndarray:
        """All actions allowed (the env ignores impossible lane changes); an
        empty slot of :class:`icv_envs.rl.slots.SlotParallelEnv` allows IDLE only."""
        m = np.ones(len(self.actions), dtype=np.int8)
        if not meaningful:
            m[:] = 0
            m[self.idle_action()] = 1
        return m

    def idle_action(self) -> int:
        """The index of ``IDLE`` (keep the lane and the target speed)."""
        return next(k for k, a in self.actions.items() if a == "IDLE")


#: the integer scalar types :meth:`DiscreteMetaAction.check_many` takes at once (bool is not among them)
_INT_SCALARS = frozenset({int, np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64})

ACTION_TYPES = {c.name: c for c in (ContinuousAction, DiscreteMetaAction, FormationResidual)}


def action_factory(env, config: dict) -> ActionType:
    """The action type of ``config`` (``config["type"]``, default ContinuousAction)."""
    return pick_type("action", config, ACTION_TYPES, "ContinuousAction")(env, config)
