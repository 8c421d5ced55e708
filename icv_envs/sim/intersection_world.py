"""Vectorised 2-D simulation core of the multi-lane unsignalized intersection.

Paper Sec. 4-5 and Table 2 (Xu et al., IET ITS 2021), docs/intersection.md.  Knows
nothing about Gymnasium, PettingZoo or the coordination methods: the
environment :mod:`icv_envs.envs.intersection` and the policies in
:mod:`icv_envs.policies.platoon_expert` / :mod:`icv_envs.policies.fcfs` are
layers over it.

Geometry (legs, lanes, paths, zones): :mod:`icv_envs.sim.intersection_layout`.

Route coordinates
-----------------
Every vehicle has one route: the approach lane of its leg, then the path
``(movement, lane)`` through the box, then the departure lane.  ``s`` is the
arc length of the body centre along that route from the stop line (negative
before it).  ``X = L / 2 - s`` (``L`` the path length) is the distance to the
centre used for the virtual platoon's *spacing* (the convention of
:func:`~icv_envs.platoon.conflicts.required_layer_gap`: exact for straight
movements, the path midpoint counts as the centre of a turn).  ``dist =
box_half - s`` is the literal distance to the centre along the leg's axis on
the approach (continued along the path after the stop line); the zones
(approaching ``dist > R2``, adjusting ``R2 >= dist > R1``, coordinating
``dist <= R1``) and the *order* of the virtual platoon's nodes use it, so
that the order of two vehicles in one approach lane is their physical order
(``X`` can invert it: a right turn's path is 16 m shorter than a straight
one's, so a right-turner 8 m behind a straight vehicle in the shared middle
lane has the smaller ``X``).  Vehicles are generated at ``dist = R3``.

Before a vehicle enters the box its path is the one of its *expected* lane
(``tlane``, set by the coordination layer); the lane it actually enters from
is locked in ``plane`` when its centre crosses the stop line.

Events, checked every substep: entering the box; leaving it (the exit leg is
recorded, a wrong one is counted); *clearing* it (whole body out, the
throughput counts these); removal at ``departure_length`` past the box;
collisions (exact rectangle test, sweep and prune run twice: along ``x`` for
the east-west legs and along ``y`` for the north-south legs, the box region
in both); leaving the drivable surface (the centre more than 0.5 m outside
the approach lanes of its leg or the departure lanes of its exit) counts as
a crash; a vehicle driving back out of its approach road is removed as
``left_road``.
"""

from __future__ import annotations

import math

import numpy as np

from icv_envs.platoon.geometry import N_LANES
from icv_envs.sim.intersection_layout import DEFAULT_BOX_HALF, IntersectionLayout, validate_radii
from icv_envs.sim.intersection_metrics import (
    JAM_SECONDS,
    QUEUE_GAP,
    STOPPED_SPEED,
    ConflictAreas,
    FaultStats,
    JamWatch,
    MotionStats,
    PetStats,
    collision_fault,
)
from icv_envs.sim._kernels.frames import intersection_frames
from icv_envs.sim._kernels.intersection import box_collision_pairs, route_rows, rows_of_ids
from icv_envs._ufuncs import clip as uclip, flatnonzero

__all__ = [
    "IntersectionLayout",
    "IntersectionWorld",
    "Fleet",
    "RouteState",
    "StepEvents",
    "DEFAULT_BOX_HALF",
    "validate_radii",
]

# outward unit vector of each leg (from the centre towards that leg), as in platoon.geometry
_OUT = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, -1.0], [-1.0, 0.0]])
_OFFROAD_MARGIN = 0.5


class StepEvents:
    """What happened during one policy step (vehicle ids)."""

    __slots__ = ("crashed", "removed", "left_road", "cleared", "collision_pairs", "wrong_exit")

    def __init__(self) -> None:
        self.crashed: set[int] = set()
        self.removed: set[int] = set()
        self.left_road: set[int] = set()
        self.cleared: set[int] = set()
        self.wrong_exit: set[int] = set()
        self.collision_pairs: list[tuple[int, int]] = []


