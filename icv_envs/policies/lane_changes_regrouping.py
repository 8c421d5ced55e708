"""Vehicle regrouping's lane changes in the adjusting zone (paper Sec. 5,
the second of its four steps: division, lane change, formation adjusting,
merging): which lane changes start (the slot, the gaps in the target lane,
the courtesy signals), the yields to a vehicle beside the gap, and the
changes that end or re-plan.

A mixin of :class:`icv_envs.policies.regrouping.Regrouping` (split from it
at stop 47, when that module passed 500 lines); the behaviour is documented
in :mod:`icv_envs.policies.platoon_expert`'s docstring ("Adjusting zone").
"""

from __future__ import annotations

import numpy as np

from icv_envs.formation.bezier import _lane_change_lateral_rows
from icv_envs.policies._kernels import lane_change_gaps, lane_change_progress, lane_change_ready
from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_FREE, ST_LC, Corridors
from icv_envs._ufuncs import flatnonzero

__all__ = ["LaneChanges"]


class LaneChanges:
    """Lane changes of the regrouping (Sec. 5; module docstring)."""

    def _lane_change_progress(self, world, rs) -> None:
        f = world.fleet
        act = flatnonzero(f.lc_lane >= 0)
        if not len(act):
            return
        # (unchecked: lengths > 0 by PlatoonExpert._check_params, positions finite)
        # (the curve's arithmetic compiled around numpy's arcsinh and sinh: the same numbers as the array code)
        lat_plan, _ = _lane_change_lateral_rows(act, rs.u, f.lc_u0, f.lc_lat0, f.lc_lat1, f.lc_len)
        # finished (past the curve's end near the target lane's centre, or
        # in the box) or strayed from the plan: the change ends (compiled:
        # policies/_kernels.lane_change_progress, from stop 41; the array
        # code it replaced is frozen in tests/test_expert_kernels.py)
        lane_change_progress(act, lat_plan, rs.lat_leg, rs.u, rs.phase, rs.lane, f.lc_u0, f.lc_len, f.lc_lat1,
                             float(self.p.replan_tolerance), f.klane, f.lc_lane)

    def _start_lane_changes(self, world, rs) -> None:
        p = self.p
        f = world.fleet
        lay = world.layout
        if self._yield:
            # yields end when the change started or is no longer needed, in
            # R1, when either vehicle left, or when both (nearly) stand: the
            # slot then moves the yielding one forward to open the gap
            need = (f.klane != f.tlane) & (f.lc_lane < 0) & (rs.phase == 0) & (f.stage >= ST_LC)
            alive = set(f.vid[need & (rs.dist > lay.R1) & (f.speed >= 0.5)].tolist())
            moving = set(f.vid[f.speed >= 0.5].tolist())
            for vid in [v for v, b in self._yield.items() if v not in alive or b not in moving]:
                del self._yield[vid]
        # the vehicles that need a lane change; those in division start only
        # near their slot, one that is yielding (below) any distance behind
        # it; a ready one in the coordinating zone (or queued) is listed in
        # the lane it needs (a courtesy signal), so the vehicle behind there
        # makes room (compiled: policies/_kernels.lane_change_ready, from
        # stop 41; the array code it replaced is frozen in tests/test_expert_kernels.py)
        rows, nxt = lane_change_ready(f.klane, f.tlane, f.lc_lane, rs.phase, f.stage, ST_LC, f.vid,
                                      np.fromiter(self._yield, dtype=np.int64, count=len(self._yield)),
                                      f.rows(f.ref), rs.u, f.xg, rs.dist, f.speed, float(lay.R1),
                                      float(p.slot_tolerance), f.want)
        if not len(rows):
            return
        # the manoeuvre's length, the gaps and IDM's interaction term towards
        # the target lane's leader and follower, the refused changes beside a
        # vehicle there (the yields, below) and the changes that must not
        # start side by side, in one compiled call (policies/_kernels.lane_change_gaps,
        # from stop 42; the array code it replaced is frozen in tests/test_expert_kernels.py)
        cor = Corridors.with_signals(world, rs, self._signals(f, want=False))
        length, ok, yk, yo = lane_change_gaps(
            rows, nxt, f.leg, f.speed, rs.u, rs.dist, f.length, cor.keys, cor.corr, cor.rows, cor.coord,
            float(cor.BIG), float(p.lc_duration), float(p.lc_min_length), float(p.lc_max_length),
            float(p.lc_stop_room), float(p.lc_min_length * 0.75), float(p.lc_min_gap), float(p.b_safe),
            float(p.a_max), float(2.0 * np.sqrt(p.a_max * p.idm_b)), float(p.member_T), float(p.member_s0),
            float(lay.R1))
        if len(yk):
            self._note_yields(f.vid[rows[yk]].tolist(), f.vid[yo].tolist())
        start = rows[ok]
        if len(start):
            f.lc_lane[start] = nxt[ok]
            f.lc_u0[start] = rs.u[start]
            f.lc_lat0[start] = rs.lat_leg[start]
            f.lc_lat1[start] = (nxt[ok] + 0.5) * lay.lane_width
            f.lc_len[start] = length[ok]
            self.stats["lane_changes"] += len(start)

    def _note_yields(self, me_vids: list, other_vids: list) -> None:
        """Yield to a vehicle beside the gap (our rule; the paper is silent).

        A ready vehicle in the adjusting zone whose lane change is refused
        because a vehicle in the target lane is beside it (bumper gap to the
        target lane's follower or leader at most ``lc_min_gap``) would stay
        beside that vehicle for ever when both drive at the same speed: its
        slot holds it there and the other one is not asked to make room (a
        signal from a moving vehicle holds back only the vehicles behind it,
        :meth:`PlatoonExpert._envelope`). Seen at 2000 veh/h (multi-vp, seed
        2): side by side at 10 m/s from 500 m to ``R1``, then rerouted there
        and held as a late node. So the vehicle yields: until its change
        starts, its longitudinal reference is ``lc_min_gap + 1 m`` (bumper)
        behind that vehicle at that vehicle's speed (:meth:`_apply_yields`),
        it may start the change any distance behind its slot, and it sends
        no courtesy signal (which would hold the other one back: both would
        stop). It never yields to a vehicle that yields itself (two vehicles
        swapping lanes would both drop back to a standstill). Yields start
        only above 2 m/s (slower, the courtesy signal makes room) and end
        when both vehicles (nearly) stand; inside ``R1``
        :meth:`PlatoonExpert._reroute_stuck` decides.

        ``me_vids`` yield to ``other_vids`` (pairs in row order: the refused
        changes beside a vehicle of the target lane, outside ``R1`` and at 2
        m/s or more; :func:`~icv_envs.policies._kernels.lane_change_gaps`)."""
        for me, other in zip(me_vids, other_vids):
            if other in self._yield:
                # never yield to a vehicle that yields itself: two vehicles
                # swapping lanes would each drop back behind the other to a
                # standstill (the one that yielded first keeps yielding)
                continue
            if me not in self._yield:
                self.stats["lane_change_yields"] += 1
            self._yield[me] = other

    def _apply_yields(self, world, rs) -> None:
        """Longitudinal references of the yielding vehicles (:meth:`_note_yields`):
        ``lc_min_gap + 1 m`` (bumper) behind the vehicle they yield to, at its
        speed (the nearer of that and a formation reference they already follow)."""
        if not self._yield:
            return
        f = world.fleet
        me = f.rows(np.fromiter(self._yield, dtype=np.int64, count=len(self._yield)))
        bl = f.rows(np.fromiter(self._yield.values(), dtype=np.int64, count=len(self._yield)))
        ok = (me >= 0) & (bl >= 0)
        me, bl = me[ok], bl[ok]
        if not len(me):
            return
        free = self._mode[me] == MODE_FREE
        fol = (self._mode[me] == MODE_FOLLOW) | free
        me, bl, free = me[fol], bl[fol], free[fol]
        back = rs.u[bl] - 0.5 * (f.length[bl] + f.length[me]) - self.p.lc_min_gap - 1.0
        self._xref[me] = np.where(free, back, np.minimum(self._xref[me], back))
        self._vref[me] = np.where(free, f.speed[bl], np.minimum(self._vref[me], f.speed[bl]))
        self._mode[me] = MODE_FOLLOW
