"""Geometry of the multi-lane unsignalized intersection: legs, lanes, paths through the box, zones.

Paper Sec. 4 and Table 2 (Xu et al., IET ITS 2021), docs/intersection.md.  Pure geometry, no vehicles:
the simulation core :mod:`icv_envs.sim.intersection_world` moves vehicles on it.

Geometry (:class:`IntersectionLayout`)
--------------------------------------
Coordinates and numbering are those of :mod:`icv_envs.platoon.geometry`:
origin at the centre, ``x`` east, ``y`` NORTH, legs ``N, E, S, W``, approach
lanes 0 (next to the centre line) .. 2 (kerb), movements ``3 * leg + turn``.
Every (movement, approach lane) has a centreline path through the box
(departure rule ``"same"``: a straight line or an exact quarter circle), held
analytically (start, direction, end, centre, radius) so that points, headings
and projections are closed-form and vectorised.  The lane-use table decides
which (movement, lane) paths exist in the road network; the derived conflict
model (:func:`icv_envs.platoon.conflicts.conflict_model`) comes with the
layout.

``box_half`` defaults to 16 m, not the 12 m of three 4 m lanes: a right turn
from the kerb lane is a quarter circle of radius ``box_half - 2.5 w``, 2 m
for a 12 m box, which the paper's vehicle (wheelbase 2.8 m, steering within
+-30 deg, minimum turning radius 4.85 m) cannot drive.  With 16 m it is 6 m
(25 deg of steering); the box is then the usual square with 4 m of rounded
kerb beyond the lane edges.  The conflict matrix is the same for 12 and
16 m (checked in the tests) and :func:`~icv_envs.platoon.conflicts.
required_layer_gap` stays 19 m, so ``D_t = 20 m`` remains valid.

Route coordinates (``s``, ``X``, ``dist``) and events: :mod:`icv_envs.sim.intersection_world`.
"""

from __future__ import annotations

import math

import numpy as np

from icv_envs.platoon.conflicts import conflict_model
from icv_envs.platoon._kernels import atan2_rows
from icv_envs.platoon.geometry import LEGS, N_LANES, lane_use_table
from icv_envs.sim._kernels.intersection import arc_project_rows

__all__ = ["IntersectionLayout", "DEFAULT_BOX_HALF", "validate_radii"]

#: Default half side of the box (metres), see the module docstring.
DEFAULT_BOX_HALF: float = 16.0

# outward unit vector of each leg (from the centre towards that leg), as in platoon.geometry
_OUT = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, -1.0], [-1.0, 0.0]])


def _right_of(d: np.ndarray) -> np.ndarray:
    """Unit vector(s) 90 degrees clockwise of ``d`` (the right-hand side)."""
    d = np.asarray(d, dtype=np.float64)
    return np.stack([d[..., 1], -d[..., 0]], axis=-1)


def _real(name, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(value)):
        raise ValueError(f"{name} must be a finite number (metres), got {value!r}")
    return float(value)


def validate_radii(R1, R2, R3, box_half: float = DEFAULT_BOX_HALF) -> tuple[float, float, float]:
    """Check the zone radii: ``box_half < R1 < R2 < R3`` (metres).

    Raises:
        ValueError: naming the radii and the required order.
    """
    r1, r2, r3 = _real("R1", R1), _real("R2", R2), _real("R3", R3)
    b = _real("box_half", box_half)
    if not (b < r1 < r2 < r3):
        raise ValueError(
            f"zone radii must be ordered box_half < R1 < R2 < R3 (coordinating < adjusting < "
            f"generation radius); got box_half={b:g}, R1={r1:g}, R2={r2:g}, R3={r3:g}"
        )
    return r1, r2, r3


