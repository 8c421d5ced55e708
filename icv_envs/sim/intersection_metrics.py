"""Run metrics of the intersection: what vehicles do, surrogate safety, jams.

Accumulated by :class:`icv_envs.sim.intersection_world.IntersectionWorld`
every integration step (``dt`` = 0.04 s); the environment's ``metrics()``
reports the summaries.  The motion keys are the same as the highway's
(``mean_speed, speed_fluctuation, speed_std, stopped_share,
commanded_abs_accel``) and are defined the same way.

Motion (:class:`MotionStats`, every vehicle present, every substep)
    * ``speed_fluctuation``: mean ``|dv/dt|`` of the REALISED speed,
      ``dv = v(t + dt) - v(t)`` after the model's limits ``0 <= v <= v_max``:
      what the vehicles do (the paper's Fig. 14 b caption: "average
      acceleration").  A vehicle held at 0 m/s while braking is commanded
      contributes 0.
    * ``commanded_abs_accel``: mean ``|a|`` of the commanded acceleration (the
      figure reported as ``speed_fluctuation`` before); a diagnostic.
    * ``speed_std``: per-vehicle standard deviation of speed over its time in
      the simulation, averaged over vehicles with >= 2 samples.
    * ``stopped_share``: share of vehicle-substeps with ``v <``
      :data:`STOPPED_SPEED`.

Post-encroachment time (:class:`PetStats`)
    Conflict areas are derived from the layout, one per pair of lane paths
    (movement, approach lane) of two CONFLICTING movements that meet:

    * a crossing point strictly inside the box (from
      :attr:`icv_envs.platoon.conflicts.ConflictModel.crossings`), crossing
      angle ``theta``: the area is the part of path A on which A's body can
      overlap a vehicle of width ``W`` centred on path B,
      ``|s_A - s_A^c| < L_A / 2 + h_A`` with ``h_A = W / 2 (1 + |cos theta|) /
      |sin theta|`` (exact for straight paths and bodies on their paths; 3.5 m
      for a 5 x 2 m car at a right angle);
    * a merge point (two paths ending in the same departure lane): the exit
      point, ``h = 0`` (the body passing over the point).

    Diverging pairs (same approach lane) and vehicles on the same path are
    car following, not encroachment, and are left out.  A vehicle occupies an
    area while its route coordinate satisfies the inequality above; PET is
    sampled every time a vehicle ENTERS an area: ``t_enter - t_exit`` of the
    last vehicle of the other path to leave it (so a crossing pair gives one
    sample, whichever goes first).  If a vehicle of the other path is still
    inside when it enters, the sample is taken when that one leaves and is
    negative (the two occupied the area together: a near miss or a
    collision).  Reported: ``pet_min``, ``pet_p05`` (5th percentile of all
    samples of the run), ``pet_samples``; ``None`` without samples.  Times
    are substep times (0.04 s resolution).

Jams (:class:`JamWatch`)
    A vehicle is *jammed* when it has been stopped (``v <``
    :data:`STOPPED_SPEED`) for more than :data:`JAM_SECONDS` (10 s)
    continuously while NOT in a queue at the box.  Before the stop line a
    vehicle is in the queue if, following the vehicles ahead of it in its
    approach lane through bumper gaps below :data:`QUEUE_GAP` (10 m), one
    reaches either the stop line (the first vehicle of the lane within
    :data:`QUEUE_GAP` of it) or a *moving* vehicle (at least
    :data:`STOPPED_SPEED`): the front of a discharging queue, whose start-up
    wave has not reached this vehicle yet.  The second anchor matters for
    long queues: once the front moves off, its vehicles are soon more than
    10 m apart while the tail still stands (fcfs, 5000 veh/h, seed 2, t =
    422.8 s: the head of a 13-vehicle queue 13.7 m from the line at 5.7
    m/s, three vehicles 67-81 m out still standing 2 m behind their moving
    leaders; fcfs-tight, seed 1, t = 277.5 s: the 27th vehicle of a 200 m
    queue whose front had started to discharge before it stopped; both
    were counted as jammed by the stop-line anchor alone).  A vehicle
    standing behind a vehicle that stands too, with no chain to the line,
    is not in a queue at the box (a hold of the controller away from the
    line).  A vehicle stopped inside the box or after it is never in a
    queue.  ``jammed`` is
    the number of distinct vehicles that were ever jammed in the run,
    ``jammed_vehicle_seconds`` the time they spent jammed; both must be 0
    for a working controller (stopping at the line to wait for one's turn is
    allowed for as long as it takes).

Collisions by fault (:class:`FaultStats`, :func:`collision_fault`)
    Every new collision pair is counted once in
    ``collisions_by_fault[kind][driver]``: ``driver`` is ``expert`` or
    ``policy`` by who drove the AT-FAULT vehicle in that step (an action
    equal to the expert's is expert-driven; the env tells the world,
    ``IntersectionWorld.set_expert_driven``).  Kinds, from the two headings
    and positions at the moment of contact:

    * rear-end (headings within 30 deg): the rear vehicle (behind along the
      mean heading) is at fault, ``struck_ahead``, unless the front one was
      moving sideways towards it faster than ``CUT_IN_SPEED`` (0.2 m/s, the
      highway's value), ``struck_from_behind`` (the front one at fault);
    * ``angle`` (crossing or head-on): at fault the vehicle closing on the
      other faster (its speed component along the line between the two
      centres), i.e. the one that drove into the other; a vehicle standing
      still is never at fault against a moving one.
"""

