"""The formation layer's join plans: per vehicle, the reference that takes a
member from where it is to its slot (module docstring of
:mod:`icv_envs.sim.formations`; :func:`icv_envs.formation.control.join_profile`,
paper Sec. 3.4's feedback tracks it).

A plan is made from a member's offset to its slot ``d0``, its speed relative
to the formation ``v0`` and its acceleration ``a0``: the shortest duration
``T`` whose quintic stays within the acceleration, jerk and speed limits
(compiled search), then the quintic's coefficients, stored with the plan, and
its values at ``T`` (every later time is clamped to ``T``). The plans live in
arrays indexed by vehicle id, grown as ids appear, beside the slot each plan
was made for (formation id, metres behind the front) and when the first plan
for that slot should have arrived (the stall test's deadline)."""

from __future__ import annotations

import functools

import numpy as np

from icv_envs.formation._kernels import plan_search_store, profile_eval
from icv_envs.formation.control import (
    _PROFILE_SAMPLES,
    JOIN_GROW,
    JOIN_SEARCH_CAP,
    _quintic_coeffs,
    join_profile,
)
from icv_envs.sim._kernels import id_range
from icv_envs.sim._kernels.formation_step import plan_pass

__all__ = ["JoinPlans", "JOIN_MAX_DURATION"]

#: cap of the join-plan duration search within the speed band [s]: a plan
#: that needs longer is infeasible inside the band (see :meth:`JoinPlans.plan`)
JOIN_MAX_DURATION = 120.0


@functools.lru_cache(maxsize=1)
def _default_plan_ends() -> tuple[float, ...]:
    """The default plan's (duration 1 s from rest) values at its end and its
    polynomial's coefficients, ``(fd, fv, fa, c3, c4, c5)``: computed once
    for the process (from stop 52; at every first :meth:`JoinPlans.grow`,
    each reset's, before)."""
    one, zero = np.ones(1), np.zeros(1)
    fd, fv, fa = join_profile(one, one, zero, zero, zero)
    c3, c4, c5 = _quintic_coeffs(one, zero, zero, zero)
    return tuple(float(a[0]) for a in (fd, fv, fa, c3, c4, c5))