class Fleet:
    """Structure-of-arrays vehicle state, rows sorted by ``vid``.

    Fields are declared with :meth:`define` (the coordination layers declare
    their own per-vehicle memory the same way), so adding and removing
    vehicles keeps every array aligned.
    """

    def __init__(self) -> None:
        self._fields: dict[str, tuple[type, object]] = {}
        self.next_vid = 0
        self.vid = np.zeros(0, dtype=np.int64)
        self._row_of: np.ndarray | None = None  # vid -> row table (-1: absent), built on demand, dropped when vid changes

    def define(self, name: str, dtype, default) -> None:
        if name in self._fields:
            return
        self._fields[name] = (dtype, default)
        setattr(self, name, np.full(len(self.vid), default, dtype=dtype))

    @property
    def n(self) -> int:
        return len(self.vid)

    def add(self, k: int, **values) -> np.ndarray:
        """Append ``k`` vehicles with new ids; each field takes its value from
        ``values`` (a scalar, or ``k`` values) or its default. Unknown fields
        raise before anything is added (from stop 41; before, after the
        fields were extended). Each field's new rows are filled by one
        assignment (the scalar or the ``k`` values cast to the field's dtype,
        as ``np.asarray(v, dtype)`` broadcast did, at a third of its cost: a
        spawn extends about forty fields)."""
        unknown = set(values) - set(self._fields)
        if unknown:
            raise ValueError(f"unknown vehicle fields {sorted(unknown)}")
        ids = np.arange(self.next_vid, self.next_vid + k, dtype=np.int64)
        self.next_vid += k
        self.vid = np.concatenate((self.vid, ids))
        self._row_of = None
        for name, (dtype, default) in self._fields.items():
            new = np.empty(k, dtype=dtype)
            new[...] = values.get(name, default)
            setattr(self, name, np.concatenate((getattr(self, name), new)))
        return ids

    def remove(self, mask) -> None:
        keep = ~np.asarray(mask, dtype=bool)
        self.vid = self.vid[keep]
        self._row_of = None
        for name in self._fields:
            setattr(self, name, getattr(self, name)[keep])

    def rows(self, vids) -> np.ndarray:
        """Rows of ``vids`` (-1 for vehicles not present). The coordination
        layer asks this for a handful of ids at a time, about forty times
        per step: one compiled lookup in an id -> row table rebuilt when the
        fleet changes (``add``/``remove``)."""
        vids = np.asarray(vids, dtype=np.int64)
        if self._row_of is None:
            t = np.full(self.next_vid, -1, dtype=np.int64)
            t[self.vid] = np.arange(len(self.vid))
            self._row_of = t
        if vids.ndim == 1:
            return rows_of_ids(self._row_of, vids)
        return rows_of_ids(self._row_of, vids.ravel()).reshape(vids.shape)


class RouteState:
    """Derived per-vehicle route quantities of the current state (cached)."""

    __slots__ = ("cx", "cy", "u", "lat_leg", "lane", "pid", "s", "lat", "X", "dist", "phase", "L")

    def __init__(self, **kw) -> None:
        for k, v in kw.items():
            setattr(self, k, v)


