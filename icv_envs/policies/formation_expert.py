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

from icv_envs.formation.bezier import _lane_change_lateral_rows, _pure_pursuit_rows, lane_change_lateral
from icv_envs.formation.control import DEFAULT_KP, DEFAULT_KV
from icv_envs._hooks import hook_table, own_hooks
from icv_envs._ufuncs import flatnonzero
from icv_envs.policies._params import check_steering_and_gains, real_param
from icv_envs.policies._kernels import (
    desired_lane_rows,
    exit_lanes,
    expert_accelerations,
    expert_control_rows,
    expert_lane_speeds,
    free_speed_pow,
    free_speed_pow_rows,
    lane_change_starts,
    lane_changes_ended,
    lane_end_escape,
    lane_speed_rows,
    normalised_actions,
    preview_points,
    safety_cap,
)
from icv_envs.sim.traffic import LAT_ACCEL_MAX


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
        # the IDM's 2 sqrt(a_max b) (the parameters are fixed once checked, as above)
        self._idm_root = float(2.0 * np.sqrt(self.p.a_max * self.p.idm_b))
        # normalised_actions' scales (a_max, a_min, steer_max)
        self._normalise_scales = (float(self.p.a_max), float(self.p.a_min), float(self.p.steer_max))
        self._consts = None  # (road, the kernels' arguments that depend on it and the parameters only)

    def _road_consts(self, road) -> dict:
        """The kernels' arguments that depend only on the road and the
        parameters (fixed once checked, as the values above), made once per
        road (a reset builds a new one), for the argument builders below."""
        c = self._consts
        if c is not None and c[0] is road:
            return c[1]
        p = self.p
        period = float(road.length) if road.periodic else -1.0
        n_lanes = int(road.n_lanes)
        ends = (road.lane_ends, road._ob_lane, road._ob_lo, road._ob_hi, road._ramp_iv)
        d = {
            "exit": (bool(road.has_ramp_lane), int(road.n_exits), n_lanes, road._diverge_iv, road._exit_x, period,
                     float(p.exit_lookahead), float(p.exit_lookahead_per_lane)),
            "escape": (period, n_lanes, *ends, float(p.lc_max_length)),
            "speed_table": (p.lane_speeds is not None,
                            np.asarray(p.lane_speeds if p.lane_speeds is not None else (), dtype=np.float64)),
            "speed_rule": (n_lanes, bool(road.has_ramp_lane), float(p.ramp_speed), float(p.desired_speed)),
            "targets": (n_lanes, float(p.exit_speed), float(p.blocked_slowdown), float(p.v_min)),
            "idm": (float(p.a_max), float(p.idm_b), float(p.idm_T), float(p.idm_s0)),
            "feedback": (period, float(p.kp), float(p.kv), float(max(p.a_min, p.comfort_accel[0])),
                         float(min(p.a_max, p.comfort_accel[1])), float(p.v_min)),
            "starts": (period, n_lanes, int(road.total_lanes), *ends, road._merge_iv, road._diverge_iv,
                       bool(road.has_ramp_lane), float(road.lane_width), float(p.lc_duration), float(p.lc_min_length),
                       float(p.lc_max_length), float(self._lc_length_min), float(self._lc_time_min), float(p.idm_s0),
                       float(p.member_time_gap), float(p.idm_T), float(p.a_max), self._idm_root, float(p.b_safe),
                       float(p.lc_min_gap)),
            "safety": (period, n_lanes, *ends, float(p.lc_min_length), float(p.member_time_gap), float(p.idm_T),
                       float(p.a_max), float(p.idm_s0), self._idm_root, float(p.a_min), float(p.a_max)),
        }
        self._consts = (road, d)
        return d

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
        """Desired speed of a free vehicle in ``lane`` (vectorised): the
        ``lane_speeds`` table at the lane (clipped to the table), else
        ``ramp_speed`` in a ramp lane and ``desired_speed`` elsewhere
        (:func:`icv_envs.policies._kernels.lane_speed_rows`)."""
        return lane_speed_rows(*self._lane_speed_args(road, lane))

    def _lane_speed_args(self, road, lane) -> tuple:
        """:func:`~icv_envs.policies._kernels.lane_speed_rows`' arguments (for
        :meth:`_lane_speeds` and the one-call tail of :meth:`compute`)."""
        c = self._road_consts(road)
        return (*c["speed_table"], np.asarray(lane, dtype=np.int64), *c["speed_rule"])

    def _desired_lanes(self, world, desired, lane, member, exiting, cx, v, index) -> np.ndarray:
        """Hook for subclasses: the lane each vehicle wants. The formation
        expert keeps what the formation layer assigned (members), heads for
        the ramp (exiting) or the main road (on-ramp), and otherwise keeps its
        lane."""
        return desired

    # ----------------------------------------------------------------- helpers
    def _exit_lanes(self, world, lane, lane_ref, member):
        """``(desired, exiting)`` before the ``_desired_lanes`` hook: targets
        of members, the ramp lane for exiting vehicles, the main road for
        free vehicles on a ramp (:func:`icv_envs.policies._kernels.exit_lanes`)."""
        return exit_lanes(*self._exit_args(world, lane, lane_ref, member))

    def _exit_args(self, world, lane, lane_ref, member) -> tuple:
        """:func:`~icv_envs.policies._kernels.exit_lanes`' arguments (for
        :meth:`_exit_lanes` and the one-call desired lanes of :meth:`compute`)."""
        tr = world.traffic
        cx, _ = tr.center()
        return (np.asarray(member, dtype=bool), np.asarray(lane_ref, dtype=np.int64), np.asarray(lane, dtype=np.int64),
                tr.exit, cx, *self._road_consts(world.road)["exit"])

    def _lane_end_escape(self, world, desired, lane, member, exiting):
        """``desired`` with free vehicles whose lane ends ahead sent to the
        nearest continuing main lane (:func:`icv_envs.policies._kernels.lane_end_escape`)."""
        return lane_end_escape(np.asarray(desired, dtype=np.int64), np.asarray(lane, dtype=np.int64),
                               np.asarray(member, dtype=bool), np.asarray(exiting, dtype=bool),
                               *self._escape_args(world))

    def _escape_args(self, world) -> tuple:
        """:func:`~icv_envs.policies._kernels.lane_end_escape`'s arguments after
        the desired lanes, lanes, members and exiting flags."""
        cx, _ = world.traffic.center()
        return (cx, *self._road_consts(world.road)["escape"])

    def _lane_change_starts(self, world, index, active, lane, desired, member):
        """Which vehicles start a lane change now: ``(rows, target lanes,
        curve lengths, blocked)``, ``blocked`` marking those whose
        manoeuvre was allowed but refused by the gaps (the rules:
        :func:`icv_envs.policies._kernels.lane_change_starts`)."""
        tr = world.traffic
        cx, cy = tr.center()
        return lane_change_starts(
            np.asarray(active, dtype=bool), cx, cy, tr.speed, np.asarray(tr.length, dtype=np.float64),
            np.asarray(lane, dtype=np.int64), np.asarray(desired, dtype=np.int64), np.asarray(member, dtype=bool),
            index.keys, index.rows, index.lanes, index.x, float(index.offset),
            *self._road_consts(world.road)["starts"])

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
        head, tail = self._safety_args(world, index, lane, desired, member, exiting, bounds)
        return safety_cap(*head, np.asarray(acc, dtype=np.float64), *tail)

    def _safety_args(self, world, index, lane, desired, member, exiting, bounds=None) -> tuple[tuple, tuple]:
        """:func:`~icv_envs.policies._kernels.safety_cap`'s arguments before and
        after the accelerations (for :meth:`_safety_cap` and the one-call
        tail of :meth:`compute`)."""
        tr = world.traffic
        cx, _ = tr.center()
        head = (index.keys, index.rows, index.lanes, index.x, float(index.offset), cx, tr.speed,
                np.asarray(tr.length, dtype=np.float64), tr.lc_lane, np.asarray(lane, dtype=np.int64),
                np.asarray(desired, dtype=np.int64), np.asarray(member, dtype=bool), np.asarray(exiting, dtype=bool))
        tail = self._road_consts(world.road)["safety"]  # (clipped to [a_min, a_max], its last two)
        if bounds is not None:
            tail = tail[:-2] + (float(bounds[0]), float(bounds[1]))
        return head, tail

    def _normalise(self, a: np.ndarray, phi: np.ndarray) -> np.ndarray:
        # compiled (policies/_kernels/laws.py::normalised_actions: the arithmetic
        # of ``clip(stack([where(a >= 0, a / a_max, -a / a_min), phi /
        # steer_max], axis=1), -1, 1)``, element by element)
        return normalised_actions(np.asarray(a, dtype=np.float64), np.asarray(phi, dtype=np.float64),
                                  *self._normalise_args())

    def _normalise_args(self) -> tuple:
        """``(a_max, a_min, steer_max)``, :func:`~icv_envs.policies._kernels.normalised_actions`' scales."""
        return self._normalise_scales

    def _accel_args(self, world, n, free_rows, free_pow, m, x_ref, v_ref, a_ref) -> tuple:
        """:func:`~icv_envs.policies._kernels.expert_accelerations`' arguments
        (for both paths of :meth:`compute`)."""
        tr = world.traffic
        cx, _ = tr.center()
        c = self._road_consts(world.road)
        return (n, free_rows, free_pow, tr.speed, *c["idm"], m, cx, np.asarray(x_ref, dtype=np.float64),
                np.asarray(v_ref, dtype=np.float64), np.asarray(a_ref, dtype=np.float64), *c["feedback"])

    def _lane_target_args(self, road, exiting, blocked, member) -> tuple:
        """:func:`~icv_envs.policies._kernels.expert_lane_speeds`' arguments after
        the lane speeds and lanes."""
        return (np.asarray(exiting, dtype=bool), np.asarray(blocked, dtype=bool), np.asarray(member, dtype=bool),
                *self._road_consts(road)["targets"])

    def compute(self, world) -> np.ndarray:
        p = self.p
        tr, road = world.traffic, world.road
        n = tr.n
        if n == 0:
            return np.zeros((0, 2))
        cx, cy = tr.center()
        v = tr.speed
        W = road.lane_width
        lane = road.lane_of_rows(cy)
        index = world.lane_index()
        x_ref, lane_ref, v_ref, member = world.manager.references(tr)

        # ------------------------------------------------------ desired lane
        # (compiled: policies/_kernels.exit_lanes and lane_end_escape, which
        # document the rules; the array code they replaced is their
        # reference in tests/test_kernels.py)
        if own_hooks(self, _HEAD_HOOKS):  # the three in one call (policies/_kernels.desired_lane_rows)
            desired, exiting = desired_lane_rows(*self._exit_args(world, lane, lane_ref, member),
                                                 *self._escape_args(world))
        else:
            desired, exiting = self._exit_lanes(world, lane, lane_ref, member)
            desired = self._desired_lanes(world, desired, lane, member, exiting, cx, v, index)
            desired = self._lane_end_escape(world, desired, lane, member, exiting)

        # --------------------------------------------- lane-change plan state
        # a lane change ends once past the curve AND settled on the new lane
        # centre (until then the vehicle keeps steering for it), or stopped
        # there (a vehicle held by a lane end before the end of its curve is
        # on the new lane and may plan its next change); one that strayed
        # from its curve re-plans (compiled: formation/_kernels.lateral_rows,
        # libm's arcsinh and sinh from stop 49, and
        # policies/_kernels.lane_changes_ended; every argument is a finite
        # float64 state array, every length > 0)
        active = tr.lc_lane >= 0
        if np.count_nonzero(active):
            a_rows = flatnonzero(active)
            y_plan, _ = _lane_change_lateral_rows(a_rows, tr.x, tr.lc_x0, tr.lc_y0, tr.lc_y1, tr.lc_len)
            lane_changes_ended(a_rows, y_plan, tr.x, tr.y, cy, v, tr.lc_x0, tr.lc_len, tr.lc_y1, tr.lc_lane,
                               float(p.replan_tolerance))
            active = tr.lc_lane >= 0

        # ------------------------------------------------ start lane changes
        # (compiled: policies/_kernels.lane_change_starts, which documents the
        # rules; the array code it replaced is its reference in tests/test_kernels.py)
        start, s_lane, s_len, blocked = self._lane_change_starts(world, index, active, lane, desired, member)
        if len(start):
            tr.lc_lane[start] = s_lane
            tr.lc_x0[start] = tr.x[start]
            tr.lc_y0[start] = tr.y[start]
            tr.lc_y1[start] = s_lane * W
            tr.lc_len[start] = s_len
            active = tr.lc_lane >= 0

        # ---------------------------------------------------------- steering
        # (preview points, the curve at them and pure pursuit: compiled
        # arithmetic around numpy's transcendental calls, the same numbers as
        # the array code bit for bit; tests/test_expert_kernels.py)
        px, py = preview_points(tr.x, v, lane, float(W), float(p.preview_min), float(p.preview_time))
        if np.count_nonzero(active):
            a_rows = flatnonzero(active)
            py[a_rows] = _lane_change_lateral_rows(a_rows, px, tr.lc_x0, tr.lc_y0, tr.lc_y1, tr.lc_len)[0]
        phi = _pure_pursuit_rows(tr.x, tr.y, tr.heading, px, py, float(p.wheelbase), float(p.steer_max),
                                 tr.heading_cos_sin())

        # ------------------------------------------------------ longitudinal
        # the lane's speed; the exit speed on the main road for exiting
        # vehicles; a free vehicle refused a lane change slows by
        # blocked_slowdown, and one refused on its way to its exit drops to
        # the minimum speed: alongside traffic at the lane speed then passes
        # it within seconds and opens the gap (at lane speed -
        # blocked_slowdown the vehicles heading for the same exit stay side
        # by side for hundreds of metres and one misses the exit)
        tail = own_hooks(self, _TAIL_HOOKS)
        targets = self._lane_target_args(road, exiting, blocked, member)
        if not tail:
            lane_speed = expert_lane_speeds(np.asarray(self._lane_speeds(road, lane), dtype=np.float64), lane,
                                            *targets)
        # free vehicles: the IDM without a leader (its power from numpy, as
        # traffic.idm_acceleration takes it); members: the feedback law on the
        # reference, which starts where the member joined and moves to its
        # slot smoothly (the formation layer re-plans it when the member falls
        # more than 5 m off), so the error seen here stays small; braking is
        # faded out as v approaches v_min (the control floor; the safety cap
        # below still wins). Compiled: policies/_kernels.expert_accelerations.
        free_rows = flatnonzero(~member)
        m = flatnonzero(member)
        a_ref = world.manager.reference_accel(tr)  # (cached with references() above)
        if tail:
            # the lane speeds and the free term (its power libm's inside from stop 50,
            # numpy's between the calls before), then the longitudinal law, the safety
            # envelope and the normalised actions, each run in one call
            # (policies/_kernels.free_speed_pow_rows, expert_control_rows)
            free_pow = free_speed_pow_rows(*self._lane_speed_args(road, lane), *targets, free_rows, v)
            head, tail_args = self._safety_args(world, index, lane, desired, member, exiting)
            return expert_control_rows(*self._accel_args(world, n, free_rows, free_pow, m, x_ref, v_ref, a_ref), *head,
                                       *tail_args, np.asarray(phi, dtype=np.float64), *self._normalise_args())
        free_pow = free_speed_pow(free_rows, v, lane_speed)
        acc = expert_accelerations(*self._accel_args(world, n, free_rows, free_pow, m, x_ref, v_ref, a_ref))
        # safety envelope: leaders in the lanes the vehicle occupies or enters
        acc = self._safety_cap(world, index, acc, lane, desired, member, exiting)
        return self._normalise(acc, phi)


# the hooks whose kernels compute() runs in one call while they are its own
# (icv_envs._hooks.own_hooks): the desired lanes, and the longitudinal tail
_HEAD_HOOKS = hook_table(FormationExpert, "_exit_lanes", "_desired_lanes", "_lane_end_escape")
_TAIL_HOOKS = hook_table(FormationExpert, "_lane_speeds", "_safety_cap", "_normalise")
