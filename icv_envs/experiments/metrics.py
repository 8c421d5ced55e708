"""Run metrics, defined in one place.

* ``mean_speed``: mean of vehicle speed over all vehicle-substeps [m/s].
* ``speed_fluctuation``: mean absolute acceleration |a| over all
  vehicle-substeps [m/s^2]. The paper's Fig. 11 caption calls its
  "speed fluctuation" an average acceleration (docs/metrics.md#speed-fluctuation); we use mean |a|
  so that braking and accelerating both count.
* ``collisions``: vehicles involved in a collision (or that left the
  drivable surface).
* ``min_gap``: smallest bumper-to-bumper gap between a vehicle and its leader
  in the same lane, sampled at every policy step [m] (``null`` if never two
  vehicles shared a lane).
* ``vehicles``: vehicles that took part in the run (initial plus spawned);
  ``vehicles_final``: on the road at the end; ``exited``: reached their exit.
"""

from __future__ import annotations

import math

__all__ = ["run_metrics"]


def run_metrics(world) -> dict:
    st = world.stats
    n = max(st["vehicle_steps"], 1)
    return {
        "collisions": int(st["collisions"]),
        "mean_speed": st["speed_sum"] / n,
        "speed_fluctuation": st["abs_accel_sum"] / n,
        "min_gap": None if not math.isfinite(st["min_gap"]) else float(st["min_gap"]),
        "vehicles": int(world.traffic.next_vid),
        "vehicles_final": int(world.traffic.n),
        "exited": int(st["exited"]),
        "left_road": int(st["left_road"]),
        "sim_seconds": float(world.time),
        "vehicle_steps": int(st["vehicle_steps"]),
    }
