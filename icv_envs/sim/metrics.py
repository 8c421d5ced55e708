"""Run metrics: what the vehicles do, defined once.

The simulation cores (:class:`icv_envs.sim.world.World`, and any other world
that wants the same figures) feed two accumulators every integration step;
:func:`run_metrics` turns a highway world's accumulators into the run totals
that the environments' ``metrics()`` report.

Motion (:class:`MotionStats`, every substep, every vehicle on the road):

* ``mean_speed``: mean speed over all vehicle-substeps [m/s].
* ``speed_fluctuation``: mean |dv/dt| of the *realised* speed over all
  vehicle-substeps [m/s^2], ``dv = v(t + dt) - v(t)`` after the speed limits
  ``0 <= v <= v_max`` have been applied. The paper's Fig. 11 and Fig. 14
  captions call this figure the "average acceleration" (docs/metrics.md#speed-fluctuation); it measures what the
  vehicles do: a vehicle standing at 0 m/s while braking is commanded, or
  cruising at ``v_max`` while acceleration is commanded, contributes 0.
* ``commanded_abs_accel``: mean |a| of the *commanded* acceleration (the
  figure this package reported as ``speed_fluctuation`` before); a
  diagnostic of what the controllers ask for, not of what happens.
* ``speed_std``: per-vehicle standard deviation of speed over the vehicle's
  time on the road, averaged over vehicles with at least two samples [m/s].
* ``stopped_share``: share of vehicle-substeps with ``v <`` :data:`STOPPED_SPEED`.

Surrogate safety on the highway (:class:`HeadwayStats`, every policy step,
every vehicle with a leader in the lane its body centre is in):

* ``min_gap``: smallest bumper-to-bumper gap to that leader [m];
* ``min_time_headway``: smallest time headway ``gap / v`` of a moving
  follower (``v >=`` :data:`STOPPED_SPEED`; a standing vehicle has no time
  headway, its gap is in ``min_gap``) [s];
* ``time_headway_p05``: 5th percentile of those time headways pooled over
  all (vehicle, policy step) samples, read off a fixed histogram of
  :data:`HEADWAY_BIN` s bins (rounded down to the bin; ``null`` without samples).
  Headways beyond :data:`HEADWAY_MAX` s go into one overflow bin, so the
  percentile is exact whenever fewer than 95% of the samples exceed it.

Counts: ``collisions`` (vehicles involved in a collision or that left the
drivable surface), ``vehicles`` (that took part), ``vehicles_final`` (on the
road at the end), ``exited``, ``left_road``, ``missed_exits`` (vehicles that
passed their exit without taking it).

``collisions_by_fault[kind][driver]`` (:meth:`icv_envs.sim.world.World.classify_collisions`):
one count per colliding pair (at least one of the two newly crashed) and one
per vehicle that left the road or hit an obstacle (``road``, at fault
itself). A pair whose bodies overlap less along the road than across it is a
rear-end contact: the rear vehicle is at fault (``struck_ahead``) unless the
front one was moving sideways towards it faster than 0.2 m/s (a cut-in: the
front vehicle, ``struck_from_behind``, is at fault); otherwise a
``side_swipe``, at fault the vehicle moving sideways towards the other
faster. ``driver`` is ``expert`` or ``policy`` by who drove the at-fault
vehicle in that step (an action equal to the expert's is expert-driven).
The intersection counts the same way with ``angle`` instead of
``side_swipe`` and ``road`` (``icv_envs.sim.intersection_metrics``).

``jammed`` (highway): vehicles that at some time stood (below 0.1 m/s)
longer than 30 s with at least 32 m of free road ahead (the IDM desired gap
at the top speed, ``s0 + v_max T``): nothing physical held them, so the
controller did (:meth:`icv_envs.sim.world.World.record_min_gap`). Must be 0.
"""

from __future__ import annotations

import math

import numpy as np

from icv_envs.sim._kernels import headway_record, motion_record

