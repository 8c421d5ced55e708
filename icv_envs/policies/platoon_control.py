"""The intersection expert's control (paper Sec. 4.3 and Sec. 5's controller):
from the coordination layer's per-vehicle modes and references
(:mod:`icv_envs.policies.regrouping`, :mod:`icv_envs.policies.virtual_platoon`)
to the normalised ``(n, 2)`` actions every vehicle takes through the agents'
action space: pure-pursuit steering along the lane, the lane-change curve or
the path through the box (eq. (Bezier) and the preview law); the
longitudinal feedback law (eq. (22)) on the reference; and the safety
envelope over it (the leader in the vehicle's corridors, stopped vehicles on
its path, the safe-speed cap of the virtual platoon). A mixin of
:class:`icv_envs.policies.platoon_expert.PlatoonExpert`, whose parameters
(``p``, checked once when it is made), state and coordination it uses."""

from __future__ import annotations

import numpy as np

from icv_envs.policies._kernels import (
    box_obstacle_rows,
    box_steering,
    envelope_pairs,
    idm_free_pow,
    normalised_actions,
    platoon_accelerations,
    platoon_actions_rows,
    stop_line_caps,
)
from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_TREE, Corridors
from icv_envs.sim.traffic import idm_acceleration
from icv_envs._hooks import own_hooks
from icv_envs._ufuncs import clip as uclip, flatnonzero

__all__ = ["PlatoonControl"]

# (read-only empty arrays: the one-call path's unused arguments, one numba specialisation)
_EMPTY_F = np.zeros(0)
_EMPTY_I = np.zeros(0, dtype=np.int64)
_EMPTY_B = np.zeros(0, dtype=bool)
for _a in (_EMPTY_F, _EMPTY_I, _EMPTY_B):
    _a.setflags(write=False)
#: ``(free_pow, mode, xref, vref, tight, vcap)`` for a longitudinal law the one-call path does not run
_UNUSED_LONG = (_EMPTY_F, _EMPTY_I, _EMPTY_F, _EMPTY_F, _EMPTY_B, _EMPTY_F)
#: the speed below which a vehicle in the box is an obstacle (:meth:`PlatoonControl._path_obstacles`' default)
_V_STOPPED = 1.0


