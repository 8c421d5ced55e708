"""Vehicle state as arrays, the paper's kinematic bicycle model, lane-sorted
neighbour search and sort-based collision checks.

Every per-step operation here is vectorised over vehicles and costs
O(N log N) (a sort) rather than highway-env's O(N^2) scans:

* :meth:`Traffic.step` integrates the rear-axle kinematic bicycle model of
  the paper's Sec. 2.2, eq. (state), for all vehicles at once;
* :func:`lane_index` builds a lane-sorted index (a vehicle that straddles two
  lanes is listed in both) and :func:`leaders` / :func:`followers` answer
  "who is ahead of me in lane l" with one ``np.searchsorted`` per query batch;
* :func:`find_collisions` sorts body centres by ``x`` and only compares each
  vehicle with its next few neighbours in that order (sweep and prune), then
  runs an exact separating-axis test on the few candidate pairs.
"""

from __future__ import annotations

import numpy as np

from icv_envs.sim._kernels import build_lane_index, build_lane_index_pair, collision_pairs, cos_sin_rows, leader_rows

__all__ = [
    "Traffic",
    "LaneIndex",
    "lane_index",
    "leaders",
    "followers",
    "find_collisions",
    "rect_overlap",
    "idm_acceleration",
    "limit_steering",
    "LAT_ACCEL_MAX",
]

#: Friction coefficient of a dry asphalt road (Rajamani, *Vehicle Dynamics and
#: Control*, 2nd ed., Springer 2012, Sec. 13: peak mu about 0.8-1.0 on dry
#: asphalt; we take the low end).
FRICTION_MU = 0.8
#: Gravitational acceleration [m/s^2].
GRAVITY = 9.81
#: Lateral-acceleration bound of the kinematic bicycle model [m/s^2]:
#: ``|a_y| <= 0.5 mu g``. Polack, Altche, d'Andrea-Novel and de La Fortelle,
#: "The kinematic bicycle model: a consistent model for planning feasible
#: trajectories for autonomous vehicles?", IEEE IV 2017, show that the
#: kinematic model stays consistent with a dynamic (tyre) model only while the
#: lateral acceleration stays below ``0.5 mu g``; beyond it the tyres saturate
#: and a kinematic model would let a vehicle turn on the spot at speed.
LAT_ACCEL_MAX = 0.5 * FRICTION_MU * GRAVITY

_FLOAT_FIELDS = (
    "x",  # rear-axle position along the road [m]
    "y",  # rear-axle lateral position [m], lane l centred at l * lane_width
    "heading",  # yaw angle from +x towards +y [rad]
    "speed",  # [m/s]
    "accel",  # last applied acceleration [m/s^2]
    "steer",  # last applied front-wheel steering angle [rad]
    "length",  # body length [m]
    "width",  # body width [m]
    "spawn_time",  # [s]
    # expert memory: the Bezier lane-change plan (rear-axle path)
    "lc_x0",
    "lc_y0",
    "lc_y1",
    "lc_len",
    # formation manager: the assigned target, metres behind the front target
    "tgt_behind",
    # standing time [s]: how long the vehicle has been below 0.1 m/s (jam detection)
    "stopped_for",
)
_INT_FIELDS = (
    "vid",  # unique id, also the agent index ("icv_<vid>")
    "exit",  # index of the off-ramp to leave at, -1 for none
    "group",  # formation id, -1 when not in a formation
    "lc_lane",  # lane the active lane change goes to, -1 when none
    "tgt_lane",  # lane of the assigned formation target, -1 when none
)
_BOOL_FIELDS = ("crashed",)