__all__ = [
    "STOPPED_SPEED",
    "HEADWAY_BIN",
    "HEADWAY_MAX",
    "MotionStats",
    "HeadwayStats",
    "run_metrics",
    "MOTION_KEYS",
]

#: [m/s] below this a vehicle counts as stopped (``stopped_share``) and has no time headway
STOPPED_SPEED: float = 0.1
#: [s] histogram bin of the time-headway percentile
HEADWAY_BIN: float = 0.01
#: [s] headways above this share one overflow bin
HEADWAY_MAX: float = 20.0

#: the motion keys every method reports (shared with the intersection env)
MOTION_KEYS = ("mean_speed", "speed_fluctuation", "speed_std", "stopped_share", "commanded_abs_accel")


class MotionStats:
    """Accumulates speed and acceleration figures over vehicle-substeps.

    :meth:`record` is called once per integration step with the vehicles'
    ids, their speeds before and after the step, the commanded accelerations
    and ``dt``; per-vehicle speed moments are kept in arrays indexed by id
    (ids are small non-negative integers, unique per run)."""

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
            new = max(size, 2 * len(self._n), 64)
            pad = new - len(self._n)
            self._n = np.concatenate([self._n, np.zeros(pad, dtype=np.int64)])
            self._s1 = np.concatenate([self._s1, np.zeros(pad)])
            self._s2 = np.concatenate([self._s2, np.zeros(pad)])

    def record(self, vid, v_before, v_after, commanded, dt: float) -> None:
        vid = np.asarray(vid, dtype=np.int64)
        if not len(vid):
            return
        v0 = np.asarray(v_before, dtype=np.float64)
        v1 = np.asarray(v_after, dtype=np.float64)
        a = np.asarray(commanded, dtype=np.float64)
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        if not (vid.ndim == 1 and v0.shape == v1.shape == a.shape == vid.shape):
            raise ValueError(f"vid, v_before, v_after and commanded must be 1-D of one length; got shapes "
                             f"{vid.shape}, {v0.shape}, {v1.shape}, {a.shape}")
        # compiled, with NumPy's summation order (icv_envs.sim._kernels.motion_record)
        sv, sdv, sa, stopped, top = motion_record(vid, v0, v1, a, STOPPED_SPEED, self._n, self._s1, self._s2)
        if stopped == -1:
            raise ValueError(f"vehicle ids must be >= 0, got {int(top)}")
        if stopped == -2:
            self._grow(int(top) + 1)
            sv, sdv, sa, stopped, top = motion_record(vid, v0, v1, a, STOPPED_SPEED, self._n, self._s1, self._s2)
        self.add(len(vid), sv, sdv, sa, stopped, dt)

    def add(self, n: int, sv: float, sdv: float, sa: float, stopped: int, dt: float) -> None:
        """Add one substep's sums (``n`` vehicles; speeds, ``|dv|``,
        ``|commanded|``; vehicles standing) whose per-vehicle moments were
        already accumulated (:meth:`record`, or the compiled substeps of
        :meth:`icv_envs.sim.world.World.substeps` after :meth:`reserve`)."""
        self.vehicle_steps += n
        self.speed_sum += sv
        self.realised_abs_accel_sum += sdv / float(dt)
        self.commanded_abs_accel_sum += sa
        self.stopped_steps += stopped

    def totals(self) -> tuple:
        """The run's accumulators ``(vehicle_steps, speed_sum,
        realised_abs_accel_sum, commanded_abs_accel_sum, stopped_steps)``,
        for a compiled pass that adds to them (:func:`icv_envs.sim._kernels.quiet_substeps`)."""
        return (int(self.vehicle_steps), float(self.speed_sum), float(self.realised_abs_accel_sum),
                float(self.commanded_abs_accel_sum), int(self.stopped_steps))

    def set_totals(self, vehicle_steps: int, speed_sum: float, realised: float, commanded: float,
                   stopped_steps: int) -> None:
        """The accumulators after such a pass (in :meth:`totals`' order)."""
        self.vehicle_steps = vehicle_steps
        self.speed_sum = speed_sum
        self.realised_abs_accel_sum = realised
        self.commanded_abs_accel_sum = commanded
        self.stopped_steps = stopped_steps

    def reserve(self, size: int) -> None:
        """Room for the per-vehicle moments of ids ``< size``."""
        self._grow(size)

    def moments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The per-vehicle arrays (count, sum of speeds, sum of squares), by id, updated in place."""
        return self._n, self._s1, self._s2

    def per_vehicle_std(self) -> np.ndarray:
        """Speed standard deviation of every vehicle with >= 2 samples."""
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


class HeadwayStats:
    """Minimum gap, minimum and 5th-percentile time headway (car following)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.min_gap = math.inf
        self.min_time_headway = math.inf
        self.samples = 0
        self._hist = np.zeros(int(round(HEADWAY_MAX / HEADWAY_BIN)) + 1, dtype=np.int64)

    def record(self, gap, speed) -> None:
        """``gap[i]``: bumper gap of vehicle ``i`` to its leader (``inf``
        without one); ``speed[i]``: its speed."""
        gap = np.asarray(gap, dtype=np.float64)
        v = np.asarray(speed, dtype=np.float64)
        if not (gap.ndim == 1 and v.shape == gap.shape):
            raise ValueError(f"gap and speed must be 1-D of one length; got shapes {gap.shape}, {v.shape}")
        # compiled (icv_envs.sim._kernels.headway_record)
        self.add_record(*headway_record(gap, v, self._hist, HEADWAY_BIN, STOPPED_SPEED))

    def add_record(self, g_min: float, th_min: float, count: int) -> None:
        """What one :meth:`record` adds besides the histogram (which the
        compiled record fills in place): the smallest gap and time headway
        of its call and their count (``World.record_min_gap``'s one-call
        path records so, from stop 43)."""
        self.min_gap = min(self.min_gap, g_min)
        self.min_time_headway = min(self.min_time_headway, th_min)
        self.samples += count

    def percentile(self, q: float) -> float | None:
        """``q``-th percentile (0..100) of the recorded time headways: the
        lower edge of the bin where the cumulative count reaches q% (rounded
        down, so a safety figure is never overstated; ``inf`` if that is the
        overflow bin)."""
        if not 0 <= q <= 100:
            raise ValueError(f"percentile q must be in [0, 100], got {q!r}")
        if self.samples == 0:
            return None
        c = np.cumsum(self._hist)
        k = int(np.searchsorted(c, q / 100.0 * self.samples, side="left"))
        if k >= len(self._hist) - 1:
            return math.inf
        return k * HEADWAY_BIN

    def summary(self) -> dict:
        p05 = self.percentile(5.0)
        return {
            "min_gap": None if not math.isfinite(self.min_gap) else float(self.min_gap),
            "min_time_headway": None if not math.isfinite(self.min_time_headway) else float(self.min_time_headway),
            "time_headway_p05": None if p05 is None or not math.isfinite(p05) else float(p05),
        }


def run_metrics(world) -> dict:
    """Run totals of a :class:`~icv_envs.sim.world.World` (see the module docstring)."""
    st = world.stats
    m = {"collisions": int(st["collisions"])}
    m.update(world.motion.summary())
    m.update(world.headways.summary())
    m.update({
        "vehicles": int(world.traffic.next_vid),
        "vehicles_final": int(world.traffic.n),
        "exited": int(st["exited"]),
        "left_road": int(st["left_road"]),
        "sim_seconds": float(world.time),
        "vehicle_steps": int(world.motion.vehicle_steps),
        "jammed": int(st.get("jammed", 0)),
        "missed_exits": int(st.get("missed_exits", 0)),
        "collisions_by_fault": dict(st["collisions_by_fault"]) if "collisions_by_fault" in st else {},
    })
    return m