class PlatoonControl:
    """Steering, longitudinal law and safety envelope of :class:`~icv_envs.policies.platoon_expert.PlatoonExpert` (module docstring)."""

    # the hooks the one-call path of ``compute`` stands for, and the longitudinal
    # law it computes itself unless replaced (FCFS's): set by PlatoonExpert
    # (icv_envs._hooks.hook_table of its own methods)
    _ONE_CALL_HOOKS: tuple | None = None
    _LONGITUDINAL_HOOK: tuple | None = None

    def compute(self, world) -> np.ndarray:
        """Normalised actions ``(n, 2)`` for every vehicle (rows in fleet
        order): the steering (:meth:`_steering`), the longitudinal law
        (:meth:`_longitudinal`) and the safety envelope over it
        (:meth:`_envelope`), normalised. While the steering and the
        envelope (its leader caps, its end and the path obstacles:
        ``PlatoonExpert._ONE_CALL_HOOKS``) are this class's own, in one
        compiled call (:func:`~icv_envs.policies._kernels.platoon_actions_rows`,
        from stop 47: the same kernels with the same arguments in their
        order; the longitudinal law too unless it is replaced; the turn
        signals, groups and coordination flags from their hooks), with the
        envelope's path obstacles added in Python when a vehicle stands in
        the box. Both paths take their arguments from the same builders
        (:meth:`_steering_args` and the others); ``tests/test_platoon_one_call.py``
        holds them equal step by step."""
        f = world.fleet
        if f.n == 0:
            return np.zeros((0, 2))
        self._check_stamp(world)
        rs = world.route()
        p = self.p
        if self._ONE_CALL_HOOKS is not None and own_hooks(self, self._ONE_CALL_HOOKS):
            return self._compute_one_call(world, rs)
        phi = self._steering(world, rs)
        acc = self._longitudinal(world, rs)
        cap = self._envelope(world, rs, acc)
        # normalised: a / a_max for a >= 0, else -a / a_min; phi / steer_max;
        # both clipped to [-1, 1] (compiled: policies/_kernels.normalised_actions)
        return normalised_actions(uclip(np.minimum(acc, cap), p.a_min, p.a_max), phi, float(p.a_max),
                                  float(p.a_min), float(p.steer_max))

    def _compute_one_call(self, world, rs) -> np.ndarray:
        """:meth:`compute` through :func:`~icv_envs.policies._kernels.platoon_actions_rows`
        (its docstring), from the argument builders the separate calls use:
        :meth:`_steering_args`, :meth:`_longitudinal_args` (or the replaced
        law's accelerations), the index without signals and the signals of
        :meth:`_envelope`, :meth:`_envelope_pairs_args`, the stopped-vehicle
        test of :meth:`_path_obstacles` and :meth:`_stop_line_args`."""
        p = self.p
        f = world.fleet
        if own_hooks(self, self._LONGITUDINAL_HOOK):
            acc_given, long_args = _EMPTY_F, self._longitudinal_args(world, rs)
        else:  # (a longitudinal law of its own: its accelerations; the base law's arguments unused)
            acc_given = np.ascontiguousarray(self._longitudinal(world, rs), dtype=np.float64)
            long_args = self._longitudinal_args(world, rs, _UNUSED_LONG)
        base = Corridors.plain(world, rs)
        done, actions, W, binding, passed, n_other, n_member = platoon_actions_rows(
            *self._steering_args(world, rs), acc_given, *long_args, base.rows, base.corr, base.coord, base.keys,
            np.asarray(self._signals(f), dtype=np.int64), Corridors.BIG,
            *self._envelope_pairs_args(f, rs, bool(p.envelope_in_box)), rs.L, _V_STOPPED,
            *self._stop_line_args(world, rs))
        st = self.stats
        st["virtual_cap_binding"] += int(binding)
        st["signal_alongside_passed"] += int(passed)
        if done:
            st["envelope_box_binding"] += int(n_other)
            st["envelope_box_binding_member"] += int(n_member)
            return actions
        # a vehicle stands in the box: the envelope's end as _envelope's, from the caps so far
        phi, acc, cap, cap_other = W
        self._envelope_tail(world, rs, acc, cap, cap_other)
        return normalised_actions(uclip(np.minimum(acc, cap), p.a_min, p.a_max), phi, float(p.a_max),
                                  float(p.a_min), float(p.steer_max))

    def _steering(self, world, rs) -> np.ndarray:
        """Pure-pursuit steering along the kept lane, the lane-change curve or
        the path through the box (compiled: :func:`icv_envs.policies._kernels.box_steering`;
        the array code it replaced is its reference in ``tests/test_box_steering.py``)."""
        return box_steering(*self._steering_args(world, rs))

    def _steering_args(self, world, rs) -> tuple:
        """:func:`~icv_envs.policies._kernels.box_steering`'s arguments (for
        :meth:`_steering` and the one-call path)."""
        p = self.p
        f = world.fleet
        lay = world.layout
        # (unchecked: the parameters were checked once, _check_params; the
        # states are finite float64 arrays)
        return (f.x, f.y, f.heading, f.speed, f.klane, f.mv, rs.pid, rs.phase, rs.s, rs.u, f.lc_lane, f.lc_u0,
                f.lc_lat0, f.lc_lat1, f.lc_len, f.leg, lay.L, lay.P0, lay.D0, lay.P1, lay.D1, lay.arc, lay.TH0, lay.SGN,
                lay.R, lay.C, float(lay.box_half), lay.out, lay.app_dir, lay.app_right, float(lay.lane_width),
                float(p.preview_min), float(p.preview_time), float(p.wheelbase), float(p.steer_max))

    def _longitudinal(self, world, rs) -> np.ndarray:
        """Every vehicle the IDM without a leader; followers (``MODE_FOLLOW``)
        the feedback law on their reference in the comfort range; tree
        vehicles (``MODE_TREE``) the feedback law on their reference in
        ``X``, with full braking where the safety bound binds (``tight``),
        capped by the virtual cap. The reference error is clipped to
        ``ref_error_clip`` first. Compiled
        (:func:`icv_envs.policies._kernels.platoon_accelerations`, the
        arithmetic of the array code it replaced, frozen in
        ``tests/test_expert_kernels.py``); the IDM's power from numpy."""
        acc, binding = platoon_accelerations(*self._longitudinal_args(world, rs))
        self.stats["virtual_cap_binding"] += int(binding)
        return acc

    def _longitudinal_args(self, world, rs, unused: tuple | None = None) -> tuple:
        """:func:`~icv_envs.policies._kernels.platoon_accelerations`'
        arguments (for :meth:`_longitudinal` and the one-call path; with
        ``unused``, the one-call path of an expert whose law is its own:
        empty arrays ``(free_pow, mode, xref, vref, tight, vcap)`` in place
        of the per-vehicle inputs, which it does not read)."""
        p = self.p
        f = world.fleet
        v = f.speed
        if unused is None:
            # (compiled from stop 50: the power libm's, numpy's before)
            free_pow = idm_free_pow(np.asarray(v, dtype=np.float64), float(np.maximum(p.v0, 0.1)))
            vcap = self._vcap if len(self._vcap) == f.n else np.zeros(f.n)
            mode, xref, vref, tight = self._mode, self._xref, self._vref, self._tight
        else:
            free_pow, mode, xref, vref, tight, vcap = unused
        return (v, free_pow, float(min(p.a_max, p.comfort[1])), float(p.idm_b), float(p.idm_T), float(p.idm_s0),
                mode, MODE_FOLLOW, MODE_TREE, rs.u, rs.X, xref, vref, tight, vcap, float(p.ref_error_clip),
                float(p.kp), float(p.kv), float(p.comfort[0]), float(p.comfort[1]), float(p.a_min), float(p.a_max))

    def _envelope(self, world, rs, acc_ref) -> np.ndarray:
        """IDM interaction cap towards the leader in every corridor (module docstring)."""
        p = self.p
        f = world.fleet
        n = f.n
        cor = Corridors.with_signals(world, rs, self._signals(f))
        cap = np.full(n, np.inf)
        cap_other = np.full(n, np.inf)
        # towards the leader in every corridor (compiled: policies/_kernels.envelope_pairs;
        # the array code it replaced is its reference in tests/test_box_steering.py):
        # a vehicle waiting to change into this lane holds back only the
        # vehicles behind it: one already alongside (bumper gap < 0) goes
        # on, or it would stand beside the waiting vehicle, whose lane
        # change it blocks, for ever (single-vp, 3000 veh/h, seed 0:
        # gridlock from t = 215 s); its leader is then the next one ahead.
        # A member of the leader's group, or a coordinated vehicle (tree /
        # reservation, or one that has left the box) behind another one past
        # the stop line, keeps a short time gap (the coordination keeps them
        # apart). Gipps (1981) safe speed on top: stop behind the leader even
        # if it brakes at |a_min| from now on and this vehicle reacts one
        # policy period (cap_tau) later; IDM's interaction term alone does
        # not guarantee it when a member closes in fast on a leader that
        # brakes hard. ``cap_other``: the same towards leaders of another
        # group only (in the box, that is what the coordination must make
        # unnecessary)
        self.stats["signal_alongside_passed"] += self._envelope_pairs(f, rs, cor, bool(p.envelope_in_box), cap,
                                                                      cap_other)
        self._envelope_tail(world, rs, acc_ref, cap, cap_other)
        return cap

    def _envelope_tail(self, world, rs, acc_ref, cap, cap_other) -> None:
        """The end of :meth:`_envelope`, on the caps towards the leaders
        (lowered in place): the vehicles stopped on a path, then the stop
        line and the binding counts."""
        p = self.p
        f = world.fleet
        # a (nearly) stopped vehicle in the box on this vehicle's path, whatever its own path
        qi, oj, og, vo = self._path_obstacles(world, rs)
        if len(qi):
            v = f.speed[qi]
            safe = idm_acceleration(v, p.v_max, og, v - vo, p.a_max, p.idm_b, p.idm_T, p.idm_s0, free_term=False)
            safe = np.minimum(safe, self._gipps(v, vo, og - p.member_s0))
            np.minimum.at(cap, qi, safe)
            np.minimum.at(cap_other, qi, safe)
            self.stats["path_obstacle_binding"] += int((safe < 0).sum())
        # stop line for vehicles that may not enter (the IDM's interaction
        # term towards it, s0 = 0.5 m); then the in-box vehicles whose cap
        # binds, towards another group's leader or a member's (compiled:
        # policies/_kernels.stop_line_caps, from stop 41; the array code it
        # replaced is frozen in tests/test_box_steering.py)
        n_other, n_member = stop_line_caps(*self._stop_line_args(world, rs), cap, cap_other, rs.phase, acc_ref)
        self.stats["envelope_box_binding"] += n_other
        self.stats["envelope_box_binding_member"] += n_member

    def _stop_line_args(self, world, rs) -> tuple:
        """:func:`~icv_envs.policies._kernels.stop_line_caps`' arguments
        before the caps (the IDM's interaction term towards the stop line,
        ``s0 = 0.5 m``)."""
        p = self.p
        f = world.fleet
        return (self._stop, rs.u, f.length, f.speed, float(p.stop_margin), float(p.a_max),
                float(np.sqrt(p.a_max * p.idm_b)), float(p.idm_T), 0.5)

    def _envelope_pairs(self, f, rs, cor, in_box: bool, cap, cap_other) -> int:
        """Lower ``cap`` and ``cap_other`` in place towards the leaders of the
        corridor index ``cor`` (:func:`icv_envs.policies._kernels.envelope_pairs`;
        the box included when ``in_box``); returns the number of signal-only
        leaders alongside that were passed."""
        return int(envelope_pairs(cor.lead, cor.coord, cor.rows, cor.signal_only,
                                  *self._envelope_pairs_args(f, rs, in_box), cap, cap_other))

    def _envelope_pairs_args(self, f, rs, in_box: bool) -> tuple:
        """:func:`~icv_envs.policies._kernels.envelope_pairs`' arguments
        between the corridor index and the caps (for :meth:`_envelope_pairs`
        and the one-call path)."""
        p = self.p
        b = abs(p.a_min)
        tau = p.cap_tau
        co = self._coordinated(f) | (rs.phase == 2)
        return (f.length, f.speed, np.asarray(self._group(f), dtype=np.int64), np.asarray(co, dtype=bool), rs.phase,
                float(p.member_T), float(p.idm_T), float(p.member_s0), float(p.idm_s0), float(p.a_max),
                float(p.idm_b), float(2.0 * np.sqrt(p.a_max * p.idm_b)), float(b), float(tau), float((b * tau) ** 2),
                bool(in_box))

    def _path_obstacles(self, world, rs, v_stopped: float = _V_STOPPED, look: float = 60.0):
        """Pairs ``(vehicle, obstacle, bumper gap, obstacle speed)``: a vehicle
        slower than ``v_stopped`` in the box (or within 10 m past it) whose
        body covers the path of a vehicle approaching (within 40 m of the
        stop line) or in the box, ahead of it by at most ``look`` metres.  The
        corridors only know leaders on one's own lane or path; a vehicle
        stopped across it (after a crash, or stopped by its own controller)
        must be seen too.  Lateral test: the obstacle's rectangle, turned by
        its heading relative to the path, overlaps the vehicle's width plus
        0.2 m; gap: along the path, bumper to the obstacle's nearest extent.

        A vehicle in the box held by such an obstacle will come to rest
        behind it, ``member_s0`` short of it on its own path; where that
        resting place covers another vehicle's path, it is an obstacle (speed
        0) for that vehicle already (a *ghost*; never for the obstacles that
        hold it).  Issue 11: with a vehicle held stopped in the box by a
        policy, fcfs vehicles with reservations drove into vehicles crawling
        across their path to their resting place behind it (3 pairs in 240
        s).  Without a stopped vehicle in the box there is no ghost."""
        f = world.fleet
        lay = world.layout
        e = np.zeros(0, dtype=np.int64)
        empty = (e, e, np.zeros(0), np.zeros(0))
        # (compiled: policies/_kernels.box_obstacle_rows, from stop 42; the array
        # expression it replaced is frozen in tests/test_box_steering.py)
        obs = box_obstacle_rows(rs.phase, rs.s, rs.L, f.speed, float(v_stopped))
        if not len(obs):
            return empty
        q = flatnonzero((((rs.phase == 0) & (rs.u > -40.0)) | (rs.phase == 1)) & ~f.crashed)
        if not len(q):
            return empty
        qi, oj, gap = self._covering(world, rs, q, obs, rs.cx[obs], rs.cy[obs], f.heading[obs],
                                     f.length[obs], f.width[obs], look)
        vo = f.speed[oj]
        # ghosts: the resting places of in-box vehicles held by those obstacles
        held = np.unique(qi[rs.phase[qi] == 1])
        if len(held):
            g_min = np.full(f.n, np.inf)
            np.minimum.at(g_min, qi, gap)
            s_rest = rs.s[held] + np.maximum(g_min[held] - self.p.member_s0, 0.0)
            gx, gy, gh = lay.route_points(rs.pid[held], s_rest)
            gi, gj, gg = self._covering(world, rs, q, held, gx, gy, gh, f.length[held], f.width[held], look)
            # never for the vehicle itself or for an obstacle that holds it
            holds = set(zip(qi.tolist(), oj.tolist()))
            keep = np.array([a != b and (b, a) not in holds for a, b in zip(gi.tolist(), gj.tolist())], dtype=bool)
            if keep.any():
                qi = np.concatenate([qi, gi[keep]])
                oj = np.concatenate([oj, gj[keep]])
                gap = np.concatenate([gap, gg[keep]])
                vo = np.concatenate([vo, np.zeros(int(keep.sum()))])
                self.stats["path_ghost_pairs"] = self.stats.get("path_ghost_pairs", 0) + int(keep.sum())
        return qi, oj, gap, vo

    def _covering(self, world, rs, q, obs, ox, oy, oh, olen, owid, look):
        """``(vehicle, obstacle, gap)`` for every vehicle of ``q`` whose path
        ahead (within ``look`` m) the rectangle of obstacle ``obs[k]``
        (centre ``ox, oy``, heading ``oh``, size ``olen x owid``) covers."""
        f = world.fleet
        lay = world.layout
        n_o = len(obs)
        qi = np.repeat(q, n_o)
        kk = np.tile(np.arange(n_o), len(q))
        oj = obs[kk]
        k = qi != oj
        qi, oj, kk = qi[k], oj[k], kk[k]
        pid = rs.pid[qi]
        s_o, lat_o = lay.project(pid, ox[kk], oy[kk], np.ones(len(qi), dtype=np.int64))
        past = s_o > lay.L[pid]
        if past.any():
            s2, l2 = lay.project(pid[past], ox[kk[past]], oy[kk[past]], np.full(int(past.sum()), 2))
            s_o[past], lat_o[past] = s2, l2
        _, _, hp = lay.route_points(pid, s_o)
        dh = oh[kk] - hp
        c, sn = np.abs(np.cos(dh)), np.abs(np.sin(dh))
        across = 0.5 * (olen[kk] * sn + owid[kk] * c)
        along = 0.5 * (olen[kk] * c + owid[kk] * sn)
        gap = s_o - along - rs.s[qi] - 0.5 * f.length[qi]
        hit = (np.abs(lat_o) < 0.5 * f.width[qi] + across + 0.2) & (s_o > rs.s[qi]) & (gap < look)
        return qi[hit], oj[hit], gap[hit]

    def _gipps(self, v, v_lead, room) -> np.ndarray:
        """Acceleration cap ``(v_safe - v) / tau`` with Gipps' safe speed
        ``v_safe = -b tau + sqrt((b tau)^2 + v_lead^2 + 2 b room)``, ``b =
        |a_min|``, ``tau = cap_tau`` (the policy period), ``room`` the bumper
        gap minus the standstill margin."""
        p = self.p
        b = abs(p.a_min)
        tau = p.cap_tau
        vs = -b * tau + np.sqrt((b * tau) ** 2 + v_lead ** 2 + 2.0 * b * np.maximum(room, 0.0))
        return (vs - v) / tau