class IntersectionWorld:
    """All vehicles of the intersection, advanced together with array operations.

    Args:
        layout: an :class:`IntersectionLayout`.
        dt: simulation step (0.04 s, Table 2).
        wheelbase: bicycle model wheelbase (2.8 m).
        v_max: speed limit of the model (20 m/s, Table 2).
        v_free: free-flow speed used for delays (10 m/s, the virtual
            leader's desired speed).
    """

    def __init__(self, layout: IntersectionLayout, dt: float = 0.04, wheelbase: float = 2.8,
                 v_max: float = 20.0, v_free: float = 10.0) -> None:
        self.layout = layout
        self.dt = float(dt)
        self.wheelbase = float(wheelbase)
        self.v_max = float(v_max)
        self.v_free = float(v_free)
        self.time = 0.0
        self.step_count = 0
        f = self.fleet = Fleet()
        for name in ("x", "y", "heading", "speed", "accel", "steer", "spawn_time", "spawn_s", "enter_time"):
            f.define(name, np.float64, 0.0)
        f.define("length", np.float64, 5.0)
        f.define("width", np.float64, 2.0)
        for name in ("leg", "mv", "tlane"):
            f.define(name, np.int64, 0)
        f.define("plane", np.int64, -1)
        f.define("exit_leg", np.int64, -1)
        for name in ("entered", "departed", "cleared", "crashed", "wrong_exit"):
            f.define(name, bool, False)
        self._route: RouteState | None = None
        self.stats = {
            "vehicle_steps": 0,
            "speed_sum": 0.0,
            "abs_accel_sum": 0.0,
            "collisions": 0,
            "spawned": 0,
            "cleared": 0,
            "removed": 0,
            "crashed_removed": 0,
            "left_road": 0,
            "wrong_exits": 0,
            "rerouted": 0,
            "travel_time_sum": 0.0,
            "delay_sum": 0.0,
            "min_speed_in_box": math.inf,
        }
        self.collision_log: list[tuple[float, int, int]] = []
        # run metrics (icv_envs.sim.intersection_metrics)
        self.motion = MotionStats()
        if not hasattr(layout, "_conflict_areas"):
            layout._conflict_areas = ConflictAreas(layout)
        self.pet = PetStats(layout._conflict_areas)
        self.jams = JamWatch()
        self.faults = FaultStats()
        self._expert_vids: set[int] | None = None  # set_expert_driven; None: all expert-driven

    def reset_metrics(self) -> None:
        """Restart the motion, PET, jam and fault accumulators (after a warm-up)."""
        self.motion.reset()
        self.pet.reset()
        self.jams.reset()
        self.faults.reset()

    def set_expert_driven(self, vids, expert_mask) -> None:
        """Which vehicles the expert drives in the coming step (the others
        follow a given, e.g. learned, action), for the at-fault attribution
        of collisions (:class:`~icv_envs.sim.intersection_metrics.FaultStats`)."""
        vids = np.asarray(vids)
        em = np.asarray(expert_mask, dtype=bool)
        self._expert_vids = None if np.count_nonzero(em) == len(em) else set(vids[em].tolist())

    # the highway env's code calls the fleet "traffic"
    @property
    def traffic(self) -> Fleet:
        return self.fleet

    # ----------------------------------------------------------------- spawn
    def spawn(self, leg: int, lane: int, movement: int, speed: float, s: float, tlane: int,
              length: float = 5.0, width: float = 2.0) -> int:
        """Add one vehicle on approach ``lane`` of ``leg`` at route coordinate ``s`` (< 0)."""
        lay = self.layout
        d0 = lay.app_dir[leg]
        centre = lay.box_half * _OUT[leg] + (lane + 0.5) * lay.lane_width * lay.app_right[leg] + s * d0
        h = math.atan2(d0[1], d0[0])
        rear = centre - 0.5 * self.wheelbase * d0
        vid = self.fleet.add(1, x=rear[0], y=rear[1], heading=h, speed=speed, leg=leg, mv=movement,
                             tlane=tlane, spawn_time=self.time, spawn_s=s, length=length, width=width)
        self.stats["spawned"] += 1
        self._route = None
        return int(vid[0])

    # ---------------------------------------------------------------- queries
    def centers(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.fleet
        h = 0.5 * self.wheelbase
        return f.x + h * np.cos(f.heading), f.y + h * np.sin(f.heading)

    def route(self) -> RouteState:
        """Route coordinates of the current state (cached until the next change)."""
        if self._route is not None:
            return self._route
        f = self.fleet
        lay = self.layout
        # compiled (icv_envs.sim._kernels.intersection.route_rows; the array
        # code it replaced is its reference in tests/test_intersection_frames.py)
        Fl, In = route_rows(
            f.x, f.y, f.heading, 0.5 * self.wheelbase, f.leg, f.mv, f.plane, f.tlane, f.entered, f.departed, _OUT,
            lay.app_dir, lay.app_right, lay.box_half, lay.lane_width, N_LANES, lay.P0, lay.D0, lay.P1, lay.D1, lay.L,
            lay.arc, lay.C, lay.TH0, lay.R, lay.SGN)
        cx, cy, u, lat_leg, s, lat, X, dist, L = Fl  # (row views)
        lane, pid, phase = In
        self._route = RouteState(cx=cx, cy=cy, u=u, lat_leg=lat_leg, lane=lane, pid=pid, s=s, lat=lat, X=X, dist=dist,
                                 phase=phase, L=L)
        return self._route

    def route_is(self, rs) -> bool:
        """Is ``rs`` the current route state (not invalidated since)?"""
        return self._route is rs

    def invalidate(self) -> None:
        self._route = None

    # --------------------------------------------------------------- dynamics
    def substep(self, accel: np.ndarray, steer: np.ndarray, events: StepEvents) -> None:
        """One integration step of ``dt`` for all vehicles, then the events of
        the module docstring (:meth:`substeps` with one frame)."""
        self.substeps(accel, steer, 1, events)

    def substeps(self, accel: np.ndarray, steer: np.ndarray, n: int, events: StepEvents) -> int:
        """Up to ``n`` integration steps with the same controls, each with
        the events of the module docstring, the run metrics (motion, PET,
        jam watch) and the collision test, in one compiled call
        (:func:`icv_envs.sim._kernels.intersection_frames`) that stops after
        the first frame in which something happens that is handled here (a
        wrong exit, a vehicle clearing the box, a crash, a removal, a
        vehicle standing longer than the jam watch's limit). Returns how
        many steps ran; the state, statistics, metrics and events are those
        of as many single steps, bit for bit."""
        f = self.fleet
        lay = self.layout
        n = int(n)
        if n < 1:
            raise ValueError(f"n = {n}; allowed: an integer >= 1")
        if not f.n:
            self.time += self.dt
            self.step_count += 1
            self._route = None
            return 1
        accel = np.ascontiguousarray(accel, dtype=np.float64)
        steer = np.ascontiguousarray(steer, dtype=np.float64)
        if accel.shape != (f.n,) or steer.shape != (f.n,):
            raise ValueError(f"accel and steer must have shape ({f.n},) (one per vehicle); got {accel.shape} and "
                             f"{steer.shape}")
        top = int(f.vid[-1]) + 1  # (rows sorted by id: Fleet.add appends new ids, remove keeps the order)
        self.motion.reserve(top)
        lo, hi, occ, path, busy = self.pet.tables(top)
        m = self.motion
        stt = self.stats
        vs, ssum, rea, com, sst = m.totals()
        (ran, event, S, times, acc, counts, trans, busy, B, i, j, jam_rows) = intersection_frames(
            n, f.x, f.y, f.heading, f.speed, accel, steer, f.crashed, self.dt, self.wheelbase, self.v_max, self.time,
            f.vid, f.leg, f.mv, f.length, f.width, f.tlane, f.entered, f.departed, f.cleared, f.wrong_exit,
            f.exit_leg, f.plane, f.enter_time, _OUT, lay.app_dir, lay.app_right, lay.dep_right, lay.exit_of,
            lay.box_half, lay.lane_width, N_LANES, _OFFROAD_MARGIN, -(lay.R3 - lay.box_half + 50.0),
            lay.departure_length, lay.P0, lay.D0, lay.P1, lay.D1, lay.L, lay.arc, lay.C, lay.TH0, lay.R, lay.SGN,
            STOPPED_SPEED, *m.moments(), lo, hi, occ, path, busy, self.jams.standing_times(top),
            JAM_SECONDS, vs, ssum, rea, com, sst, float(stt["speed_sum"]), float(stt["abs_accel_sum"]),
            float(stt["min_speed_in_box"]))
        # (the state and the last frame's events as row views of two arrays)
        f.x, f.y, f.heading, f.speed, f.accel, f.steer, cx, cy, u, lat_leg = S
        crash, new_wrong, clear_now, removed, left = B
        nv = f.n
        # the clock, the motion totals and the run statistics, added frame by
        # frame inside as single steps add them (the same additions of the
        # same doubles, in order), and the PET events frame by frame
        ssum, rea, com, ss, sa, mn = acc.tolist()
        vs, sst = counts.tolist()
        m.set_totals(vs, ssum, rea, com, sst)
        times = times.tolist()
        t = times[-1]
        self.time = t
        self.step_count += ran
        stt["vehicle_steps"] += nv * ran
        stt["speed_sum"], stt["abs_accel_sum"], stt["min_speed_in_box"] = ss, sa, mn
        if len(trans):
            # each frame's events (rows in frame order) at its time; a frame
            # without events changes nothing there (from stop 47 it is not
            # called: every call sets the same ``busy``)
            tf = trans[:, 0].tolist()
            n_t = len(tf)
            q = 0
            while q < n_t:
                fr = tf[q]
                q1 = q + 1
                while q1 < n_t and tf[q1] == fr:
                    q1 += 1
                self.pet.apply(times[fr], busy, trans[q:q1, 1:])
                q = q1
        else:  # no PET events: the occupancy only
            self.pet.apply(t, busy, trans[:, 1:])
        self._route = None
        if not event:
            return int(ran)
        # what the last frame's events mean
        if new_wrong.any():
            stt["wrong_exits"] += int(new_wrong.sum())
            events.wrong_exit.update(int(v) for v in f.vid[new_wrong])
        if clear_now.any():
            kc = flatnonzero(clear_now)
            good = kc[~f.wrong_exit[kc]]
            stt["cleared"] += len(good)
            if len(good):
                pid = 3 * f.mv[good] + np.maximum(f.plane[good], 0)
                dist = -f.spawn_s[good] + lay.L[pid] + 0.5 * f.length[good]
                tt = self.time - f.spawn_time[good]
                stt["travel_time_sum"] += float(tt.sum())
                stt["delay_sum"] += float((tt - dist / self.v_free).sum())
            events.cleared.update(int(v) for v in f.vid[kc])
        if len(jam_rows):
            self.jams.judge(self.time, self.dt, f.vid, jam_rows, lambda rows: self._in_queue(rows, u, lat_leg),
                            dist=lay.box_half - u)
        # collisions
        if len(i):
            crash[i] = True
            crash[j] = True
            ev = self._expert_vids
            for ra, rb in zip(i.tolist(), j.tolist()):
                a_, b_ = int(f.vid[ra]), int(f.vid[rb])
                events.collision_pairs.append((a_, b_))
                self.collision_log.append((round(self.time, 6), a_, b_))
                if not (f.crashed[ra] and f.crashed[rb]):  # a new collision of this pair
                    kind, k = collision_fault(cx[ra], cy[ra], f.heading[ra], f.speed[ra],
                                              cx[rb], cy[rb], f.heading[rb], f.speed[rb])
                    guilty = (a_, b_)[k]
                    self.faults.record(kind, ev is None or guilty in ev)
        new_crash = crash & ~f.crashed
        if new_crash.any():
            f.crashed = f.crashed | new_crash
            events.crashed.update(int(v) for v in f.vid[new_crash])
            stt["collisions"] += int(new_crash.sum())
        gone = (removed | left) & ~f.crashed
        if gone.any():
            events.removed.update(int(v) for v in f.vid[removed & gone])
            events.left_road.update(int(v) for v in f.vid[left & gone])
            stt["removed"] += int((removed & gone).sum())
            stt["left_road"] += int((left & gone).sum())
            f.remove(gone)
        return int(ran)

    def _in_queue(self, rows, u, lat_leg) -> np.ndarray:
        """Is each of ``rows`` in a queue at the box (the :class:`~icv_envs.sim.intersection_metrics.JamWatch`
        rule): following the vehicles ahead in its approach lane through bumper gaps below ``QUEUE_GAP``,
        does one reach the stop line (the first vehicle within ``QUEUE_GAP`` of it) or a moving vehicle
        (the front of a discharging queue)?  Vehicles in or past the box: False."""
        f = self.fleet
        w = self.layout.lane_width
        appr = flatnonzero(~f.entered)
        out = np.zeros(len(rows), dtype=bool)
        if not len(appr):
            return out
        lane = uclip(np.floor(lat_leg[appr] / w), 0, N_LANES - 1).astype(np.int64)
        key = 3 * f.leg[appr] + lane
        ua = u[appr]
        o = np.lexsort((-ua, key))
        a, key, ua = appr[o], key[o], ua[o]
        ln = f.length[a]
        first = np.ones(len(a), dtype=bool)
        first[1:] = key[1:] != key[:-1]
        gap = np.empty(len(a))
        gap[first] = -ua[first] - 0.5 * ln[first]
        nf = flatnonzero(~first)
        gap[nf] = ua[nf - 1] - ua[nf] - 0.5 * (ln[nf - 1] + ln[nf])
        linked = gap < QUEUE_GAP
        # an anchor for the vehicle behind: the stop line (first vehicle of the lane) or a moving leader
        moving = f.speed[a] >= STOPPED_SPEED
        seed = first.copy()
        seed[nf] = moving[nf - 1]
        # runs of consecutive linked vehicles of one lane; queued from the first anchor of the run backwards
        anchor = seed & linked
        c = np.cumsum(anchor)
        start = np.maximum.accumulate(np.where(~linked | first, np.arange(len(a)), 0))
        queued = linked & ((c - (c[start] - anchor[start])) > 0)
        inq = np.zeros(f.n, dtype=bool)
        inq[a] = queued
        return inq[np.asarray(rows, dtype=np.int64)]

    def collision_pairs(self, cx=None, cy=None) -> tuple[np.ndarray, np.ndarray]:
        """Colliding row pairs: sweep and prune along ``x`` over the east-west
        legs and the box region, along ``y`` over the north-south legs and
        the box region; exact rectangle tests decide (compiled whole:
        :func:`icv_envs.sim._kernels.intersection.box_collision_pairs`)."""
        f = self.fleet
        if cx is None:
            cx, cy = self.centers()
        return box_collision_pairs(cx, cy, f.heading, f.length, f.width, self.layout.box_half)

    def reroute(self, rows, movements) -> None:
        """The drivers of ``rows`` (before the box) take ``movements`` (of their
        own leg) instead of their planned ones: a driver who reaches the stop
        line in a lane that does not serve its turn takes a turn that lane
        serves (counted in ``stats["rerouted"]``; the vehicle then leaves by
        the exit of its new movement, which is not a wrong exit)."""
        f = self.fleet
        rows = np.asarray(rows, dtype=np.int64)
        movements = np.asarray(movements, dtype=np.int64)
        if not len(rows):
            return
        if np.any(f.entered[rows]) or np.any(self.layout.leg_of[movements] != f.leg[rows]):
            raise ValueError("reroute: only vehicles before the box, to a movement of their own leg")
        f.mv[rows] = movements
        self.stats["rerouted"] += len(rows)
        self._route = None

    def remove_crashed_vehicles(self) -> np.ndarray:
        f = self.fleet
        ids = f.vid[f.crashed]
        if len(ids):
            f.remove(f.crashed)
            self.stats["crashed_removed"] += len(ids)
            self._route = None
        return ids