from __future__ import annotations

import math

import numpy as np

from icv_envs.sim._kernels import pet_transitions
from icv_envs.sim.metrics import STOPPED_SPEED, MotionStats  # one definition of the motion metrics

__all__ = ["STOPPED_SPEED", "JAM_SECONDS", "QUEUE_GAP", "MotionStats", "ConflictAreas", "PetStats", "JamWatch",
           "pet_summary", "MOTION_KEYS", "FAULT_KINDS", "FaultStats", "collision_fault"]

#: [s] stopped longer than this outside a queue at the box = jammed
JAM_SECONDS: float = 10.0
#: [m] bumper gap that still counts as "in the queue" (a stopped IDM queue keeps 1-2 m)
QUEUE_GAP: float = 10.0
#: the motion keys (shared with the highway's metrics)
MOTION_KEYS = ("mean_speed", "speed_fluctuation", "speed_std", "stopped_share", "commanded_abs_accel")
#: collision kinds of the intersection (the highway's have ``side_swipe`` and ``road`` instead of ``angle``)
FAULT_KINDS = ("struck_ahead", "struck_from_behind", "angle")
#: [m/s] lateral speed above which a front vehicle counts as cutting in (the highway's CUT_IN_SPEED)
CUT_IN_SPEED: float = 0.2
#: rear-end when the headings differ by less than this [rad]
REAR_END_ANGLE: float = math.radians(30.0)


def collision_fault(xa, ya, ha, va, xb, yb, hb, vb) -> tuple[str, int]:
    """``(kind, at_fault)`` of a collision between vehicles ``a`` (0) and
    ``b`` (1) from their centres, headings and speeds (module docstring)."""
    dx, dy = xb - xa, yb - ya
    dh = math.atan2(math.sin(hb - ha), math.cos(hb - ha))
    if abs(dh) < REAR_END_ANGLE:
        hm = ha + 0.5 * dh
        ex, ey = math.cos(hm), math.sin(hm)
        ahead_b = dx * ex + dy * ey > 0.0  # b is ahead of a
        rear, front = (0, 1) if ahead_b else (1, 0)
        xs = ((xa, ya, ha, va), (xb, yb, hb, vb))
        xf, yf, hf, vf = xs[front]
        xr, yr = xs[rear][0], xs[rear][1]
        # the front vehicle's sideways speed towards the rear one's side of its path
        nx, ny = -ey, ex
        side = math.copysign(1.0, (xr - xf) * nx + (yr - yf) * ny)
        towards = side * vf * (math.cos(hf) * nx + math.sin(hf) * ny)
        if towards > CUT_IN_SPEED:
            return "struck_from_behind", front
        return "struck_ahead", rear
    d = math.hypot(dx, dy) or 1.0
    ca = va * (math.cos(ha) * dx + math.sin(ha) * dy) / d
    cb = -vb * (math.cos(hb) * dx + math.sin(hb) * dy) / d
    return "angle", 0 if ca >= cb else 1


