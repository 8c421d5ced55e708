"""The low-level layer under :class:`~icv_envs.envs.actions.DiscreteMetaAction`.

An agent's meta action changes its target lane (by one) or its target speed
index (by one); this layer turns the targets into ``[u_a, u_s]`` every policy
step, with the paper's own controllers:

* **lateral** (paper Sec. 2.2 and 3.4): a lane change follows the cubic
  Bezier curve of :func:`icv_envs.formation.bezier.lane_change_lateral` over
  ``clip(v * lc_duration, lc_min_length, lc_max_length)`` metres (the
  expert's parameters: :class:`~icv_envs.policies.formation_expert.ExpertParams`
  on the highway, :class:`~icv_envs.policies.platoon_expert.PlatoonParams` at
  the intersection); steering is the preview (pure-pursuit) law
  :func:`icv_envs.formation.bezier.pure_pursuit_steering` on a point
  ``max(preview_min, v * preview_time)`` ahead: on the lane-change curve, on
  the target lane's centre, and at the intersection along the vehicle's path
  through the box and its departure lane;
* **longitudinal** (paper Sec. 2.2, eq. (law)): ``a = k_p (X - X_ref) + k_v
  (v - v_ref)`` with no position reference (``X = X_ref``), i.e.
  ``a = k_v (v - v_target)``, ``k_v = -1.1 /s`` (time constant 0.9 s), clipped
  to the vehicle's acceleration range.

A lane-change request against the direction of an ongoing lane change
aborts it, as in highway-env (whose ``LANE_LEFT`` during a change to the
right moves the target lane index back): a new curve from the vehicle's
current position back to the lane it came from, if that lane is still
available over the curve; a request in the same direction during a change
is ignored.  Without it two agents that started changing into one lane
from both sides at the same step could not undo it (the learned lane-drop
policies' collisions, issue 9).

State per vehicle (target lane, speed index, lane-change plan) is keyed by
vehicle id, created the first time a vehicle is driven by meta actions (its
lane and the target speed nearest its speed) and dropped when it leaves.
"""

from __future__ import annotations

import numpy as np

from icv_envs.formation.bezier import _pure_pursuit_steering, lane_change_lateral
from icv_envs.formation.control import DEFAULT_KP, DEFAULT_KV, _longitudinal_feedback

__all__ = ["MetaController"]

# the feedback law's gains and feed-forward as longitudinal_feedback converts them (0-d float64 arrays)
_KP, _KV, _A_REF = (np.asarray(g, dtype=np.float64) for g in (DEFAULT_KP, DEFAULT_KV, 0.0))


def _steering(rx, ry, heading, tx, ty, p) -> np.ndarray:
    """:func:`~icv_envs.formation.bezier.pure_pursuit_steering` of the
    simulator's own arrays (one finite float64 per vehicle, as the experts
    pass theirs), without its input checks: the same arithmetic, the same
    numbers (from stop 45: the checks were a fifth of this layer's time)."""
    f8 = np.float64
    return _pure_pursuit_steering(np.asarray(rx, dtype=f8), np.asarray(ry, dtype=f8), np.asarray(heading, dtype=f8),
                                  np.asarray(tx, dtype=f8), np.asarray(ty, dtype=f8), float(p.wheelbase),
                                  float(p.steer_max))


def _members(a: np.ndarray, sorted_b: np.ndarray) -> np.ndarray:
    """``np.isin(a, sorted_b)`` for a sorted array of distinct ids ``sorted_b``
    (a binary search instead of isin's sort of both)."""
    if not len(sorted_b):
        return np.zeros(len(a), dtype=bool)
    pos = np.minimum(np.searchsorted(sorted_b, a), len(sorted_b) - 1)
    return sorted_b[pos] == a


