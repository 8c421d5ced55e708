"""Straight multi-lane road layout: lanes, lane drops, obstacles and ramps.

The simulation core works in road coordinates: ``x`` metres along the road,
``y`` metres to the right of the centre of lane 0 (highway-env's convention:
lane 0 is the leftmost lane, ``y`` grows to the right of the driving
direction, lane ``l`` is centred at ``y = l * lane_width``). The ramp lane,
when the road has ramps, is lane ``n_lanes`` (to the right of the main road),
as in the paper's Fig. 2a and Table 1 (a merge segment of 100 m at an
on-ramp, a diverge segment of 50 m at an off-ramp).

Everything here is a small set of numpy arrays so the per-step queries
(``available``, ``interval_end``) are vectorised over vehicles. The layout is
also turned into a highway-env :class:`~highway_env.road.road.RoadNetwork`
for rendering (:meth:`RoadLayout.to_network`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from icv_envs.sim._kernels import interval_ends, lanes_available
from icv_envs.sim._kernels.physics import lane_of_rows
from icv_envs._ufuncs import clip as uclip

__all__ = ["OnRamp", "OffRamp", "Obstacle", "RoadLayout"]


@dataclass(frozen=True)
class OnRamp:
    """An on-ramp: the ramp lane runs from ``start - approach`` to ``end``.

    Vehicles on the ramp lane may move to the rightmost main lane only in the
    merge segment ``[start, end]`` (paper Table 1: 100 m).
    """

    start: float
    end: float
    approach: float = 300.0


@dataclass(frozen=True)
class OffRamp:
    """An off-ramp: the ramp lane opens at ``start`` (diverge segment
    ``[start, end]``, paper Table 1: 50 m) and continues to ``exit_x`` where
    the vehicle leaves the simulation (it has reached its exit)."""

    start: float
    end: float
    exit_x: float


@dataclass(frozen=True)
class Obstacle:
    """A static obstacle centred at ``x`` in ``lane``, ``length`` metres long.

    Paper Sec. 3.4: an obstacle that makes its lane undrivable is handled as a
    lane-count change, so it blocks the whole lane over its length."""

    lane: int
    x: float
    length: float = 4.0
    width: float = 2.0


@dataclass
class RoadLayout:
    """A straight road of ``n_lanes`` main lanes plus an optional ramp lane.

    ``lane_ends[l]`` is where main lane ``l`` ends (``inf`` if it runs to the
    end of the road): a lane drop. Obstacles block their lane over their
    length. Main lane ``l`` is available at ``x`` when ``x < lane_ends[l]``
    and no obstacle covers ``x``; the ramp lane is available inside a ramp's
    extent only.
    """

    n_lanes: int
    length: float
    lane_width: float = 4.0
    lane_ends: np.ndarray | None = None
    on_ramps: list[OnRamp] = field(default_factory=list)
    off_ramps: list[OffRamp] = field(default_factory=list)
    obstacles: list[Obstacle] = field(default_factory=list)
    periodic: bool = False

    def __post_init__(self) -> None:
        if int(self.n_lanes) != self.n_lanes or self.n_lanes < 1:
            raise ValueError(f"n_lanes must be an integer >= 1, got {self.n_lanes!r}")
        if not np.isfinite(self.length) or self.length <= 0:
            raise ValueError(f"road length must be a finite number > 0, got {self.length!r}")
        if self.lane_ends is None:
            self.lane_ends = np.full(self.n_lanes, np.inf)
        self.lane_ends = np.asarray(self.lane_ends, dtype=np.float64)
        if self.lane_ends.shape != (self.n_lanes,):
            raise ValueError(
                f"lane_ends must have one entry per main lane ({self.n_lanes}), got shape {self.lane_ends.shape}"
            )
        for ob in self.obstacles:
            if not 0 <= ob.lane < self.n_lanes:
                raise ValueError(f"obstacle lane must be in [0, {self.n_lanes - 1}], got {ob.lane}")
        # Intervals where the ramp lane exists, as arrays [k, 2]
        ramp = [(r.start - r.approach, r.end) for r in self.on_ramps]
        ramp += [(r.start, r.exit_x) for r in self.off_ramps]
        # merge touching / overlapping stretches: the ramp lane is one lane
        merged: list[list[float]] = []
        for a, b in sorted(ramp):
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        self._ramp_iv = np.array(merged, dtype=np.float64).reshape(-1, 2)
        self._merge_iv = np.array([(r.start, r.end) for r in self.on_ramps], dtype=np.float64).reshape(-1, 2)
        self._diverge_iv = np.array([(r.start, r.end) for r in self.off_ramps], dtype=np.float64).reshape(-1, 2)
        self._exit_x = np.array([r.exit_x for r in self.off_ramps], dtype=np.float64)
        # whether a ramp lane exists, and the lanes with it: read several
        # times a step, so plain attributes of the layout as built (from
        # stop 51; properties before, derived from the same fields)
        self.has_ramp_lane: bool = len(self._ramp_iv) > 0
        self.total_lanes: int = self.n_lanes + (1 if self.has_ramp_lane else 0)
        if self.periodic:
            # a ring: every stretch must lie inside [0, length) so that no lane
            # feature straddles the seam (place the seam on a plain stretch)
            for a, b in list(self._ramp_iv) + [(o.x - o.length / 2, o.x + o.length / 2) for o in self.obstacles]:
                if a < 0 or b >= self.length:
                    raise ValueError(
                        f"on a ring road every ramp and obstacle must lie inside [0, {self.length}); "
                        f"got a stretch [{a}, {b}]: move the seam (x = 0) to a plain stretch"
                    )
            if np.isfinite(self.lane_ends).any():
                raise ValueError("a ring road cannot have lane drops (lane_ends must all be inf)")
        obs = sorted(self.obstacles, key=lambda o: (o.lane, o.x))
        self._ob_lane = np.array([o.lane for o in obs], dtype=np.int64)
        self._ob_lo = np.array([o.x - o.length / 2 for o in obs], dtype=np.float64)
        self._ob_hi = np.array([o.x + o.length / 2 for o in obs], dtype=np.float64)

    # ------------------------------------------------------------------ lanes
    @property
    def ramp_lane(self) -> int:
        """Index of the ramp lane (right of the main lanes)."""
        return self.n_lanes

    def exit_lookahead(self, lane, base: float, per_lane: float) -> np.ndarray:
        """Distance before its exit at which a vehicle in ``lane`` heads for
        the ramp lane: ``base`` for the last lane change (from the outermost
        main lane) plus ``per_lane`` for every further lane it has to cross
        (a vehicle further left needs more road for the same manoeuvre)."""
        extra = np.maximum(self.ramp_lane - np.asarray(lane) - 1, 0)
        return base + per_lane * extra

    def lane_center(self, lane) -> np.ndarray:
        return np.asarray(lane, dtype=np.float64) * self.lane_width

    def lane_of(self, y) -> np.ndarray:
        """Lane index whose centre is nearest to lateral position ``y``."""
        return uclip(np.rint(np.asarray(y) / self.lane_width), 0, self.total_lanes - 1).astype(np.int64)

    def lane_of_rows(self, y: np.ndarray) -> np.ndarray:
        """:meth:`lane_of` of a 1-D float64 array of finite positions (a
        state's ``cy``), in one compiled call (:func:`icv_envs.sim._kernels.physics.lane_of_rows`)."""
        return lane_of_rows(y, float(self.lane_width), int(self.total_lanes))

    # ---------------------------------------------------------------- ring
    def mod(self, x) -> np.ndarray:
        """Position folded onto the road: ``x mod length`` on a ring, ``x`` otherwise."""
        x = np.asarray(x, dtype=np.float64)
        return np.mod(x, self.length) if self.periodic else x

    def wrap(self, d) -> np.ndarray:
        """Signed longitudinal difference: the shortest way round on a ring
        (in ``[-length/2, length/2)``), ``d`` itself otherwise."""
        d = np.asarray(d, dtype=np.float64)
        if not self.periodic:
            return d
        half = 0.5 * self.length
        return np.mod(d + half, self.length) - half

    def exit_ahead(self, exit_index, x) -> np.ndarray:
        """Distance from ``x`` to the start of the diverge segment of exit
        ``exit_index``, measured forwards. Inside the diverge segment it is in
        ``[-(diverge length), 0]``; on a straight road it is more negative once
        the exit has been passed, on a ring it counts to the next time round."""
        e = np.asarray(exit_index, dtype=np.int64)
        ds, de = self._diverge_iv[e, 0], self._diverge_iv[e, 1]
        x = np.asarray(x, dtype=np.float64)
        if not self.periodic:
            return ds - x
        return np.mod(de - x, self.length) - (de - ds)

    def available(self, lane, x) -> np.ndarray:
        """Whether ``lane`` is drivable at ``x`` (vectorised, broadcasting;
        compiled: :func:`icv_envs.sim._kernels.lanes_available`)."""
        lane, x = self._lane_x(lane, x)
        x = self.mod(x)
        out = lanes_available(np.ascontiguousarray(lane).reshape(-1), np.ascontiguousarray(x).reshape(-1),
                              self.n_lanes, self.lane_ends, self._ob_lane, self._ob_lo, self._ob_hi, self._ramp_iv)
        return out.reshape(lane.shape)

    def interval_end(self, lane, x) -> np.ndarray:
        """Distance-free position where the drivable stretch of ``lane``
        containing (or following) ``x`` ends: the next lane end, obstacle rear
        or ramp end ahead of ``x`` (``inf`` if none). Vectorised."""
        lane, x = self._lane_x(lane, x)
        if self.periodic:
            xm = self.mod(x)
            return self._interval_end(lane, xm) + (x - xm)
        return self._interval_end(lane, x)

    @staticmethod
    def _lane_x(lane, x) -> tuple[np.ndarray, np.ndarray]:
        """``lane`` (int64) and ``x`` (float64) as arrays of one shape (broadcast only when the shapes differ)."""
        lane, x = np.asarray(lane, dtype=np.int64), np.asarray(x, dtype=np.float64)
        if lane.shape != x.shape:
            lane, x = np.broadcast_arrays(lane, x)
        return lane, x

    def _interval_end(self, lane, x) -> np.ndarray:
        # compiled (icv_envs.sim._kernels.interval_ends; the numpy version is
        # kept in tests/test_kernels.py as its reference)
        shape = lane.shape
        out = interval_ends(np.ascontiguousarray(lane, dtype=np.int64).reshape(-1),
                            np.ascontiguousarray(x, dtype=np.float64).reshape(-1), self.n_lanes, self.lane_ends,
                            self._ob_lane, self._ob_lo, self._ob_hi, self._ramp_iv)
        return out.reshape(shape)

    def in_merge(self, x) -> np.ndarray:
        """Inside an on-ramp merge segment (ramp lane -> rightmost main lane allowed)."""
        x = self.mod(x)
        if not len(self._merge_iv):
            return np.zeros(x.shape, dtype=bool)
        return ((x[..., None] >= self._merge_iv[:, 0]) & (x[..., None] <= self._merge_iv[:, 1])).any(axis=-1)

    def in_diverge(self, x) -> np.ndarray:
        """Inside an off-ramp diverge segment (rightmost main lane -> ramp lane allowed)."""
        x = self.mod(x)
        if not len(self._diverge_iv):
            return np.zeros(x.shape, dtype=bool)
        return ((x[..., None] >= self._diverge_iv[:, 0]) & (x[..., None] <= self._diverge_iv[:, 1])).any(axis=-1)

    def drivable_main_lanes(self, x0: float, x1: float) -> list[int]:
        """Main lanes drivable over the whole window ``[x0, x1]`` (the lanes a
        formation spanning that window may use; paper Sec. 3.3-3.4: a lane
        that closes ahead, by a lane drop or a blocking obstacle, is removed
        from the formation, which then re-forms on the remaining lanes)."""
        x0, x1 = float(x0), float(x1)
        if self.periodic:
            span = min(max(x1 - x0, 0.0), self.length)
            a = float(np.mod(x0, self.length))
            pieces = [(a, a + span)] if a + span <= self.length else [(a, self.length), (0.0, a + span - self.length)]
        else:
            x0 = max(x0, 0.0)
            pieces = [(x0, max(x1, x0))]
        ok = np.ones(self.n_lanes, dtype=bool)
        for p0, p1 in pieces:
            ok &= self.lane_ends > p1
            if len(self._ob_lane):
                hit = (self._ob_hi >= p0) & (self._ob_lo <= p1)
                ok[self._ob_lane[hit]] = False
        return [int(l) for l in np.flatnonzero(ok)]

    def exit_position(self, exit_index) -> np.ndarray:
        return self._exit_x[np.asarray(exit_index, dtype=np.int64)]

    def diverge_start(self, exit_index) -> np.ndarray:
        return self._diverge_iv[np.asarray(exit_index, dtype=np.int64), 0]

    def diverge_end(self, exit_index) -> np.ndarray:
        return self._diverge_iv[np.asarray(exit_index, dtype=np.int64), 1]

    @property
    def n_exits(self) -> int:
        return len(self.off_ramps)

    # -------------------------------------------------------------- rendering
    def to_network(self):
        """A highway-env :class:`RoadNetwork` drawing this layout.

        The road is cut at every lane drop and ramp boundary (obstacles are
        drawn as highway-env obstacles, not as cuts); each
        piece holds the lanes that exist there, with continuous outer lines
        and striped lines between lanes. Used for rendering only: the
        simulation core never queries it in the hot loop."""
        from highway_env.road.lane import LineType, StraightLane
        from highway_env.road.road import RoadNetwork

        net = RoadNetwork()
        cuts = {0.0, float(self.length)}
        cuts.update(float(e) for e in self.lane_ends if np.isfinite(e) and 0 < e < self.length)
        for iv in (self._ramp_iv, self._merge_iv, self._diverge_iv):
            for a, b in iv:
                cuts.update(float(np.clip(v, 0, self.length)) for v in (a, b))
        cuts = sorted(cuts)
        C, S, N = LineType.CONTINUOUS_LINE, LineType.STRIPED, LineType.NONE
        w = self.lane_width
        for k, (a, b) in enumerate(zip(cuts[:-1], cuts[1:])):
            if b - a < 1e-6:
                continue
            mid = 0.5 * (a + b)
            present = [lane for lane in range(self.n_lanes) if mid < self.lane_ends[lane]]
            ramp_here = self.has_ramp_lane and bool(self.available(self.n_lanes, mid))
            if ramp_here:
                present.append(self.n_lanes)
            # the ramp is fenced off from the main road by a continuous line
            # except along merge and diverge segments
            open_ramp = bool(self.in_merge(mid) or self.in_diverge(mid))
            for j, lane in enumerate(present):
                left = C if j == 0 else N
                right = C if j == len(present) - 1 else S
                if ramp_here and j == len(present) - 2 and not open_ramp:
                    right = C
                net.add_lane(
                    f"s{k}",
                    f"s{k + 1}",
                    StraightLane([a, lane * w], [b, lane * w], line_types=(left, right), width=w),
                )
        return net