class Traffic:
    """Structure-of-arrays vehicle state.

    Arrays are kept compact (vehicle ``i`` is row ``i`` of every array) and
    sorted by ``vid``; removal deletes rows. Positions are rear-axle
    positions, as in the paper's model; :meth:`center` gives body centres
    (the centre of the wheelbase, i.e. ``wheelbase / 2`` ahead of the rear
    axle), used for gaps, lanes and collisions.
    """

    def __init__(self, wheelbase: float = 2.8, period: float | None = None,
                 lat_accel_max: float = LAT_ACCEL_MAX) -> None:
        self.wheelbase = float(wheelbase)
        self.lat_accel_max = None if lat_accel_max is None else float(lat_accel_max)  # None: no limit
        self.period = None if period is None else float(period)
        for f in _FLOAT_FIELDS:
            setattr(self, f, np.zeros(0, dtype=np.float64))
        for f in _INT_FIELDS:
            setattr(self, f, np.zeros(0, dtype=np.int64))
        for f in _BOOL_FIELDS:
            setattr(self, f, np.zeros(0, dtype=bool))
        self.next_vid = 0
        self._center = None  # (x, y, heading, cx, cy): see center()
        self._cos_sin = None  # (heading, cos, sin): see heading_cos_sin()

    # ------------------------------------------------------------ bookkeeping
    @property
    def n(self) -> int:
        return len(self.vid)

    def add(
        self,
        x,
        y,
        speed,
        heading=0.0,
        length=5.0,
        width=2.0,
        exit=-1,
        time: float = 0.0,
    ) -> np.ndarray:
        """Add vehicles (arrays broadcast); returns their new ids."""
        x = np.atleast_1d(np.asarray(x, dtype=np.float64))
        k = len(x)
        vals = {
            "x": x,
            "y": y,
            "heading": heading,
            "speed": speed,
            "accel": 0.0,
            "steer": 0.0,
            "length": length,
            "width": width,
            "spawn_time": time,
            "lc_x0": 0.0,
            "lc_y0": 0.0,
            "lc_y1": 0.0,
            "lc_len": 0.0,
            "tgt_behind": 0.0,
            "stopped_for": 0.0,
        }
        ids = np.arange(self.next_vid, self.next_vid + k, dtype=np.int64)
        self.next_vid += k
        # (np.full broadcasts a scalar or a (k,) array as broadcast_to did, without its Python overhead)
        for f in _FLOAT_FIELDS:
            v = np.full(k, vals[f], dtype=np.float64)
            setattr(self, f, np.concatenate([getattr(self, f), v]))
        ivals = {"vid": ids, "exit": exit, "group": -1, "lc_lane": -1, "tgt_lane": -1}
        for f in _INT_FIELDS:
            v = np.full(k, ivals[f], dtype=np.int64)
            setattr(self, f, np.concatenate([getattr(self, f), v]))
        self.crashed = np.concatenate([self.crashed, np.zeros(k, dtype=bool)])
        return ids

    def remove(self, mask: np.ndarray) -> None:
        keep = ~np.asarray(mask, dtype=bool)
        for f in _FLOAT_FIELDS + _INT_FIELDS + _BOOL_FIELDS:
            setattr(self, f, getattr(self, f)[keep])

    def rows(self, vids) -> np.ndarray:
        """Row indices of vehicle ids (ids must be present)."""
        return np.searchsorted(self.vid, vids)

    def center(self) -> tuple[np.ndarray, np.ndarray]:
        """Body centres ``(cx, cy)``, ``wheelbase / 2`` ahead of the rear
        axle (``cx`` folded onto a ring). Kept until ``x``, ``y`` or
        ``heading`` is replaced, so the dozen callers of a step share one
        computation. The centres, and the ``x``, ``y`` and ``heading``
        arrays they were computed from, are read-only from then on: a
        change of the state assigns new arrays (``tr.x = tr.x + dx``), and
        writing into the old ones in place raises instead of leaving stale
        centres."""
        c = self._center
        if c is not None and c[0] is self.x and c[1] is self.y and c[2] is self.heading:
            return c[3], c[4]
        h = 0.5 * self.wheelbase
        ch, sh = self.heading_cos_sin()  # (libm's, as the compiled substeps' centres; NumPy's before stop 51)
        cx = self.x + h * ch
        if self.period is not None:
            cx = np.mod(cx, self.period)
        return self.set_center(cx, self.y + h * sh)

    def heading_cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """libm's ``cos`` and ``sin`` of the headings (the compiled
        substeps' calls; from stop 51, NumPy's before), kept until
        ``heading`` is replaced (as :meth:`center`; ``heading`` is read-only
        from then on), so the observations' features and the expert's pure
        pursuit of one state share them. The compiled substeps leave theirs
        (:meth:`keep_cos_sin`); otherwise one compiled call
        (:func:`icv_envs.sim._kernels.cos_sin_rows`). Read them, do not
        write them."""
        c = self._cos_sin
        h = self.heading
        if c is not None and c[0] is h:
            return c[1], c[2]
        cs = cos_sin_rows(h)
        return self.keep_cos_sin(cs[0], cs[1])

    def keep_cos_sin(self, c: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Record ``(c, s)`` as the cosines and sines of the current headings
        (libm's: the compiled substeps compute them with the new state);
        ``heading`` is read-only from then on."""
        self.heading.setflags(write=False)
        self._cos_sin = (self.heading, c, s)
        return c, s

    def set_center(self, cx: np.ndarray, cy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Record ``(cx, cy)`` as the body centres of the current state (the
        compiled substep computes them with the new state)."""
        for arr in (cx, cy, self.x, self.y, self.heading):
            arr.setflags(write=False)
        self._center = (self.x, self.y, self.heading, cx, cy)
        return cx, cy

    # --------------------------------------------------------------- dynamics
    def step(self, accel: np.ndarray, steer: np.ndarray, dt: float, v_max: float) -> None:
        """Integrate the rear-axle kinematic bicycle model (paper Sec. 2.2,
        eq. (state); the paper's X/Y are swapped relative to ours):

            x' = v cos(theta),  y' = v sin(theta),
            theta' = v tan(phi) / L,  v' = a

        with forward Euler over ``dt``. Speed is kept in ``[0, v_max]``:
        the lower bound of the configured speed range is a control target,
        not a physical limit, so a vehicle can always brake to a stop.

        The steering angle is first limited by speed so that the lateral
        acceleration ``v^2 tan(phi) / L`` stays within ``lat_accel_max``
        (:func:`limit_steering`, :data:`LAT_ACCEL_MAX`); ``steer`` records
        the angle actually applied.

        :meth:`icv_envs.sim.world.World.substep` runs the same operations
        compiled (:func:`icv_envs.sim._kernels.kinematic_substep`, tested
        against this method)."""
        self.accel = np.asarray(accel, dtype=np.float64)
        self.steer = limit_steering(np.asarray(steer, dtype=np.float64), self.speed, self.wheelbase,
                                    self.lat_accel_max)
        v = self.speed
        self.x = self.x + v * np.cos(self.heading) * dt
        self.y = self.y + v * np.sin(self.heading) * dt
        self.heading = self.heading + v * np.tan(self.steer) / self.wheelbase * dt
        self.speed = np.clip(v + self.accel * dt, 0.0, v_max)
        if self.period is not None:
            self.x = np.mod(self.x, self.period)


def limit_steering(steer, speed, wheelbase=2.8, lat_accel_max=LAT_ACCEL_MAX):
    """Front-wheel angle limited so that the lateral acceleration of the
    rear-axle kinematic bicycle model, ``a_y = v^2 tan(phi) / L``, satisfies
    ``|a_y| <= lat_accel_max`` (default ``0.5 mu g``, see
    :data:`LAT_ACCEL_MAX`). At low speed the mechanical limit
    (``steer_max``, applied by the caller) is the binding one; above
    ``sqrt(a_y L / tan(steer_max))`` (about 4.5 m/s with 30 deg) this one is.
    ``lat_accel_max=None`` disables the limit. Vectorised."""
    steer = np.asarray(steer, dtype=np.float64)
    if lat_accel_max is None:
        return steer
    v2 = np.maximum(np.asarray(speed, dtype=np.float64) ** 2, 1e-9)
    phi_max = np.arctan(float(lat_accel_max) * float(wheelbase) / v2)
    return np.clip(steer, -phi_max, phi_max)


def bicycle_step(x, y, heading, speed, accel, steer, dt, wheelbase=2.8, v_max=np.inf, lat_accel_max=None):
    """Pure-function form of :meth:`Traffic.step` (paper eq. (state)); used by
    the highway-env vehicle class so both paths share one model. With
    ``lat_accel_max`` the steering is limited by :func:`limit_steering`
    first (:class:`Traffic` always applies it)."""
    steer = limit_steering(steer, speed, wheelbase, lat_accel_max)
    x = x + speed * np.cos(heading) * dt
    y = y + speed * np.sin(heading) * dt
    heading = heading + speed * np.tan(steer) / wheelbase * dt
    speed = np.clip(speed + accel * dt, 0.0, v_max)
    return x, y, heading, speed


# ---------------------------------------------------------------- neighbours
class LaneIndex:
    """Vehicles sorted by (lane, x), a vehicle listed once per lane it
    occupies. ``key = lane * offset + x`` makes one sorted float array so a
    batch of (lane, x) queries is a single ``np.searchsorted``."""

    __slots__ = ("keys", "rows", "lanes", "x", "offset")

    def __init__(self, keys, rows, lanes, x, offset):
        self.keys, self.rows, self.lanes, self.x, self.offset = keys, rows, lanes, x, offset


def occupied_lanes(cy, width, lane_width, n_lanes, margin=0.0, length=None, heading=None):
    """(rows, lanes) pairs: vehicle ``row`` overlaps lane ``lane`` when its
    footprint reaches more than ``margin`` metres over the lane's edge line.

    The footprint is the rotated body rectangle: with ``length`` and
    ``heading`` its lateral half-extent is ``(L |sin h| + W |cos h|) / 2``, so
    a vehicle angled across a lane line (mid lane change) is listed in every
    lane a corner of it is in, and the vehicles of those lanes see it."""
    base = np.rint(cy / lane_width).astype(np.int64)
    rows_l, lanes_l = [], []
    idx = np.arange(len(cy))
    half = 0.5 * np.asarray(width, dtype=np.float64)
    if length is not None and heading is not None:
        half = 0.5 * (np.asarray(length) * np.abs(np.sin(heading)) + np.asarray(width) * np.abs(np.cos(heading)))
    reach = 0.5 * lane_width + half - margin
    for d in (-1, 0, 1):
        lane = base + d
        ok = (lane >= 0) & (lane < n_lanes) & (np.abs(cy - lane * lane_width) < reach)
        rows_l.append(idx[ok])
        lanes_l.append(lane[ok])
    return np.concatenate(rows_l), np.concatenate(lanes_l)


#: how far from a ring's seam :func:`lane_index` lists a vehicle a second time, one lap on [m]
LANE_INDEX_GHOST = 1000.0


def lane_index(cx, cy, width, lane_width, n_lanes, road_length, periodic: bool = False, ghost: float = LANE_INDEX_GHOST,
               reserved_lane=None, length=None, heading=None, pair: bool = False):
    """Build the lane-sorted index. On a ring (``periodic``), vehicles within
    ``ghost`` metres of the seam are listed a second time one lap further
    (``x + length`` and ``x - length``) so that searches see round the seam;
    ``LaneIndex.x`` holds those unfolded positions (use it for gaps).

    ``reserved_lane[i] >= 0`` lists vehicle ``i`` in that lane too: a vehicle
    that has started a lane change holds its target lane before its body
    reaches it (a turn signal), so two vehicles do not move into one gap.
    ``length`` and ``heading`` give each vehicle's footprint (see
    :func:`occupied_lanes`). With ``pair`` (and ``reserved_lane``) both
    views at once, the body-only one first, each as its own call builds it
    (:func:`icv_envs.sim._kernels.build_lane_index_pair`)."""
    f = np.float64
    n = len(cx)
    footprint = length is not None and heading is not None

    def vec(a):
        a = np.asarray(a, dtype=f)
        return a if a.shape == (n,) else np.broadcast_to(a, (n,))

    width = vec(width)
    length = vec(length if footprint else 0.0)
    heading = vec(heading if footprint else 0.0)
    args = (np.asarray(cx, dtype=f), np.asarray(cy, dtype=f), width, length, heading, footprint, float(lane_width),
            int(n_lanes))
    tail = (bool(periodic), float(road_length), float(ghost))
    if pair:
        k0, r0, l0, x0, k1, r1, l1, x1, offset = build_lane_index_pair(
            *args, np.asarray(reserved_lane, dtype=np.int64), *tail)
        return LaneIndex(k0, r0, l0, x0, offset), LaneIndex(k1, r1, l1, x1, offset)
    res = np.zeros(0, dtype=np.int64) if reserved_lane is None else np.asarray(reserved_lane, dtype=np.int64)
    keys, rows, lanes, xs, offset = build_lane_index(*args, res, *tail)
    return LaneIndex(keys, rows, lanes, xs, offset)


def leaders(index: LaneIndex, q_rows, q_lanes, cx, return_x: bool = False):
    """Row of the nearest other vehicle at or ahead of vehicle ``q_rows``
    (body-centre x greater or EQUAL) in lane ``q_lanes``; -1 if none. A
    vehicle exactly alongside counts as a leader (at a negative gap), so two
    vehicles that keep identical x (members of one sublayer) always see each
    other. With ``return_x`` also the leader's (unfolded) position."""
    q_rows = np.ascontiguousarray(q_rows, dtype=np.int64)
    q_lanes = np.asarray(q_lanes, dtype=np.int64)
    if q_lanes.shape != q_rows.shape:
        q_lanes = np.ascontiguousarray(np.broadcast_to(q_lanes, q_rows.shape))
    out, xo = leader_rows(index.keys, index.rows, index.lanes, index.x, float(index.offset), q_rows, q_lanes,
                          np.asarray(cx, dtype=np.float64))
    return (out, xo) if return_x else out


def followers(index: LaneIndex, q_rows, q_lanes, cx, return_x: bool = False):
    """Row of the nearest other vehicle strictly behind ``q_rows`` in
    ``q_lanes`` (a vehicle exactly alongside is a leader, see :func:`leaders`); -1 if none."""
    q_rows = np.asarray(q_rows, dtype=np.int64)
    q_lanes = np.asarray(q_lanes, dtype=np.int64)
    out = np.full(len(q_rows), -1, dtype=np.int64)
    xo = np.full(len(q_rows), -np.inf)
    if not len(index.keys):
        return (out, xo) if return_x else out
    qk = q_lanes * index.offset + cx[q_rows]
    pos = np.searchsorted(index.keys, qk, side="left") - 1
    ok = pos >= 0
    p = np.maximum(pos, 0)
    ok &= (index.lanes[p] == q_lanes) & (index.rows[p] != q_rows)
    out[ok] = index.rows[p[ok]]
    xo[ok] = index.x[p[ok]]
    return (out, xo) if return_x else out


# ---------------------------------------------------------------- collisions
def rect_overlap(c1x, c1y, h1, l1, w1, c2x, c2y, h2, l2, w2) -> np.ndarray:
    """Exact overlap test of oriented rectangles (separating axis theorem),
    vectorised over pairs. ``h`` headings, ``l`` lengths, ``w`` widths."""
    dx, dy = c2x - c1x, c2y - c1y
    u1 = (np.cos(h1), np.sin(h1))
    u2 = (np.cos(h2), np.sin(h2))
    overlap = np.ones(np.shape(dx), dtype=bool)
    for ax, ay in (u1, (-u1[1], u1[0]), u2, (-u2[1], u2[0])):
        d = np.abs(dx * ax + dy * ay)
        r1 = 0.5 * l1 * np.abs(ax * u1[0] + ay * u1[1]) + 0.5 * w1 * np.abs(-ax * u1[1] + ay * u1[0])
        r2 = 0.5 * l2 * np.abs(ax * u2[0] + ay * u2[1]) + 0.5 * w2 * np.abs(-ax * u2[1] + ay * u2[0])
        overlap &= d < r1 + r2
    return overlap


def find_collisions(cx, cy, heading, length, width, period: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """All colliding pairs ``(i, j)`` (rows, i < j in x order).

    Sweep and prune: sort by x; compare each vehicle with the vehicle ``k``
    places ahead for k = 1, 2, ... while any such pair is closer in x than
    the largest possible sum of half-extents. Axis-aligned bounding boxes
    prune, the separating-axis test decides. O(N log N + N k_max). On a
    ring (``period``) vehicles near the seam get a ghost one lap on; pairs
    found through a ghost are mapped back to rows (deduplicated, sorted).
    Compiled whole (:func:`icv_envs.sim._kernels.collision_pairs`)."""
    f = np.float64
    return collision_pairs(np.asarray(cx, dtype=f), np.asarray(cy, dtype=f), np.asarray(heading, dtype=f),
                           np.asarray(length, dtype=f), np.asarray(width, dtype=f),
                           -1.0 if period is None else float(period))


# ---------------------------------------------------------------------- IDM
def idm_acceleration(v, v0, gap, dv, a_max=3.0, b=2.0, T=1.0, s0=2.0, delta=4.0, free_term=True):
    """Intelligent Driver Model (Treiber et al. 2000), vectorised.

    ``gap`` is bumper-to-bumper (``inf`` for no leader), ``dv = v - v_lead``.
    With ``free_term=False`` only the interaction term ``-a (s*/s)^2`` plus
    ``a`` is returned: the safety envelope used on top of the formation law.
    """
    v = np.asarray(v, dtype=np.float64)
    s_star = s0 + np.maximum(0.0, v * T + v * dv / (2.0 * np.sqrt(a_max * b)))
    gap = np.maximum(np.asarray(gap, dtype=np.float64), 0.1)
    inter = (s_star / gap) ** 2
    if free_term:
        free = (v / np.maximum(v0, 0.1)) ** delta
        return a_max * (1.0 - free - inter)
    return a_max * (1.0 - inter)
