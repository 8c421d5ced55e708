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
    continuously while NOT in a queue at the box: before the stop line a
    vehicle is in the queue if the first vehicle of its approach lane is
    within :data:`QUEUE_GAP` (10 m, bumper) of the stop line and every gap
    from there back to this vehicle is below :data:`QUEUE_GAP`; a vehicle
    stopped inside the box or after it is never in a queue.  ``jammed`` is
    the number of distinct vehicles that were ever jammed in the run,
    ``jammed_vehicle_seconds`` the time they spent jammed; both must be 0
    for a working controller (stopping at the line to wait for one's turn is
    allowed for as long as it takes).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["STOPPED_SPEED", "JAM_SECONDS", "QUEUE_GAP", "MotionStats", "ConflictAreas", "PetStats", "JamWatch",
           "pet_summary", "MOTION_KEYS"]

#: [m/s] below this a vehicle counts as stopped (the highway uses the same value)
STOPPED_SPEED: float = 0.1
#: [s] stopped longer than this outside a queue at the box = jammed
JAM_SECONDS: float = 10.0
#: [m] bumper gap that still counts as "in the queue" (a stopped IDM queue keeps 1-2 m)
QUEUE_GAP: float = 10.0
#: the motion keys (shared with the highway's metrics)
MOTION_KEYS = ("mean_speed", "speed_fluctuation", "speed_std", "stopped_share", "commanded_abs_accel")


class MotionStats:
    """Speed and realised / commanded acceleration over vehicle-substeps."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.vehicle_steps = 0
        self.speed_sum = 0.0
        self.realised_abs_accel_sum = 0.0
        self.commanded_abs_accel_sum = 0.0
        self.stopped_steps = 0
        self._n = np.zeros(0, dtype=np.int64)
        self._s1 = np.zeros(0)
        self._s2 = np.zeros(0)

    def _grow(self, size: int) -> None:
        if size > len(self._n):
            pad = max(size, 2 * len(self._n), 64) - len(self._n)
            self._n = np.concatenate([self._n, np.zeros(pad, dtype=np.int64)])
            self._s1 = np.concatenate([self._s1, np.zeros(pad)])
            self._s2 = np.concatenate([self._s2, np.zeros(pad)])

    def record(self, vid, v_before, v_after, commanded, dt: float) -> None:
        """One substep: ids, speeds before and after it, commanded accelerations, ``dt``."""
        vid = np.asarray(vid, dtype=np.int64)
        if not len(vid):
            return
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        v0 = np.asarray(v_before, dtype=np.float64)
        v1 = np.asarray(v_after, dtype=np.float64)
        self.vehicle_steps += len(vid)
        self.speed_sum += float(v1.sum())
        self.realised_abs_accel_sum += float(np.abs(v1 - v0).sum()) / float(dt)
        self.commanded_abs_accel_sum += float(np.abs(np.asarray(commanded, dtype=np.float64)).sum())
        self.stopped_steps += int((v1 < STOPPED_SPEED).sum())
        self._grow(int(vid.max()) + 1)
        np.add.at(self._n, vid, 1)
        np.add.at(self._s1, vid, v1)
        np.add.at(self._s2, vid, v1 * v1)

    def per_vehicle_std(self) -> np.ndarray:
        ok = self._n >= 2
        n = self._n[ok].astype(np.float64)
        mean = self._s1[ok] / n
        return np.sqrt(np.maximum(self._s2[ok] / n - mean * mean, 0.0))

    def summary(self) -> dict:
        n = max(self.vehicle_steps, 1)
        std = self.per_vehicle_std()
        return {
            "mean_speed": self.speed_sum / n,
            "speed_fluctuation": self.realised_abs_accel_sum / n,
            "speed_std": float(std.mean()) if len(std) else 0.0,
            "stopped_share": self.stopped_steps / n,
            "commanded_abs_accel": self.commanded_abs_accel_sum / n,
        }


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
        self.reset()

    def reset(self) -> None:
        A = self.areas.n
        self.last_exit = np.full((A, 2), np.nan)  # time the last vehicle of each side left
        self.inside = np.zeros((A, 2), dtype=np.int64)  # vehicles of each side inside now
        self.pending: dict[tuple[int, int], list[float]] = {}  # (area, side) -> entry times waiting for the other side
        self._occ: dict[int, np.ndarray] = {}  # vid -> occupied area ids
        self._sides: dict[int, dict] = {}  # vid -> {area: side} of its path
        self.samples: list[float] = []

    def record(self, t: float, vid, pid, s, length) -> None:
        """Occupancy update at time ``t`` for vehicles ``vid`` on paths ``pid``
        at route coordinate ``s`` (vehicles near the box only is enough;
        vehicles not listed are treated as having left every area)."""
        bp = self.areas.by_path
        now: dict[int, np.ndarray] = {}
        side_of: dict[int, dict] = {}
        for v, p, x, ln in zip(np.asarray(vid).tolist(), np.asarray(pid).tolist(), np.asarray(s).tolist(),
                               np.asarray(length).tolist()):
            e = bp.get(p)
            if e is None:
                continue
            ids, side, lo, hi = e
            occ = (x - 0.5 * ln < hi) & (x + 0.5 * ln > lo)
            if occ.any() or v in self._occ:
                now[v] = ids[occ]
                side_of[v] = dict(zip(ids.tolist(), side.tolist()))
        for v in set(self._occ) | set(now):
            old = self._occ.get(v, np.zeros(0, dtype=np.int64))
            new = now.get(v, np.zeros(0, dtype=np.int64))
            if not len(old) and not len(new):
                continue
            sides = side_of.get(v) or self._sides.get(v, {})
            for a in np.setdiff1d(old, new).tolist():
                self._leave(t, a, sides[a])
            for a in np.setdiff1d(new, old).tolist():
                self._enter(t, a, sides[a])
        self._occ = {v: o for v, o in now.items() if len(o)}
        self._sides = {v: side_of[v] for v in self._occ}

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
    """Vehicles stopped more than :data:`JAM_SECONDS` outside a queue at the box."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.stopped_for: dict[int, float] = {}
        self.ever: set[int] = set()
        self.jammed_seconds = 0.0
        self.log: list[tuple[float, int]] = []  # (time, vid) when a vehicle is first counted as jammed

    def record(self, t: float, dt: float, vid, speed, in_queue_fn) -> None:
        """``in_queue_fn(rows)`` -> bool per row: is the stopped vehicle in a queue at the box."""
        vid = np.asarray(vid)
        stopped = np.asarray(speed) < STOPPED_SPEED
        so = self.stopped_for
        new = {}
        for r in np.flatnonzero(stopped).tolist():
            v = int(vid[r])
            new[v] = so.get(v, 0.0) + dt
        self.stopped_for = new
        long_rows = [r for r in np.flatnonzero(stopped).tolist() if new[int(vid[r])] > JAM_SECONDS]
        if not long_rows:
            return
        rows = np.asarray(long_rows, dtype=np.int64)
        q = in_queue_fn(rows)
        for r, inq in zip(rows.tolist(), np.asarray(q).tolist()):
            if inq:
                continue
            v = int(vid[r])
            self.jammed_seconds += dt
            if v not in self.ever:
                self.ever.add(v)
                self.log.append((round(t, 3), v))

    def summary(self) -> dict:
        return {"jammed": len(self.ever), "jammed_vehicle_seconds": float(self.jammed_seconds)}
