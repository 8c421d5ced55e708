"""The paper's highway reference methods as policies in the agents' action space.

* :class:`IdmMobilPolicy` (``idm``): no coordination. Car following by IDM
  (Treiber et al. 2000) at the lane's desired speed; discretionary lane
  changes by MOBIL (Kesting et al. 2007, symmetric rule, politeness
  ``politeness``, threshold ``mobil_threshold``, safety ``b_safe``);
  mandatory moves to the main road from an on-ramp and to the ramp before an
  exit.
* :class:`LaneLpPolicy` (``lane-lp``): the optimal lane assignment of Dao et
  al. (2007), reconstructed in :mod:`icv_envs.policies.lane_lp`: at every
  on-ramp the LP is solved (every ``lp_period`` seconds) over the vehicles on
  the 2000 m downstream, and each vehicle that merges there is given the lane
  whose LP share its exit group most lacks; it drives to that lane with the
  same gap acceptance and then keeps it (IDM car following) until its exit
  approaches. Vehicles never assigned by the LP fall back to MOBIL.

Both reuse the lateral machinery of :class:`FormationExpert` (one-lane-at-a-time
Bezier lane changes with gap acceptance, preview steering, IDM safety
envelope); only the choice of lane and the free-road speed differ.
"""

from __future__ import annotations

import numpy as np

from icv_envs.policies.formation_expert import ExpertParams, FormationExpert
from icv_envs.policies.lane_lp import optimal_lane_shares
from icv_envs.sim.traffic import followers, idm_acceleration, leaders

__all__ = ["IdmMobilPolicy", "LaneLpPolicy"]


class IdmMobilPolicy(FormationExpert):
    def __init__(self, params: ExpertParams | None = None, politeness: float = 0.3, mobil_threshold: float = 0.2):
        super().__init__(params)
        self.politeness = float(politeness)
        self.mobil_threshold = float(mobil_threshold)

    def _idm_in_lane(self, world, rows, lanes, cx, v, index, self_speed=None):
        """IDM acceleration of vehicles ``rows`` if they drove in ``lanes``
        (leader there, and the end of that lane as a standing obstacle)."""
        p = self.p
        tr, road = world.traffic, world.road
        lead, lx = leaders(index, rows, lanes, cx, return_x=True)
        has = lead >= 0
        gap = np.full(len(rows), np.inf)
        gap[has] = lx[has] - cx[rows[has]] - 0.5 * (tr.length[lead[has]] + tr.length[rows[has]])
        dv = np.where(has, v[rows] - v[np.maximum(lead, 0)], 0.0)
        end_gap = road.interval_end(lanes, cx[rows]) - cx[rows] - 0.5 * tr.length[rows]
        use = end_gap < gap
        gap = np.where(use, end_gap, gap)
        dv = np.where(use, v[rows], dv)
        v0 = self._lane_speeds(road, lanes)
        return idm_acceleration(v[rows], v0, gap, dv, p.a_max, p.idm_b, p.idm_T, p.idm_s0, free_term=True)

    def _follower_accel(self, world, foll, gap, v_lead, v, v0):
        p = self.p
        ok = foll >= 0
        out = np.zeros(len(foll))
        if ok.any():
            vf = v[foll[ok]]
            out[ok] = idm_acceleration(vf, v0[ok], gap[ok], vf - v_lead[ok], p.a_max, p.idm_b, p.idm_T, p.idm_s0)
        return out

    def _mobil(self, world, cand, lane, cx, v, index) -> np.ndarray:
        """MOBIL lane choice for rows ``cand`` (settled free vehicles on main
        lanes): returns the chosen lane (the current one if no change)."""
        tr, road = world.traffic, world.road
        best = lane[cand].copy()
        if not len(cand):
            return best
        a_cur = self._idm_in_lane(world, cand, lane[cand], cx, v, index)
        best_gain = np.full(len(cand), self.mobil_threshold)
        # old follower: gains when we leave
        of, ofx = followers(index, cand, lane[cand], cx, return_x=True)
        ld, ldx = leaders(index, cand, lane[cand], cx, return_x=True)
        L = tr.length
        v0_cur = self._lane_speeds(road, lane[cand])
        gap_of_now = np.where(of >= 0, cx[cand] - ofx - 0.5 * (L[cand] + L[np.maximum(of, 0)]), np.inf)
        gap_of_after = np.where(
            (of >= 0) & (ld >= 0), ldx - ofx - 0.5 * (L[np.maximum(ld, 0)] + L[np.maximum(of, 0)]), np.inf
        )
        v_ld = np.where(ld >= 0, v[np.maximum(ld, 0)], v[cand])
        a_of_now = self._follower_accel(world, of, gap_of_now, v[cand], v, v0_cur)
        a_of_after = self._follower_accel(world, of, gap_of_after, v_ld, v, v0_cur)
        for d in (-1, 1):
            tgt = lane[cand] + d
            ok = (tgt >= 0) & (tgt < road.n_lanes)
            tgt = np.clip(tgt, 0, road.n_lanes - 1)
            ok &= road.available(tgt, cx[cand])
            a_new = self._idm_in_lane(world, cand, tgt, cx, v, index)
            nf, nfx = followers(index, cand, tgt, cx, return_x=True)
            nl, nlx = leaders(index, cand, tgt, cx, return_x=True)
            v0_t = self._lane_speeds(road, tgt)
            gap_nf_after = np.where(nf >= 0, cx[cand] - nfx - 0.5 * (L[cand] + L[np.maximum(nf, 0)]), np.inf)
            gap_nf_now = np.where(
                (nf >= 0) & (nl >= 0), nlx - nfx - 0.5 * (L[np.maximum(nl, 0)] + L[np.maximum(nf, 0)]), np.inf
            )
            v_nl = np.where(nl >= 0, v[np.maximum(nl, 0)], v[cand])
            a_nf_after = self._follower_accel(world, nf, gap_nf_after, v[cand], v, v0_t)
            a_nf_now = self._follower_accel(world, nf, gap_nf_now, v_nl, v, v0_t)
            safe = a_nf_after > -self.p.b_safe
            gain = a_new - a_cur + self.politeness * ((a_nf_after - a_nf_now) + (a_of_after - a_of_now))
            take = ok & safe & (gain > best_gain)
            best = np.where(take, tgt, best)
            best_gain = np.where(take, gain, best_gain)
        return best

    def _desired_lanes(self, world, desired, lane, member, exiting, cx, v, index) -> np.ndarray:
        tr, road = world.traffic, world.road
        settled = (tr.lc_lane < 0) & (desired == lane) & ~member & ~exiting & (lane < road.n_lanes)
        cand = np.flatnonzero(settled)
        if len(cand):
            desired = desired.copy()
            desired[cand] = self._mobil(world, cand, lane, cx, v, index)
        return desired