class FaultStats:
    """``collisions_by_fault[kind][driver]`` of the statistics window (module docstring)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.counts = {k: {"expert": 0, "policy": 0} for k in FAULT_KINDS}

    def record(self, kind: str, expert: bool) -> None:
        self.counts[kind]["expert" if expert else "policy"] += 1

    def summary(self) -> dict:
        return {"collisions_by_fault": {k: dict(v) for k, v in self.counts.items()}}


class ConflictAreas:
    """Conflict areas of the lane paths of a layout (module docstring).

    Attributes:
        n: number of areas.
        by_path: ``{pid: (area ids (k,), side (k,) 0/1, s_lo (k,), s_hi (k,))}``:
            the route-coordinate interval of each area along path ``pid``
            WITHOUT the vehicle's half length (added at run time).
    """

    def __init__(self, layout, vehicle_width: float = 2.0) -> None:
        model = layout.model
        W = float(vehicle_width)
        entries: dict[int, list] = {}
        n = 0

        def add(pid, area, side, lo, hi):
            entries.setdefault(int(pid), []).append((area, side, lo, hi))

        for (i, j), pts in sorted(model.crossings.items()):
            if not layout.conflict[i, j]:
                continue
            for x, y, si, sj, a, b in pts:
                pa, pb = 3 * i + int(a), 3 * j + int(b)
                _, _, ha = layout.route_points(np.array([pa]), np.array([si]))
                _, _, hb = layout.route_points(np.array([pb]), np.array([sj]))
                th = float(ha[0] - hb[0])
                sin, cos = abs(math.sin(th)), abs(math.cos(th))
                if sin < 1e-3:
                    continue
                h = 0.5 * W * (1.0 + cos) / sin
                add(pa, n, 0, si - h, si + h)
                add(pb, n, 1, sj - h, sj + h)
                n += 1
        # merges: two paths of conflicting movements ending in the same departure lane
        pids = sorted(3 * m + a for m, lanes in layout.lane_use.items() for a in lanes)
        for x, pa in enumerate(pids):
            for pb in pids[x + 1:]:
                i, j = pa // 3, pb // 3
                if i == j or not layout.conflict[i, j]:
                    continue
                if layout.exit_of[i] != layout.exit_of[j] or layout.dlane[pa] != layout.dlane[pb]:
                    continue
                add(pa, n, 0, layout.L[pa], layout.L[pa])
                add(pb, n, 1, layout.L[pb], layout.L[pb])
                n += 1
        self.n = n
        self.by_path = {}
        for pid, rows in entries.items():
            arr = np.array(rows, dtype=np.float64)
            self.by_path[pid] = (arr[:, 0].astype(np.int64), arr[:, 1].astype(np.int64), arr[:, 2], arr[:, 3])


class PetStats:
    """Post-encroachment times at the conflict areas (module docstring)."""

    def __init__(self, areas: ConflictAreas) -> None:
        self.areas = areas
        P = max(areas.by_path) + 1 if areas.by_path else 1
        K = max((len(e[0]) for e in areas.by_path.values()), default=1)
        self._ids = np.zeros((P, K), dtype=np.int64)
        self._side = np.zeros((P, K), dtype=np.int64)
        self._lo = np.full((P, K), np.inf)
        self._hi = np.full((P, K), -np.inf)
        for pid, (ids, side, lo, hi) in areas.by_path.items():
            k = len(ids)
            self._ids[pid, :k], self._side[pid, :k], self._lo[pid, :k], self._hi[pid, :k] = ids, side, lo, hi
        self._K = K
        self.reset()

    def reset(self) -> None:
        A = self.areas.n
        self.last_exit = np.full((A, 2), np.nan)  # time the last vehicle of each side left
        self.inside = np.zeros((A, 2), dtype=np.int64)  # vehicles of each side inside now
        self.pending: dict[tuple[int, int], list[float]] = {}  # (area, side) -> entry times waiting for the other side
        self._occ = np.zeros((0, self._K), dtype=bool)  # per vehicle id: occupied slots of its path's areas
        self._pid = np.zeros(0, dtype=np.int64)  # per vehicle id: the path those slots belong to
        self._busy = np.zeros(0, dtype=np.int64)  # ids with an occupied slot, sorted
        self.samples: list[float] = []

    def record(self, t: float, vid, pid, s, length) -> None:
        """Occupancy update at time ``t`` for vehicles ``vid`` on paths ``pid``
        at route coordinate ``s`` (listing the vehicles near the box is
        enough: a vehicle not listed has left every area)."""
        vid = np.asarray(vid, dtype=np.int64)
        pid = np.asarray(pid, dtype=np.int64)
        self._fit(vid)
        # compiled (icv_envs.sim._kernels.pet_transitions): which slots were
        # left and entered, in increasing (id, slot) order, as the array code
        # over the candidate rows did; the PET events in Python
        left, entered, busy = pet_transitions(
            vid, pid, np.asarray(s, dtype=np.float64), np.asarray(length, dtype=np.float64), self._lo, self._hi,
            self._occ, self._pid, self._busy)
        kind = np.concatenate([np.zeros(len(left), dtype=np.int64), np.ones(len(entered), dtype=np.int64)])
        self.apply(t, busy, np.column_stack([kind, np.concatenate([left, entered])]))

    def tables(self, top: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(lo, hi, occ, path, busy)`` for the compiled frames
        (:func:`icv_envs.sim._kernels.intersection_frames`), which call
        :func:`~icv_envs.sim._kernels.pet_transitions` as :meth:`record`
        does; ``occ`` and ``path`` hold ids ``< top`` and are updated in
        place, the new ``busy`` goes back through :meth:`apply`."""
        self._fit_top(int(top))
        return self._lo, self._hi, self._occ, self._pid, self._busy

    def apply(self, t: float, busy: np.ndarray, transitions: np.ndarray) -> None:
        """The PET events of one frame at time ``t`` after the compiled
        occupancy update: ``transitions`` rows ``(kind, path, slot)``, kind 0
        a slot left and 1 a slot entered, in the order :meth:`record`
        handles them; ``busy``: the ids inside an area now."""
        self._busy = busy
        ids, side = self._ids, self._side
        for kind, q, k in transitions.tolist():
            if kind:
                self._enter(t, int(ids[q, k]), int(side[q, k]))
            else:
                self._leave(t, int(ids[q, k]), int(side[q, k]))

    def _fit(self, vid: np.ndarray) -> None:
        """Grow the per-id tables to hold ids ``vid`` (at least doubling)."""
        self._fit_top(int(vid.max()) + 1 if len(vid) else 0)

    def _fit_top(self, top: int) -> None:
        if top > len(self._occ):
            grow = max(top, 2 * len(self._occ), 64) - len(self._occ)
            self._occ = np.concatenate([self._occ, np.zeros((grow, self._K), dtype=bool)])
            self._pid = np.concatenate([self._pid, np.zeros(grow, dtype=np.int64)])

    def _enter(self, t, a, k) -> None:
        o = 1 - k
        if self.inside[a, o] > 0:
            self.pending.setdefault((a, k), []).append(t)
        elif not math.isnan(self.last_exit[a, o]):
            self.samples.append(t - self.last_exit[a, o])
        self.inside[a, k] += 1

    def _leave(self, t, a, k) -> None:
        self.inside[a, k] -= 1
        self.last_exit[a, k] = t
        waiting = self.pending.pop((a, 1 - k), None)
        if waiting:
            self.samples.extend(te - t for te in waiting)

    def summary(self) -> dict:
        return pet_summary(self.samples)