class IntersectionLayout:
    """Geometry, lane use, paths and the conflict model of the intersection.

    Args:
        lane_use: ``"paper"``, ``"exclusive"`` or a table accepted by
            :func:`~icv_envs.platoon.geometry.lane_use_table`.
        lane_width: metres (4).
        box_half: half side of the box (16 m, see the module docstring).
        R1, R2, R3: coordinating / adjusting zone radii and generation radius
            (300, 500, 800 m; Table 2).
        departure_length: metres of departure lane after the box at whose
            end vehicles leave the simulation.
        opposing_left_conflict: passed to the conflict model.

    Raises:
        ValueError: bad lane use (unknown preset, a movement without a lane),
            radii not ordered, bad lengths.
    """

    def __init__(self, lane_use="paper", lane_width: float = 4.0, box_half: float = DEFAULT_BOX_HALF,
                 R1: float = 300.0, R2: float = 500.0, R3: float = 800.0, departure_length: float = 40.0,
                 opposing_left_conflict: bool = False) -> None:
        w = _real("lane_width", lane_width)
        b = _real("box_half", box_half)
        if w <= 0:
            raise ValueError(f"lane_width must be > 0 metres, got {lane_width!r}")
        if b < N_LANES * w:
            raise ValueError(f"box_half must be >= {N_LANES} * lane_width = {N_LANES * w:g} m, got {box_half!r}")
        self.R1, self.R2, self.R3 = validate_radii(R1, R2, R3, b)
        dl = _real("departure_length", departure_length)
        if dl <= 0:
            raise ValueError(f"departure_length must be > 0 metres, got {departure_length!r}")
        self.lane_use_name = lane_use if isinstance(lane_use, str) else "custom"
        self.lane_use = lane_use_table(lane_use)
        self.model = conflict_model(lane_use, opposing_left_conflict, lane_width=w, box_half=b)
        self.conflict = np.asarray(self.model.matrix, dtype=bool)
        self.lane_width = w
        self.box_half = b
        self.departure_length = dl
        self.out = _OUT.copy()
        self.app_dir = -_OUT
        # the approach directions' angles (exact: arctan2 of axis-aligned unit vectors)
        self.app_angle = np.arctan2(self.app_dir[:, 1], self.app_dir[:, 0])
        self.app_angle.setflags(write=False)
        self.app_right = _right_of(self.app_dir)
        self.dep_right = _right_of(_OUT)
        self.allowed = np.zeros((12, N_LANES), dtype=bool)
        for m, lanes in self.lane_use.items():
            self.allowed[m, list(lanes)] = True
        self.exit_of = np.array([(m // 3 + 1 + m % 3) % 4 for m in range(12)], dtype=np.int64)
        self.leg_of = np.arange(12) // 3
        self.turn_of = np.arange(12) % 3
        self._build_paths()

    # ------------------------------------------------------------------ paths
    def _build_paths(self) -> None:
        w, b = self.lane_width, self.box_half
        n = 12 * N_LANES
        self.P0 = np.zeros((n, 2))
        self.D0 = np.zeros((n, 2))
        self.P1 = np.zeros((n, 2))
        self.D1 = np.zeros((n, 2))
        self.C = np.zeros((n, 2))
        self.R = np.ones(n)
        self.TH0 = np.zeros(n)
        self.SGN = np.zeros(n)
        self.arc = np.zeros(n, dtype=bool)
        self.L = np.zeros(n)
        self.dlane = np.zeros(n, dtype=np.int64)
        for m in range(12):
            leg, turn = divmod(m, 3)
            e = (leg + 1 + turn) % 4
            for a in range(N_LANES):
                p = 3 * m + a
                d0 = self.app_dir[leg]
                p0 = b * _OUT[leg] + (a + 0.5) * w * _right_of(d0)
                d1 = _OUT[e]
                p1 = b * _OUT[e] + (a + 0.5) * w * _right_of(d1)  # departure rule "same"
                self.P0[p], self.D0[p], self.P1[p], self.D1[p] = p0, d0, p1, d1
                self.dlane[p] = a
                if turn == 1:
                    self.L[p] = float(np.linalg.norm(p1 - p0))
                    continue
                r = float(np.dot(p1 - p0, d0))
                side = _right_of(d0) if turn == 2 else -_right_of(d0)
                c = p0 + r * side
                self.arc[p] = True
                self.C[p] = c
                self.R[p] = r
                self.TH0[p] = math.atan2(p0[1] - c[1], p0[0] - c[0])
                self.SGN[p] = 1.0 if turn == 0 else -1.0  # left turns counter-clockwise
                self.L[p] = r * math.pi / 2.0

    @staticmethod
    def path_id(movement, lane):
        return 3 * np.asarray(movement) + np.asarray(lane)

    def route_points(self, pid, s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points ``(x, y)`` and headings at route coordinate ``s`` of paths ``pid``.

        Before the stop line the route is the approach lane (straight), after
        the box the departure lane; vectorised over vehicles.
        """
        pid = np.asarray(pid, dtype=np.int64)
        s = np.asarray(s, dtype=np.float64)
        L = self.L[pid]
        after = s > L
        base = np.where(after[:, None], self.P1[pid], self.P0[pid])
        dirn = np.where(after[:, None], self.D1[pid], self.D0[pid])
        t = np.where(after, s - L, s)
        pts = base + t[:, None] * dirn
        # (libm's atan2 from stop 50, platoon/_kernels.atan2_rows: NumPy's arctan2 at X86_V3)
        head = atan2_rows(np.ascontiguousarray(dirn[:, 1]), np.ascontiguousarray(dirn[:, 0]))
        on_arc = self.arc[pid] & (s >= 0) & ~after
        if on_arc.any():
            k = np.flatnonzero(on_arc)
            q = pid[k]
            th = self.TH0[q] + self.SGN[q] * s[k] / self.R[q]
            pts[k, 0] = self.C[q, 0] + self.R[q] * np.cos(th)
            pts[k, 1] = self.C[q, 1] + self.R[q] * np.sin(th)
            head[k] = th + self.SGN[q] * (0.5 * math.pi)
        return pts[:, 0], pts[:, 1], head

    def project(self, pid, cx, cy, phase):
        """Route coordinate ``s`` and signed offset to the right of the path.

        ``phase`` 0 (approach): along the approach lane line; 1 (in the box):
        onto the path (angle around the arc centre for turns); 2 (departed):
        along the departure lane line.
        """
        pid = np.asarray(pid, dtype=np.int64)
        px = cx - self.P0[pid, 0]
        py = cy - self.P0[pid, 1]
        d0 = self.D0[pid]
        s = px * d0[:, 0] + py * d0[:, 1]
        lat = px * d0[:, 1] - py * d0[:, 0]  # dot with right_of(d0) = (d_y, -d_x)
        dep = phase == 2
        if dep.any():
            k = np.flatnonzero(dep)
            q = pid[k]
            qx = cx[k] - self.P1[q, 0]
            qy = cy[k] - self.P1[q, 1]
            d1 = self.D1[q]
            s[k] = self.L[q] + qx * d1[:, 0] + qy * d1[:, 1]
            lat[k] = qx * d1[:, 1] - qy * d1[:, 0]
        box = (phase == 1) & self.arc[pid]
        if box.any():
            k = np.flatnonzero(box)
            s[k], lat[k] = self.arc_project(pid[k], cx[k], cy[k])
        return s, lat

    def arc_project(self, q, cx, cy):
        """:meth:`project` of points in the box onto the turn arcs ``q``
        (path ids with ``arc``): the angle around the arc's centre, as arc
        length from the stop line, and the signed offset to the right."""
        # (compiled from stop 50, sim/_kernels/intersection.arc_project_rows: libm's atan2, NumPy's at
        # X86_V3; NumPy's arctan2 before)
        q = np.asarray(q, dtype=np.int64)
        return arc_project_rows(q, np.asarray(cx, dtype=np.float64), np.asarray(cy, dtype=np.float64), self.C,
                                self.TH0, self.R, self.SGN)

    # ---------------------------------------------------------------- network
    def to_network(self, approach_extra: float = 20.0):
        """highway-env :class:`~highway_env.road.road.RoadNetwork` of the intersection.

        In highway-env's screen frame: ``(x, -y)`` of ours (``y`` points
        SOUTH, so that north is up on screen).  Nodes (each approach lane and
        each departure lane has its own, so that a turn edge starts only from
        a lane the lane-use table allows for that movement):

        * ``"{leg}:in{a}"`` -> ``"{leg}:stop{a}"``: approach lane ``a`` from
          ``R3 + approach_extra`` to the stop line;
        * ``"{leg}:stop{a}"`` -> ``"{exit}:exit{j}"``: the path of a movement
          allowed from lane ``a`` (StraightLane or CircularLane);
        * ``"{exit}:exit{j}"`` -> ``"{exit}:out{j}"``: departure lane ``j``
          from the box edge, as long as the approach road.
        """
        from highway_env.road.lane import CircularLane, LineType, StraightLane
        from highway_env.road.road import RoadNetwork

        C, S, N, CL = LineType.CONTINUOUS, LineType.STRIPED, LineType.NONE, LineType.CONTINUOUS_LINE
        w, b = self.lane_width, self.box_half
        far = self.R3 + approach_extra - b

        def flip(p):
            return np.array([p[0], -p[1]])

        net = RoadNetwork()
        for leg in range(4):
            lg = LEGS[leg]
            d0 = self.app_dir[leg]
            for a in range(N_LANES):
                stop = b * _OUT[leg] + (a + 0.5) * w * self.app_right[leg]
                start = stop - far * d0
                lines = (C if a == 0 else S, CL if a == N_LANES - 1 else N)
                net.add_lane(f"{lg}:in{a}", f"{lg}:stop{a}",
                             StraightLane(flip(start), flip(stop), width=w, line_types=lines, speed_limit=20.0))
            for j in range(N_LANES):
                edge = b * _OUT[leg] + (j + 0.5) * w * self.dep_right[leg]
                end = edge + far * _OUT[leg]
                lines = (N if j == 0 else S, CL if j == N_LANES - 1 else N)
                net.add_lane(f"{lg}:exit{j}", f"{lg}:out{j}",
                             StraightLane(flip(edge), flip(end), width=w, line_types=lines, speed_limit=20.0))
        for m in range(12):
            leg, turn = divmod(m, 3)
            e = self.exit_of[m]
            for a in self.lane_use[m]:
                p = 3 * m + a
                j = int(self.dlane[p])
                frm, to = f"{LEGS[leg]}:stop{a}", f"{LEGS[e]}:exit{j}"
                if not self.arc[p]:
                    lane = StraightLane(flip(self.P0[p]), flip(self.P1[p]), width=w, line_types=(N, N),
                                        speed_limit=20.0)
                else:
                    sgn = self.SGN[p]
                    start = -self.TH0[p]
                    end = start - sgn * 0.5 * math.pi
                    lane = CircularLane(flip(self.C[p]), float(self.R[p]), start, end, clockwise=bool(sgn < 0),
                                        width=w, line_types=(N, N), speed_limit=20.0)
                net.add_lane(frm, to, lane)
        return net