class LaneLpPolicy(IdmMobilPolicy):
    def __init__(self, params: ExpertParams | None = None, lp_period: float = 10.0, segment: float = 2000.0,
                 lane_change_distance: float = 100.0, **kw):
        super().__init__(params, **kw)
        self.lp_period = float(lp_period)
        self.segment = float(segment)
        self.lane_change_distance = float(lane_change_distance)
        self.assigned: dict[int, int] = {}
        self._shares: dict[int, tuple[float, np.ndarray]] = {}
        self._given: dict[int, np.ndarray] = {}
        self.solves = 0

    def _shares_at(self, world, k: int, cx) -> np.ndarray:
        tr, road = world.traffic, world.road
        t = world.time
        cached = self._shares.get(k)
        if cached is not None and t - cached[0] < self.lp_period:
            return cached[1]
        ramp = road.on_ramps[k]
        rel = road.wrap(cx - ramp.end) if road.periodic else cx - ramp.end
        seg = (rel >= -(ramp.end - ramp.start) - ramp.approach) & (rel < self.segment) & (tr.exit >= 0)
        E = road.n_exits
        counts = np.bincount(tr.exit[seg], minlength=E).astype(np.float64)
        dist = road.exit_ahead(np.arange(E), np.full(E, ramp.end))
        p = self.p
        lanes = np.arange(road.n_lanes)
        speeds = self._lane_speeds(road, lanes)
        cap = self.segment / (p.idm_s0 + speeds * p.idm_T + 5.0)
        shares = optimal_lane_shares(counts, dist, speeds, cap, self.lane_change_distance)
        self._shares[k] = (t, shares)
        self._given.setdefault(k, np.zeros((E, road.n_lanes)))
        self.solves += 1
        return shares

    def _desired_lanes(self, world, desired, lane, member, exiting, cx, v, index) -> np.ndarray:
        tr, road = world.traffic, world.road
        desired = desired.copy()
        if road.on_ramps and road.n_exits:
            # vehicles merging now (on the ramp lane inside a merge segment) get their LP lane
            merging = np.flatnonzero((lane == road.ramp_lane) & road.in_merge(cx) & (tr.exit >= 0) & ~exiting)
            for r in merging:
                vid = int(tr.vid[r])
                if vid in self.assigned:
                    continue
                k = self._ramp_of(road, cx[r])
                shares = self._shares_at(world, k, cx)
                e = int(tr.exit[r])
                given = self._given[k]
                deficit = shares[e] * (given[e].sum() + 1.0) - given[e]
                deficit = np.where(shares[e] > 1e-9, deficit, -np.inf)
                lane_choice = int(np.argmax(deficit))
                given[e, lane_choice] += 1.0
                self.assigned[vid] = lane_choice
        fallback = super()._desired_lanes(world, desired, lane, member, exiting, cx, v, index)
        vids = tr.vid.tolist()
        for i, vid in enumerate(vids):
            if exiting[i] or member[i]:
                continue
            a = self.assigned.get(vid)
            if a is None:
                desired[i] = fallback[i]
            elif lane[i] != road.ramp_lane:
                desired[i] = a
        return desired

    @staticmethod
    def _ramp_of(road, x) -> int:
        best, k_best = np.inf, 0
        for k, r in enumerate(road.on_ramps):
            d = abs(float(road.wrap(x - 0.5 * (r.start + r.end))))
            if d < best:
                best, k_best = d, k
        return k_best