class JoinPlans:
    """Join plans by vehicle id (module docstring).

    Args:
        limits: ``accel``, ``decel``, ``jerk`` and ``t_min`` of the profiles
            (checked by the caller).
        speeds: the speed band ``(lo, hi)`` the reference stays in [m/s].
        speed: the formation speed [m/s] (plans are relative to it).
    """

    # per vehicle id, float: the slot's place behind the front, the plan
    # (start, duration, initial offset, relative speed, acceleration, deadline),
    # its end values and its polynomial's coefficients
    FLOATS = ("slot_behind", "t0", "T", "d0", "v0", "a0", "deadline", "fd", "fv", "fa", "c3", "c4", "c5")

    def __init__(self, limits: dict, speeds: tuple, speed: float) -> None:
        self.limits = limits
        self.speeds = speeds
        self.speed = speed
        self.count = 0  # plans made: which cached profiles a plan makes stale (profile)
        self._cache = None  # (key, count when computed, profiles): see profile
        self._cap = 0
        self.slot_gid = np.zeros(0, dtype=np.int64)  # the formation a plan was made for (-1: none)
        for name in self.FLOATS:
            setattr(self, name, np.zeros(0))

    def grow(self, size: int) -> None:
        """Make room for vehicle ids below ``size`` (at least doubling); new
        ids get the default plan (duration 1 s from rest, ended)."""
        if size <= self._cap:
            return
        new = max(size, 2 * self._cap, 256)
        pad = new - self._cap
        self.slot_gid = np.concatenate([self.slot_gid, np.full(pad, -1, dtype=np.int64)])
        for name in self.FLOATS:
            setattr(self, name, np.concatenate([getattr(self, name), np.zeros(pad)]))
        self.T[self._cap:] = 1.0
        # the profile's values once it has ended (t >= T), of the default plan
        fd, fv, fa, c3, c4, c5 = _default_plan_ends()
        self.fd[self._cap:], self.fv[self._cap:], self.fa[self._cap:] = fd, fv, fa
        self.c3[self._cap:], self.c4[self._cap:], self.c5[self._cap:] = c3, c4, c5
        self._cap = new

    def capacity(self) -> int:
        """How many vehicle ids the tables hold (ids below it: :meth:`grow`)."""
        return self._cap

    def plan(self, vid: np.ndarray, d0, v0, a0, time: float) -> np.ndarray:
        """Plans for vehicles ``vid`` (non-empty) at ``time`` from offsets
        ``d0``, relative speeds ``v0`` and accelerations ``a0`` (finite);
        returns their durations."""
        self.grow(int(id_range(np.asarray(vid, dtype=np.int64))[1]) + 1)
        # no duration keeps a quintic inside the speed band when the member
        # must first reverse a large relative speed (a slow ramp vehicle
        # joining behind its slot: d0 < 0, v0 << 0 overshoots any band): the
        # search then ends at its cap and the reference would hold the
        # member's own speed for minutes. Those members get the shortest
        # plan within the acceleration and jerk limits alone; the vehicle's
        # own speed limit and the re-plan rule handle the overshoot.
        # (one compiled search for both; unchecked: d0, v0, a0 are finite
        # float64 arrays, the limits were checked when the manager was made)
        d0, v0, a0 = (np.ascontiguousarray(x, dtype=np.float64) for x in (d0, v0, a0))
        # the search's start, the search within the band (and without it for
        # the members it caps) and the store of the plans, their
        # coefficients and their values at t = T, in one compiled pass
        # (formation._kernels.plan_search_store, from stop 50; the cube
        # roots and powers libm's: that module's docstring)
        T = plan_search_store(np.asarray(vid, dtype=np.int64), float(time), d0, v0, a0, *self.search_args(),
                              *self.tables())
        self.count += len(vid)
        return T

    def plan_members(self, rows: np.ndarray, group: np.ndarray, tgt_behind: np.ndarray, anchors: np.ndarray,
                     cx: np.ndarray, speed: np.ndarray, accel: np.ndarray, vid: np.ndarray, period: float,
                     time: float) -> np.ndarray:
        """:meth:`plan` for the members at ``rows`` (non-empty, int64) of a
        formation state (rows ``vid`` sorted by id, as ``Traffic`` holds
        them): the offset from the slot ``wrap(cx - (anchors[group] -
        tgt_behind))`` (``period < 0``: a straight road), the speed relative
        to the formation and the acceleration clipped to the profile's
        limits, then :meth:`plan`'s search and store, in one compiled call
        (:func:`~icv_envs.sim._kernels.formation_step.plan_pass`, from stop
        50). Returns the durations."""
        self.grow(int(vid[-1]) + 1)
        T = plan_pass(rows, group, tgt_behind, anchors, cx, speed, accel, vid, float(self.speed), float(period),
                      float(time), *self.search_args(), *self.tables())
        self.count += len(rows)
        return T

    def search_args(self) -> tuple:
        """The compiled plan's limits and search settings, in
        :func:`~icv_envs.formation._kernels.plan_search_store`'s order
        (``accel`` .. ``tau``): the profile's acceleration, deceleration,
        jerk and shortest duration, the search's ratio and cap, the speed
        band relative to the formation, the cap without it, the sample points."""
        lim = self.limits
        return (float(lim["accel"]), float(lim["decel"]), float(lim["jerk"]), float(lim["t_min"]), JOIN_GROW,
                JOIN_MAX_DURATION, self.speeds[0] - self.speed, self.speeds[1] - self.speed, JOIN_SEARCH_CAP,
                _PROFILE_SAMPLES)

    def tables(self) -> tuple:
        """The plans' tables by vehicle id, in the compiled passes' order:
        ``t0, T, d0, v0, a0, c3, c4, c5, fd, fv, fa``."""
        return self.t0, self.T, self.d0, self.v0, self.a0, self.c3, self.c4, self.c5, self.fd, self.fv, self.fa

    def keep(self, vid: np.ndarray, time: float, P: np.ndarray) -> None:
        """Keep ``P`` (three arrays, or the rows of one ``(3, n)`` array), the
        profiles ``(d, v, a)`` of vehicles ``vid`` at ``time`` evaluated from
        these tables (by :meth:`profile`, or by the formation update's one
        call), read-only, as :meth:`profile`'s answer for them."""
        out = (P[0], P[1], P[2])
        for arr in out:
            arr.setflags(write=False)
        self._cache = ((time, vid.tobytes()), self.count, out)

    def profile(self, vid: np.ndarray, time: float, top: int | None = None):
        """``join_profile`` ``(d, v, a)`` of vehicles ``vid`` at ``time``,
        read-only. Several callers ask for the same vehicles within one step
        (the expert, the observations, the manager's own update); the last
        answer is kept, keyed on the clock and the ids, with the count of
        plans made when it was computed; once a plan was made since, all of
        them are evaluated again (one compiled call; until stop 49 only the
        re-planned ones, patched into copies of the kept arrays: the same
        numbers, the profile is element-wise, at more cost once the
        evaluation was one call). ``top``: a bound the caller knows, every
        id below it (the tables then grow to it without a search for the
        largest)."""
        key = (time, vid.tobytes())
        c = self._cache
        if c is not None and c[0] == key and c[1] == self.count:
            return c[2]  # the kept answer (these ids were in the tables when it was computed; tables only grow)
        if len(vid):
            self.grow(top if top is not None else int(id_range(np.asarray(vid, dtype=np.int64))[1]) + 1)
        self.keep(vid, time, self._eval(vid, time))
        return self._cache[2]

    def _eval(self, vid, time: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``join_profile`` of vehicles ``vid`` at ``time``: evaluated for the
        plans still running, the stored end values for those that have ended
        (``t >= T``: the quintic is evaluated at ``T`` then, so the values
        are the same numbers; :meth:`plan` stores them)."""
        # (compiled whole from stop 49: formation._kernels.profile_eval, the
        # quintic's powers libm's; before, a gather, numpy's powers and a
        # second kernel)
        P = profile_eval(vid, float(time), self.t0, self.T, self.fd, self.fv, self.fa, self.d0, self.v0, self.a0,
                         self.c3, self.c4, self.c5)
        return P[0], P[1], P[2]  # (row views)