def pet_summary(samples) -> dict:
    """``pet_min``, ``pet_p05`` (numpy's linear percentile), ``pet_samples``."""
    x = np.asarray(samples, dtype=np.float64)
    if not len(x):
        return {"pet_min": None, "pet_p05": None, "pet_samples": 0}
    return {"pet_min": float(x.min()), "pet_p05": float(np.percentile(x, 5.0)), "pet_samples": int(len(x))}


class JamWatch:
    """Vehicles stopped more than :data:`JAM_SECONDS` outside a queue at the box.

    Stopped time is kept per vehicle id; the queue rule is evaluated only
    for vehicles already stopped longer than :data:`JAM_SECONDS`."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._stopped_for = np.zeros(0)
        self.ever: set[int] = set()
        self.jammed_seconds = 0.0
        # (time, vid, distance to the centre) when a vehicle is first counted as jammed
        self.log: list[tuple[float, int, float]] = []

    def record(self, t: float, dt: float, vid, speed, in_queue_fn, dist=None) -> None:
        """``in_queue_fn(rows)`` -> bool per row: is the stopped vehicle in a queue at the box;
        ``dist`` (optional, per row): its distance to the centre, kept in the log."""
        vid = np.asarray(vid, dtype=np.int64)
        if not len(vid):
            return
        sf = self.standing_times(int(vid.max()) + 1)
        stopped = np.asarray(speed) < STOPPED_SPEED
        sf[vid] = np.where(stopped, sf[vid] + dt, 0.0)
        rows = np.flatnonzero(stopped & (sf[vid] > JAM_SECONDS))
        if len(rows):
            self.judge(t, dt, vid, rows, in_queue_fn, dist)

    def standing_times(self, top: int) -> np.ndarray:
        """The standing time of every id ``< top`` (grown to hold them; updated
        in place by :meth:`record`, or by the compiled frames,
        :func:`icv_envs.sim._kernels.intersection_frames`, which then pass
        the rows standing longer than :data:`JAM_SECONDS` to :meth:`judge`)."""
        if top > len(self._stopped_for):
            self._stopped_for = np.concatenate([self._stopped_for,
                                                np.zeros(max(top, 2 * len(self._stopped_for), 64)
                                                         - len(self._stopped_for))])
        return self._stopped_for

    def judge(self, t: float, dt: float, vid, rows, in_queue_fn, dist=None) -> None:
        """Of ``rows``, the vehicles standing longer than :data:`JAM_SECONDS`,
        those not in a queue at the box are jammed (see :meth:`record`)."""
        vid = np.asarray(vid, dtype=np.int64)
        jam = rows[~np.asarray(in_queue_fn(rows), dtype=bool)]
        self.jammed_seconds += dt * len(jam)
        where = np.full(len(jam), np.nan) if dist is None else np.asarray(dist, dtype=np.float64)[jam]
        for v, d in zip(vid[jam].tolist(), where.tolist()):
            if v not in self.ever:
                self.ever.add(v)
                self.log.append((round(t, 3), v, round(d, 1)))

    def summary(self) -> dict:
        return {"jammed": len(self.ever), "jammed_vehicle_seconds": float(self.jammed_seconds)}
