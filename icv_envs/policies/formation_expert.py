"""The formation expert: the paper's vehicle controller as a policy.

Division of labour (a design decision): the paper's target generation
(Sec. 3.2) and Hungarian assignment (Sec. 3.3) run in the formation layer
(:class:`icv_envs.sim.formations.FormationManager`), which the environment
runs whatever policy drives, so that every agent's target is part of its
observation and of the formation-keeping reward; this expert turns those
targets into controls.

For every ICV it returns an action in the agents' action space
(``[acceleration, steering]`` scaled to ``[-1, 1]``, see
:func:`icv_envs.envs.actions.action_to_controls`):

* **Lateral** (paper Sec. 2.2 and 3.4): a vehicle whose target lane differs
  from its lane changes lanes one lane at a time along a cubic Bezier curve
  (:func:`icv_envs.formation.bezier.lane_change_lateral`), tracked with a
  preview (pure-pursuit) steering law; otherwise it keeps its lane centre.
* **Longitudinal** (paper Sec. 2.2, eq. (law)): members track their
  reference with ``a = a_ref + k_p (X - X_ref) + k_v (v - v_ref)``, where
  the formation layer's reference moves smoothly from where the member
  joined to its slot (:func:`icv_envs.formation.control.join_profile`) and
  ``a_ref`` is its acceleration fed forward; the gains follow from a damping
  ratio of 1 and the largest error the feedback handles alone
  (:mod:`icv_envs.formation.control`). Free ICVs (joining from a ramp before
  they are assigned, leaving for an exit) drive IDM at the lane's desired
  speed.
* **Safety layer** (the "lower-level controller" the paper delegates to,
  Sec. 3.4): the command is capped by IDM's interaction term towards the
  leader in every lane the vehicle occupies or is moving into, and towards the
  end of its lane (lane drop, obstacle, ramp end); a lane change starts only
  when the gaps in the target lane pass a MOBIL-style safety check (neither the
  new follower nor the vehicle itself would have to brake harder than
  ``b_safe``). The configured minimum speed is a control floor that yields to
  this layer.

The plan of an ongoing lane change is the expert's only memory; it lives in
the traffic arrays (``lc_*`` columns) and is dropped when the vehicle strays
more than ``replan_tolerance`` metres from it (e.g. a learned policy drives
the vehicle), so the expert can always be queried for any vehicle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from icv_envs.formation.bezier import _lane_change_lateral, _pure_pursuit_steering, lane_change_lateral
from icv_envs.formation.control import DEFAULT_KP, DEFAULT_KV, _longitudinal_feedback
from icv_envs.sim._ufuncs import clip as uclip
from icv_envs.policies._params import check_steering_and_gains, real_param
from icv_envs.policies._kernels import normalised_actions, safety_cap
from icv_envs.sim.traffic import LAT_ACCEL_MAX, followers, idm_acceleration, leaders


def _bezier_peak() -> float:
    """max |d^2 y / dx^2| * D^2 / W of the lane-change curve (about 5.52)."""
    x = np.linspace(0.0, 1.0, 20001)
    y, _ = lane_change_lateral(x, 0.0, 0.0, 1.0, 1.0)
    return float(np.abs(np.gradient(np.gradient(y, x), x)[50:-50]).max())


BEZIER_PEAK = _bezier_peak()

__all__ = ["ExpertParams", "FormationExpert"]


@dataclass
class ExpertParams:
    wheelbase: float = 2.8
    a_min: float = -6.0
    a_max: float = 3.0
    steer_max: float = np.deg2rad(30.0)
    v_min: float = 10.0
    v_max: float = 30.0
    desired_speed: float = 25.0  # free ICVs on main lanes [m/s]
    ramp_speed: float = 15.0  # free ICVs on the ramp lane [m/s]
    exit_speed: float = 20.0  # free ICVs heading for their exit (paper Table 1: fourth lane 20 m/s)
    blocked_slowdown: float = 3.0  # [m/s] a vehicle whose lane change is refused slows by this to find a gap
    kp: float = DEFAULT_KP  # -0.3 1/s^2 (zeta = 1, omega_n = 0.548 rad/s; icv_envs.formation.control)
    kv: float = DEFAULT_KV  # -1.095 1/s
    # formation keeping uses comfortable limits; the safety envelope may still
    # brake down to a_min
    comfort_accel: tuple = (-2.0, 1.5)
    # IDM safety envelope
    idm_T: float = 1.0  # time gap of the IDM safety envelope, free ICVs [s]
    member_time_gap: float = 0.5  # ... and inside a formation, where lane changes pass 15 m gaps [s]
    idm_s0: float = 2.0
    idm_b: float = 3.0
    b_safe: float = 4.0  # [m/s^2] hardest braking a lane change may impose
    lc_min_gap: float = 4.0  # [m] minimum bumper gaps to start a lane change
    lc_duration: float = 3.0  # [s] Bezier length = clip(v * lc_duration, ...)
    lc_min_length: float = 20.0
    lc_max_length: float = 90.0
    preview_time: float = 0.8  # [s] preview distance = max(preview_min, v * preview_time)
    preview_min: float = 8.0
    replan_tolerance: float = 1.0  # [m]
    exit_lookahead: float = 400.0
    exit_lookahead_per_lane: float = 0.0  # [m] added per further lane to cross (Road.exit_lookahead)
    # desired speed of free vehicles per lane index (main lanes, then the ramp
    # lane); None: ``desired_speed`` on main lanes, ``ramp_speed`` on the ramp
    lane_speeds: tuple | None = None
    lane_width: float = 4.0  # [m] lateral size of one lane change
    lat_accel_max: float = LAT_ACCEL_MAX  # [m/s^2] the vehicle model's bound (0.5 mu g)


class FormationExpert:
    """Vectorised expert over all vehicles of a :class:`~icv_envs.sim.world.World`.

    ``FormationExpert(params).compute(world)`` returns an ``(n, 2)`` float array
    of normalised actions, row ``i`` for traffic row ``i``.
    """

    def __init__(self, params: ExpertParams | None = None) -> None:
        self.p = params or ExpertParams()
        self._check_params()
        # shortest lane change at speed v: the Bezier's peak lateral
        # acceleration is BEZIER_PEAK * W v^2 / D^2, kept within the vehicle
        # model's bound (LAT_ACCEL_MAX): D >= v * sqrt(BEZIER_PEAK * W / a_y)
        self._lc_time_min = float(np.sqrt(BEZIER_PEAK * self.p.lane_width / self.p.lat_accel_max))
        # ... and its peak curvature BEZIER_PEAK * W / D^2 within the steering
        # limit tan(steer_max) / L: D >= sqrt(BEZIER_PEAK * W * L / tan(steer_max))
        self._lc_length_min = float(np.sqrt(BEZIER_PEAK * self.p.lane_width * self.p.wheelbase
                                            / np.tan(self.p.steer_max)))

    def _check_params(self) -> None:
        """The parameter checks the paper's functions make on every call,
        made once here: :meth:`compute` calls their unchecked forms."""
        p = self.p
        check_steering_and_gains(p, "ExpertParams")

        def real(name):
            return real_param("ExpertParams", name, getattr(p, name))

        lo, hi = max(real("a_min"), float(p.comfort_accel[0])), min(real("a_max"), float(p.comfort_accel[1]))
        if not lo < 0.0 < hi:
            raise ValueError(f"ExpertParams a_min / a_max / comfort_accel = {p.a_min!r} / {p.a_max!r} / "
                             f"{p.comfort_accel!r} give feedback limits [{lo}, {hi}]; allowed: lower < 0 < upper")

    # ------------------------------------------------------------------ hooks
    def _lane_speeds(self, road, lane) -> np.ndarray:
        """Desired speed of a free vehicle in ``lane`` (vectorised)."""
        p = self.p
        if p.lane_speeds is not None:
            table = np.asarray(p.lane_speeds, dtype=np.float64)
            return table[uclip(lane, 0, len(table) - 1)]
        return np.where((lane == road.n_lanes) & road.has_ramp_lane, p.ramp_speed, p.desired_speed)

    def _desired_lanes(self, world, desired, lane, member, exiting, cx, v, index) -> np.ndarray:
        """Hook for subclasses: the lane each vehicle wants. The formation
        expert keeps what the formation layer assigned (members), heads for
        the ramp (exiting) or the main road (on-ramp), and otherwise keeps its
        lane."""
        return desired

    # ----------------------------------------------------------------- helpers
    def _safety_cap(self, world, index, acc, lane, desired, member, exiting, bounds=None) -> np.ndarray:
        """The safety envelope on top of the longitudinal law, clipped to
        ``[a_min, a_max]``: the IDM interaction term (Treiber et al. 2000)
        behind the leader in every lane a vehicle occupies (the lane index's
        entries) or is entering (``lc_lane``), and behind the end of its own
        or target lane as a standing leader unless it is leaving that lane
        or taking its exit there; a vehicle with ``k`` lane changes still to
        make before its lane ends stops ``k * lc_min_length`` before the end
        (room for them from standstill). Compiled in one pass
        (:func:`icv_envs.policies._kernels.safety_cap`; the array code it
        replaced is its reference in ``tests/test_kernels.py``). ``bounds``:
        the clip range instead of ``(a_min, a_max)`` (the tests read the
        bare envelope with ``(-inf, inf)``)."""
        p = self.p
        a_min, a_max = (p.a_min, p.a_max) if bounds is None else bounds
        tr, road = world.traffic, world.road
        cx, _ = tr.center()
        return safety_cap(index.keys, index.rows, index.lanes, index.x, float(index.offset), cx, tr.speed,
                          np.asarray(tr.length, dtype=np.float64), tr.lc_lane, np.asarray(lane, dtype=np.int64),
                          np.asarray(desired, dtype=np.int64), np.asarray(member, dtype=bool),
                          np.asarray(exiting, dtype=bool), np.asarray(acc, dtype=np.float64),
                          float(road.length) if road.periodic else -1.0, int(road.n_lanes), road.lane_ends,
                          road._ob_lane, road._ob_lo, road._ob_hi, road._ramp_iv, float(p.lc_min_length),
                          float(p.member_time_gap), float(p.idm_T), float(p.a_max), float(p.idm_s0),
                          float(2.0 * np.sqrt(p.a_max * p.idm_b)), float(a_min), float(a_max))

    def _normalise(self, a: np.ndarray, phi: np.ndarray) -> np.ndarray:
        # compiled (policies/_kernels.py::normalised_actions: the arithmetic
        # of ``clip(stack([where(a >= 0, a / a_max, -a / a_min), phi /
        # steer_max], axis=1), -1, 1)``, element by element)
        p = self.p
        return normalised_actions(np.asarray(a, dtype=np.float64), np.asarray(phi, dtype=np.float64),
                                  float(p.a_max), float(p.a_min), float(p.steer_max))

    def compute(self, world) -> np.ndarray:
        p = self.p
        tr, road = world.traffic, world.road
        n = tr.n
        if n == 0:
            return np.zeros((0, 2))
        cx, cy = tr.center()
        v = tr.speed
        W = road.lane_width
        n_tot = road.total_lanes
        lane = road.lane_of(cy)
        index = world.lane_index()
        x_ref, lane_ref, v_ref, member = world.manager.references(tr)

        # ------------------------------------------------------ desired lane
        desired = np.where(member, lane_ref, lane)
        if road.has_ramp_lane:
            ramp = road.ramp_lane
            exiting = np.zeros(n, dtype=bool)
            has = (tr.exit >= 0) & ~member
            # a vehicle on its off-ramp lane is exiting, member or not (the
            # ramp leads nowhere else; it must not stop at the ramp's end)
            has_any = tr.exit >= 0
            if has_any.any() and road.n_exits:
                ha = np.flatnonzero(has_any)
                ds_a = road.diverge_start(tr.exit[ha])
                past_a = road.wrap(cx[ha] - ds_a)
                exiting[ha] = (lane[ha] == ramp) & (past_a >= 0) & (past_a <= road.exit_position(tr.exit[ha]) - ds_a)
            if has.any() and road.n_exits:
                dist = road.exit_ahead(tr.exit[has], cx[has])
                dlen = road.diverge_end(tr.exit[has]) - road.diverge_start(tr.exit[has])
                ds = road.diverge_start(tr.exit[has])
                past_ds = road.wrap(cx[has] - ds)
                on_its_off_ramp = (lane[has] == ramp) & (past_ds >= 0) & (past_ds <= road.exit_position(tr.exit[has]) - ds)
                la = road.exit_lookahead(lane[has], p.exit_lookahead, p.exit_lookahead_per_lane)
                exiting[has] |= ((dist < la) & (dist >= -dlen)) | on_its_off_ramp
            desired = np.where(exiting, ramp, desired)
            # free vehicles on the ramp lane of an on-ramp move onto the main road
            on_ramp = (lane == ramp) & ~exiting & ~member
            desired = np.where(on_ramp, road.n_lanes - 1, desired)
        else:
            exiting = np.zeros(n, dtype=bool)
        desired = self._desired_lanes(world, desired, lane, member, exiting, cx, v, index)
        # free vehicles whose lane ends ahead head for the nearest main lane
        # that continues at least 50 m further (possibly several lanes away),
        # starting (k + 1) * lc_max_length before the end for k lane changes
        free = ~member & ~exiting & (desired == lane) & (lane < road.n_lanes)
        if free.any():
            end = road.interval_end(lane, cx)
            f_rows = np.flatnonzero(free & np.isfinite(end))
            if len(f_rows):
                lanes_all = np.arange(road.n_lanes)
                ends = road.interval_end(lanes_all[None, :], cx[f_rows][:, None])
                dist = np.abs(lanes_all[None, :] - lane[f_rows][:, None]).astype(np.float64)
                dist = np.where(ends > end[f_rows][:, None] + 50.0, dist, np.inf)
                best = np.argmin(dist + 1e-3 * lanes_all[None, :], axis=1)  # ties: the left lane
                k = dist[np.arange(len(f_rows)), best]
                go = np.isfinite(k) & (end[f_rows] - cx[f_rows] < (k + 1.0) * p.lc_max_length)
                desired[f_rows[go]] = best[go]

        # --------------------------------------------- lane-change plan state
        active = tr.lc_lane >= 0
        if active.any():
            a_rows = np.flatnonzero(active)
            # (the unchecked forms of the paper's functions: every argument
            # here is a finite float64 state array, every length > 0)
            y_plan, _ = _lane_change_lateral(
                tr.x[a_rows], tr.lc_x0[a_rows], tr.lc_y0[a_rows], tr.lc_y1[a_rows], tr.lc_len[a_rows]
            )
            stray = np.abs(y_plan - tr.y[a_rows]) > p.replan_tolerance
            # a lane change ends once past the curve AND settled on the new
            # lane centre (until then the vehicle keeps steering for it)
            # (or stopped there: a vehicle held by a lane end before the end of
            # its curve is on the new lane and may plan its next change)
            done = (tr.x[a_rows] >= tr.lc_x0[a_rows] + tr.lc_len[a_rows]) & (
                np.abs(tr.y[a_rows] - tr.lc_y1[a_rows]) < 0.3)
            done |= (v[a_rows] < 0.5) & (np.abs(cy[a_rows] - tr.lc_y1[a_rows]) < 0.3)
            tr.lc_lane[a_rows[stray | done]] = -1
            active = tr.lc_lane >= 0

        # ------------------------------------------------ start lane changes
        settled = ~active & (np.abs(cy - lane * W) < 0.6)
        blocked = np.zeros(n, dtype=bool)
        want = settled & (desired >= 0) & (desired != lane)
        if want.any():
            w_rows = np.flatnonzero(want)
            nxt = lane[w_rows] + np.sign(desired[w_rows] - lane[w_rows])
            vw = v[w_rows]
            length = uclip(vw * p.lc_duration, p.lc_min_length, p.lc_max_length)
            xw = cx[w_rows]
            ok = (nxt >= 0) & (nxt < n_tot)
            nxt = uclip(nxt, 0, n_tot - 1)
            # the target lane must exist now; the body centre crosses the lane
            # line half way along the curve, which must come before the own
            # lane ends (half a body length to spare); and the manoeuvre plus
            # the k_after lane changes still needed after it (each
            # ``lc_min_length`` from standstill) must fit before the target
            # lane ends (lanes that end together: a lane drop to fewer lanes
            # than the vehicle must cross), s0 / 2 to spare. The lane-end
            # envelope below stops such a vehicle s0 before the line
            # ``end - k * lc_min_length``, which always leaves this room.
            ok &= road.available(nxt, xw)
            end_own = road.interval_end(lane[w_rows], xw)
            end_nxt = road.interval_end(nxt, xw)
            k_after = np.abs(desired[w_rows] - nxt)
            room_own = 2.0 * (end_own - xw - 0.5 * tr.length[w_rows])
            room_nxt = end_nxt - xw - 0.5 * p.idm_s0 - k_after * p.lc_min_length
            length = np.minimum(length, np.minimum(room_own, room_nxt))
            # shortened curves must stay within the vehicle's lateral-acceleration
            # bound and, at low speed, its steering limit (lc_min_length is
            # the planning unit of the lane-end stop lines, the physical
            # minimum is shorter: slack for a vehicle that stopped late)
            ok &= length >= np.maximum(self._lc_length_min, vw * self._lc_time_min)
            if road.has_ramp_lane:
                into_ramp = nxt == road.ramp_lane
                from_ramp = lane[w_rows] == road.ramp_lane
                ok &= ~into_ramp | road.in_diverge(xw)
                ok &= ~from_ramp | road.in_merge(xw)
                # a merge must end before the ramp lane does
            # gap acceptance in the target lane
            lead, lx = leaders(index, w_rows, nxt, cx, return_x=True)
            foll, fx = followers(index, w_rows, nxt, cx, return_x=True)
            lw = tr.length[w_rows]
            gap_f = np.where(lead >= 0, lx - xw - 0.5 * (tr.length[lead] + lw), np.inf)
            gap_r = np.where(foll >= 0, xw - fx - 0.5 * (tr.length[foll] + lw), np.inf)
            vl = np.where(lead >= 0, v[lead], vw)
            vf = np.where(foll >= 0, v[foll], 0.0)
            Tw = np.where(member[w_rows], p.member_time_gap, p.idm_T)
            Tf = np.where(member[np.maximum(foll, 0)] & (foll >= 0), p.member_time_gap, p.idm_T)
            own = idm_acceleration(vw, p.v_max, gap_f, vw - vl, p.a_max, p.idm_b, Tw, p.idm_s0, free_term=False)
            fol = idm_acceleration(vf, p.v_max, gap_r, vf - vw, p.a_max, p.idm_b, Tf, p.idm_s0, free_term=False)
            possible = ok.copy()  # the manoeuvre is allowed here; only the gaps may refuse it
            # a standing follower cannot close the gap while the manoeuvre
            # starts (its own envelope holds it): half the jam distance s0
            # suffices behind it (two vehicles queued at a lane end must be
            # able to file into the continuing lane one after the other)
            min_r = np.where(vf < 0.5, 0.5 * p.idm_s0, p.lc_min_gap)
            ok &= (gap_f > p.lc_min_gap) & (gap_r > min_r) & (own > -p.b_safe) & (fol > -p.b_safe)
            # the body stays in the old lane for the first half of the curve:
            # at constant speeds the old lane's leader must still be s0 ahead
            # when the vehicle has covered it (a vehicle cannot move sideways
            # without moving forward, so a lane change started behind a
            # standing leader would stop half way, blocking both lanes)
            lo, lox = leaders(index, w_rows, lane[w_rows], cx, return_x=True)
            t_half = 0.5 * length / np.maximum(vw, 1.0)
            gap_o = np.where(lo >= 0, lox - xw - 0.5 * (tr.length[lo] + lw), np.inf)
            gap_o = gap_o + np.where(lo >= 0, v[lo], 0.0) * t_half - np.maximum(vw, 1.0) * t_half
            ok &= gap_o >= p.idm_s0
            # two vehicles must not start into the same lane in one step
            # unless the rear one could accept the front one as its leader
            # there (neither sees the other yet): keep the front one. The
            # rear one needs the gap acceptance above towards the front one
            # (before: distance only; idm on the ring, VGR 1/3, seed 0,
            # t = 659 s: one from lane 1 at 25 m/s and one from lane 3 at
            # 7.9 m/s, 27 m ahead, both into lane 2: collision)
            cand = np.flatnonzero(ok)
            if len(cand) > 1:
                o = cand[np.lexsort((-xw[cand], nxt[cand]))]
                dx = road.wrap(xw[o][:-1] - xw[o][1:])  # front minus rear, >= 0
                gap_p = dx - 0.5 * (lw[o][:-1] + lw[o][1:])
                v_rear = vw[o][1:]
                T_rear = np.where(member[w_rows[o][1:]], p.member_time_gap, p.idm_T)
                acc_rear = idm_acceleration(v_rear, p.v_max, np.maximum(gap_p, 1e-3), v_rear - vw[o][:-1], p.a_max,
                                            p.idm_b, T_rear, p.idm_s0, free_term=False)
                near = dx < lw[o][1:] + p.lc_min_gap + 2.0 * p.idm_s0 + v_rear * p.member_time_gap
                same = (nxt[o][1:] == nxt[o][:-1]) & (near | (gap_p <= p.lc_min_gap) | (acc_rear <= -p.b_safe))
                drop = np.zeros(len(o), dtype=bool)
                for k in np.flatnonzero(same):
                    if not drop[k]:
                        drop[k + 1] = True
                # a dropped vehicle between two others no longer separates them:
                # check each kept one against the previous kept one in its lane
                # (idm ring, t = 2299 s: the one in between was dropped and the
                # rear one, 17.7 m behind the front one at 25 vs 10.4 m/s, went)
                if drop.any():
                    last = {}
                    for i in range(len(o)):
                        if drop[i]:
                            continue
                        j = last.get(int(nxt[o[i]]))
                        if j is not None:
                            d = road.wrap(xw[o[j]] - xw[o[i]])
                            g = d - 0.5 * (lw[o[j]] + lw[o[i]])
                            Ti = p.member_time_gap if member[w_rows[o[i]]] else p.idm_T
                            a_i = idm_acceleration(vw[o[i]], p.v_max, max(g, 1e-3), vw[o[i]] - vw[o[j]], p.a_max,
                                                   p.idm_b, Ti, p.idm_s0, free_term=False)
                            if (d < lw[o[i]] + p.lc_min_gap + 2.0 * p.idm_s0 + vw[o[i]] * p.member_time_gap
                                    or g <= p.lc_min_gap or a_i <= -p.b_safe):
                                drop[i] = True
                                continue
                        last[int(nxt[o[i]])] = i
                ok[o[drop]] = False
            start = w_rows[ok]
            blocked = np.zeros(n, dtype=bool)
            blocked[w_rows[possible & ~ok]] = True
            if len(start):
                tr.lc_lane[start] = nxt[ok]
                tr.lc_x0[start] = tr.x[start]
                tr.lc_y0[start] = tr.y[start]
                tr.lc_y1[start] = nxt[ok] * W
                tr.lc_len[start] = length[ok]
                active = tr.lc_lane >= 0

        # ---------------------------------------------------------- steering
        ld = np.maximum(p.preview_min, v * p.preview_time)
        px = tr.x + ld
        py = lane * W
        if active.any():
            a_rows = np.flatnonzero(active)
            yp, _ = _lane_change_lateral(
                px[a_rows], tr.lc_x0[a_rows], tr.lc_y0[a_rows], tr.lc_y1[a_rows], tr.lc_len[a_rows]
            )
            py = py.astype(np.float64)
            py[a_rows] = yp
        phi = _pure_pursuit_steering(tr.x, tr.y, tr.heading, px, np.asarray(py, dtype=np.float64),
                                     float(p.wheelbase), float(p.steer_max))

        # ------------------------------------------------------ longitudinal
        lane_speed = self._lane_speeds(road, lane)
        lane_speed = np.where(exiting & (lane < road.n_lanes), p.exit_speed, lane_speed)
        lane_speed = np.where(blocked & ~member, np.maximum(lane_speed - p.blocked_slowdown, p.v_min), lane_speed)
        # a vehicle refused on its way to its exit drops to the minimum speed:
        # alongside traffic at the lane speed then passes it within seconds and
        # opens the gap (at lane speed - blocked_slowdown the vehicles heading
        # for the same exit stay side by side for hundreds of metres and one
        # misses the exit)
        lane_speed = np.where(blocked & ~member & exiting, np.minimum(lane_speed, p.v_min), lane_speed)
        acc = np.empty(n)
        free = ~member
        if free.any():
            acc[free] = idm_acceleration(
                v[free], lane_speed[free], np.inf, 0.0, p.a_max, p.idm_b, p.idm_T, p.idm_s0, free_term=True
            )
        if member.any():
            m = np.flatnonzero(member)
            # the reference starts where the member joined and moves to its
            # slot smoothly (the formation layer re-plans it when the member
            # falls more than 5 m off), so the error seen here stays small
            a_ref = world.manager.reference_accel(tr)[m]
            x_eff = cx[m] + road.wrap(x_ref[m] - cx[m])
            acc[m] = _longitudinal_feedback(cx[m], x_eff, v[m], v_ref[m], float(p.kp), float(p.kv),
                                            float(max(p.a_min, p.comfort_accel[0])),
                                            float(min(p.a_max, p.comfort_accel[1])), a_ref)
            # control floor: do not command speeds below the configured minimum
            # (braking is faded out as v approaches v_min; the safety cap below still wins)
            acc[m] = np.maximum(acc[m], 1.0 * (p.v_min - v[m]))
        # safety envelope: leaders in the lanes the vehicle occupies or enters
        acc = self._safety_cap(world, index, acc, lane, desired, member, exiting)
        return self._normalise(acc, phi)
