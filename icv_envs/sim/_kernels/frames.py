"""Several physics substeps in one compiled call (the rules every kernel
here follows: :mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.sim._kernels.formation import _wrap1
from icv_envs.sim._kernels.neighbours import collision_pairs
from icv_envs.sim._kernels.physics import kinematic_substep, road_check
from icv_envs.sim._kernels.stats import motion_record

__all__ = ["quiet_substeps"]


@nb.njit(cache=True)
def quiet_substeps(n_frames, x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase, lat, dt, v_max,
                   period, vid, length, width, stopped_speed, m_count, m_s1, m_s2, lane_width, n_lanes, total_lanes,
                   lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, edge_margin, road_end, exit_id, ex_x, de, ramp_lane,
                   cx_before):
    """Up to ``n_frames`` substeps of :meth:`icv_envs.sim.world.World.substep`
    with the same controls, each the kernels that method calls in its order
    (:func:`kinematic_substep`, :func:`motion_record`,
    :func:`collision_pairs`, :func:`road_check`, then the exit tests),
    stopping after the first substep in which something happened that the
    world must handle in Python: a colliding pair, a vehicle off the road or
    at the end of a straight road, or one on its exit ramp (``exit_id >= 0``,
    ``-1 <= wrap(cx - ex_x) < 10`` on ``ramp_lane``). ``period``: the ring's
    length, or -1; ``cx_before``: the body centres before the first
    substep. The motion moments are accumulated in place (``m_count``,
    ``m_s1``, ``m_s2`` must hold every id); the per-substep sums are
    returned for the caller to add in order. Vehicles crossing the end of
    their diverge segment on a main lane (missed exits) are counted for the
    quiet substeps only (the world counts the last one with its events).

    Returns ``(k, event, x, y, heading, speed, accel, steer, stopped_for,
    cx, cy, cx_before, sums (k, 3), stopped (k,), missed, i, j, lane, off,
    at_end, n_off, n_end)``: ``k`` substeps ran, the state and centres after
    the last, the centres before it, and its collision pairs and road check."""
    n = x.shape[0]
    sums = np.zeros((n_frames, 3))
    stopped = np.zeros(n_frames, dtype=np.int64)
    missed = 0
    cx = cx_before
    cy = y
    acc = accel
    st = steer
    i = np.zeros(0, dtype=np.int64)
    j = np.zeros(0, dtype=np.int64)
    lane = np.zeros(0, dtype=np.int64)
    off = np.zeros(0, dtype=np.bool_)
    at_end = np.zeros(0, dtype=np.bool_)
    n_off = 0
    n_end = 0
    for f in range(n_frames):
        cx_before = cx
        v_before = speed
        x, y, heading, speed, acc, st, stopped_for, cx, cy = kinematic_substep(
            x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase, lat, dt, v_max, period)
        sv, sdv, sa, ns, _ = motion_record(vid, v_before, speed, acc, stopped_speed, m_count, m_s1, m_s2)
        sums[f, 0] = sv
        sums[f, 1] = sdv
        sums[f, 2] = sa
        stopped[f] = ns
        i, j = collision_pairs(cx, cy, heading, length, width, period)
        lane, off, at_end, n_off, n_end = road_check(cx, cy, lane_width, n_lanes, total_lanes, lane_ends, ob_lane,
                                                     ob_lo, ob_hi, ramp_iv, edge_margin, road_end)
        event = i.shape[0] > 0 or n_off > 0 or n_end > 0
        crossed = 0
        for q in range(n):
            if exit_id[q] < 0:
                continue
            past = _wrap1(cx[q] - ex_x[q], period)
            if lane[q] == ramp_lane and past >= -1.0 and past < 10.0:
                event = True
            if lane[q] < n_lanes and _wrap1(cx_before[q] - de[q], period) < 0 and _wrap1(cx[q] - de[q], period) >= 0:
                crossed += 1
        if event:
            return (f + 1, True, x, y, heading, speed, acc, st, stopped_for, cx, cy, cx_before, sums[:f + 1],
                    stopped[:f + 1], missed, i, j, lane, off, at_end, n_off, n_end)
        missed += crossed
    return (n_frames, False, x, y, heading, speed, acc, st, stopped_for, cx, cy, cx_before, sums, stopped, missed, i,
            j, lane, off, at_end, n_off, n_end)