class MetaController:
    def __init__(self, env, target_speeds: np.ndarray) -> None:
        self.env = env
        self.target_speeds = np.asarray(target_speeds, dtype=np.float64)
        self.reset()

    def reset(self) -> None:
        self.vid = np.zeros(0, dtype=np.int64)
        self.lane = np.zeros(0, dtype=np.int64)
        self.sidx = np.zeros(0, dtype=np.int64)
        self.active = np.zeros(0, dtype=bool)
        self.x0 = np.zeros(0)
        self.y0 = np.zeros(0)
        self.y1 = np.zeros(0)
        self.length = np.zeros(0)
        self._world = None
        self.aborted = 0  # lane changes aborted by an opposite request

    # ----------------------------------------------------------------- state
    def _state(self, vids: np.ndarray, lane0: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Indices of ``vids`` in the state arrays, creating missing entries."""
        w = self.env.world
        if self._world is not w:
            self.reset()
            self._world = w
        # (the ids kept and the world's are sorted and distinct: membership by binary search, from stop 45)
        alive = _members(self.vid, self.env._vehicles().vid)
        if not alive.all():
            for k in ("vid", "lane", "sidx", "active", "x0", "y0", "y1", "length"):
                setattr(self, k, getattr(self, k)[alive])
        new = ~_members(vids, self.vid)
        if new.any():
            ts = self.target_speeds
            sidx = np.abs(speed[new][:, None] - ts[None, :]).argmin(axis=1)
            order = np.argsort(np.concatenate([self.vid, vids[new]]), kind="stable")
            m = int(new.sum())
            self.vid = np.concatenate([self.vid, vids[new]])[order]
            self.lane = np.concatenate([self.lane, lane0[new]])[order]
            self.sidx = np.concatenate([self.sidx, sidx])[order]
            self.active = np.concatenate([self.active, np.zeros(m, dtype=bool)])[order]
            for k in ("x0", "y0", "y1", "length"):
                setattr(self, k, np.concatenate([getattr(self, k), np.zeros(m)])[order])
        return np.searchsorted(self.vid, vids)

    def controls(self, rows: np.ndarray, dlane: np.ndarray, dspeed: np.ndarray) -> np.ndarray:
        """Normalised ``[u_a, u_s]`` for traffic ``rows`` after applying the
        lane steps ``dlane`` (-1 left, +1 right) and speed-index steps ``dspeed``."""
        if hasattr(self.env.world, "layout"):
            a, phi, p = self._intersection(rows, dlane, dspeed)
        else:
            a, phi, p = self._highway(rows, dlane, dspeed)
        ua = np.where(a >= 0, a / p.a_max, -a / p.a_min)
        return np.clip(np.stack([ua, phi / p.steer_max], axis=1), -1.0, 1.0)

    def _speed(self, k, dspeed, v, p) -> np.ndarray:
        self.sidx[k] = np.clip(self.sidx[k] + dspeed, 0, len(self.target_speeds) - 1)
        vt = self.target_speeds[self.sidx[k]]
        # (longitudinal_feedback's arithmetic on its converted arguments, without its checks: from stop 45)
        return _longitudinal_feedback(np.zeros_like(v), np.zeros_like(v), np.asarray(v, dtype=np.float64),
                                      np.asarray(vt, dtype=np.float64), _KP, _KV, float(p.a_min), float(p.a_max),
                                      _A_REF)

    # --------------------------------------------------------------- highway
    def _highway(self, rows, dlane, dspeed):
        env = self.env
        p = env._expert_params()
        w = env.world
        tr, road = w.traffic, w.road
        W = road.lane_width
        cx, cy = tr.center()
        cx, cy = cx[rows], cy[rows]
        v = tr.speed[rows]
        x, y = tr.x[rows], tr.y[rows]
        k = self._state(tr.vid[rows].astype(np.int64), road.lane_of(cy), v)
        # progress of ongoing lane changes (x measured along the ring from the start)
        act = self.active[k]
        if act.any():
            xa = self.x0[k] + road.wrap(x - self.x0[k])
            done = act & (xa >= self.x0[k] + self.length[k]) & (np.abs(y - self.y1[k]) < 0.3)
            self.active[k[done]] = False
        # a request against an ongoing lane change aborts it (highway-env: the
        # target lane index moves back): a new curve from where the vehicle is
        # back to the lane it came from, if that lane is still there
        ab = (dlane != 0) & self.active[k] & (dlane == -np.sign(self.y1[k] - self.y0[k]))
        if ab.any():
            r = np.flatnonzero(ab)
            back = self.lane[k[r]] + dlane[r]
            length = np.clip(v[r] * p.lc_duration, p.lc_min_length, p.lc_max_length)
            ok = road.available(back, cx[r]) & road.available(back, cx[r] + length)
            s = r[ok]
            ks = k[s]
            self.lane[ks] = back[ok]
            self.x0[ks] = x[s]
            self.y0[ks] = y[s]
            self.y1[ks] = back[ok] * W
            self.length[ks] = length[ok]
            self.aborted += len(s)
        # new lane-change requests
        req = (dlane != 0) & ~self.active[k]
        if req.any():
            r = np.flatnonzero(req)
            cur = self.lane[k[r]]
            nxt = cur + dlane[r]
            length = np.clip(v[r] * p.lc_duration, p.lc_min_length, p.lc_max_length)
            ok = (nxt >= 0) & (nxt < road.total_lanes)
            nxt_c = np.clip(nxt, 0, road.total_lanes - 1)
            ok &= road.available(nxt_c, cx[r]) & road.available(nxt_c, cx[r] + length)
            if road.has_ramp_lane:
                into_ramp, from_ramp = nxt_c == road.ramp_lane, cur == road.ramp_lane
                ok &= ~into_ramp | road.in_diverge(cx[r])
                ok &= ~from_ramp | road.in_merge(cx[r])
                room = road.interval_end(cur, cx[r]) - cx[r] - 5.0
                length = np.where(from_ramp, np.minimum(length, room), length)
                ok &= ~from_ramp | (room >= p.lc_min_length)
            s = r[ok]
            ks = k[s]
            self.lane[ks] = nxt[ok]
            self.active[ks] = True
            self.x0[ks] = x[s]
            self.y0[ks] = y[s]
            self.y1[ks] = nxt[ok] * W
            self.length[ks] = length[ok]
        # preview steering on the curve or the target lane centre
        ld = np.maximum(p.preview_min, v * p.preview_time)
        py = self.lane[k] * W + 0.0
        act = self.active[k]
        if act.any():
            xa = self.x0[k[act]] + road.wrap(x[act] + ld[act] - self.x0[k[act]])
            py[act], _ = lane_change_lateral(xa, self.x0[k[act]], self.y0[k[act]], self.y1[k[act]],
                                             self.length[k[act]])
        phi = _steering(x, y, tr.heading[rows], x + ld, py, p)
        return self._speed(k, dspeed, v, p), phi, p

    # ---------------------------------------------------------- intersection
    def _intersection(self, rows, dlane, dspeed):
        env = self.env
        p = env._params()
        w = env.world
        f, lay = w.fleet, w.layout
        rs = w.route()
        v = f.speed[rows]
        phase = rs.phase[rows]
        lane0 = np.where(phase == 0, rs.lane[rows], np.clip(f.plane[rows], 0, 2))
        k = self._state(f.vid[rows].astype(np.int64), lane0, v)
        u, lat = rs.u[rows], rs.lat_leg[rows]
        act = self.active[k]
        if act.any():
            done = act & (((u >= self.x0[k] + self.length[k]) & (np.abs(lat - self.y1[k]) < 0.4)) | (phase > 0))
            self.active[k[done]] = False
        # a request against an ongoing lane change aborts it (as on the highway)
        ab = (dlane != 0) & self.active[k] & (phase == 0) & (dlane == -np.sign(self.y1[k] - self.y0[k]))
        if ab.any():
            r = np.flatnonzero(ab)
            back = self.lane[k[r]] + dlane[r]
            length = np.minimum(np.clip(v[r] * p.lc_duration, p.lc_min_length, p.lc_max_length),
                                -u[r] - p.lc_stop_room)
            ok = length >= 0.75 * p.lc_min_length
            s = r[ok]
            ks = k[s]
            self.lane[ks] = back[ok]
            self.x0[ks] = u[s]
            self.y0[ks] = lat[s]
            self.y1[ks] = (back[ok] + 0.5) * lay.lane_width
            self.length[ks] = length[ok]
            self.aborted += len(s)
        req = (dlane != 0) & ~self.active[k] & (phase == 0)
        if req.any():
            r = np.flatnonzero(req)
            nxt = self.lane[k[r]] + dlane[r]
            length = np.minimum(np.clip(v[r] * p.lc_duration, p.lc_min_length, p.lc_max_length),
                                -u[r] - p.lc_stop_room)
            ok = (nxt >= 0) & (nxt <= 2) & (length >= 0.75 * p.lc_min_length)
            s = r[ok]
            ks = k[s]
            self.lane[ks] = nxt[ok]
            self.active[ks] = True
            self.x0[ks] = u[s]
            self.y0[ks] = lat[s]
            self.y1[ks] = (nxt[ok] + 0.5) * lay.lane_width
            self.length[ks] = length[ok]
        # preview point: along the approach lane (or its lane-change curve),
        # then the path through the box (the approach lane's path until the
        # vehicle enters; the world fixes it at entry) and the departure lane
        ld = np.maximum(p.preview_min, v * p.preview_time)
        appr = phase == 0
        klane = np.clip(self.lane[k], 0, 2)
        pid = np.where(appr, 3 * f.mv[rows] + klane, rs.pid[rows])
        s_prev = rs.s[rows] + ld
        px, py, _ = lay.route_points(pid, s_prev)
        pre = appr & (s_prev < 0)
        if pre.any():
            j = np.flatnonzero(pre)
            latp = (klane[j] + 0.5) * lay.lane_width
            a = self.active[k[j]]
            if a.any():
                ja, ka = j[a], k[j[a]]
                latp = latp.astype(np.float64)
                latp[a], _ = lane_change_lateral(u[ja] + ld[ja], self.x0[ka], self.y0[ka], self.y1[ka], self.length[ka])
            leg = f.leg[rows[j]]
            o = lay.box_half * lay.out[leg]
            d, rr = lay.app_dir[leg], lay.app_right[leg]
            up = u[j] + ld[j]
            px[j] = o[:, 0] + up * d[:, 0] + latp * rr[:, 0]
            py[j] = o[:, 1] + up * d[:, 1] + latp * rr[:, 1]
        phi = _steering(f.x[rows], f.y[rows], f.heading[rows], px, py, p)
        return self._speed(k, dspeed, v, p), phi, p
