"""Several physics substeps in one compiled call (the rules every kernel
here follows: :mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.sim._kernels.formation import _wrap1
from icv_envs.sim._kernels.intersection import arc_s1, box_pairs_ordered, intersection_events
from icv_envs.sim._kernels.neighbours import collision_pairs_kept
from icv_envs.sim._kernels.physics import kinematic_substep_into, road_check
from icv_envs.sim._kernels.stats import motion_record, motion_sums_add, pet_transitions

__all__ = ["quiet_substeps", "intersection_frames"]


@nb.njit(cache=True)
def _rows10(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9):
    """Ten float arrays of one length as the rows of one ``(10, n)`` array:
    the state the frames' passes return as one array (numba boxes each
    returned array for about 0.35 us, a view of a row costs 0.1)."""
    S = np.empty((10, a0.shape[0]))
    S[0] = a0
    S[1] = a1
    S[2] = a2
    S[3] = a3
    S[4] = a4
    S[5] = a5
    S[6] = a6
    S[7] = a7
    S[8] = a8
    S[9] = a9
    return S


@nb.njit(cache=True)
def quiet_substeps(n_frames, x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase, lat, dt, v_max,
                   period, vid, length, width, stopped_speed, m_count, m_s1, m_s2, lane_width, n_lanes, total_lanes,
                   lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, edge_margin, road_end, exit_id, ex_x, de, ramp_lane,
                   cx_before, time, vehicle_steps, speed_sum, realised, commanded, stopped_steps, jam_time):
    """Up to ``n_frames`` substeps of :meth:`icv_envs.sim.world.World.substep`
    with the same controls, each the kernels that method calls in its order
    (:func:`kinematic_substep`, :func:`motion_record`,
    :func:`collision_pairs`, :func:`road_check`, then the exit tests; from
    stop 48 the collision sweep's order along ``x`` is kept from frame to
    frame, :func:`~icv_envs.sim._kernels.neighbours.collision_pairs_kept`,
    the same order and pairs; from
    stop 43 the integration as :func:`kinematic_substep_carry`, whose
    headings' cosines and sines the collision test takes, the same numbers),
    stopping after the first substep in which something happened that the
    world must handle in Python: a colliding pair, a vehicle at the end of a
    straight road, or one on its exit ramp (``exit_id >= 0``, ``-1 <=
    wrap(cx - ex_x) < 10`` on ``ramp_lane``), and then also a vehicle off the
    road not yet crashed. In a substep with none of those, vehicles off the
    road not yet crashed are crashed here (``crashed`` written in place, as
    the world's handler writes it) and the frames go on; a crashed vehicle
    off the road is no event (from stop 53). ``period``: the ring's
    length, or -1; ``cx_before``: the body centres before the first
    substep. The motion moments are accumulated in place (``m_count``,
    ``m_s1``, ``m_s2`` must hold every id); the clock ``time`` advances by
    ``dt`` per substep and the run's accumulators (``vehicle_steps`` ..
    ``stopped_steps``, :class:`icv_envs.sim.metrics.MotionStats`) take each
    substep's sums in order (:func:`motion_sums_add`), the additions the
    world made one substep at a time. Vehicles crossing the end of their
    diverge segment on a main lane (missed exits) are counted for the quiet
    substeps only (the world counts the last one with its events).

    Returns ``(k, event, S, time, vehicle_steps, speed_sum, realised,
    commanded, stopped_steps, missed, E, m, n_off, n_end, n_long, n_road)``: ``k`` substeps
    ran; ``S (12, n)`` the state and centres after the last substep, the
    centres before it and the new headings' ``cos`` and ``sin`` (libm's,
    from stop 51: :meth:`icv_envs.sim.traffic.Traffic.heading_cos_sin` keeps
    them), by rows ``x, y, heading, speed, accel, steer, stopped_for, cx,
    cy, cx_before, cos, sin``; the clock and accumulators after the
    ``k``; the last substep's ``m`` collision pairs and road check packed in
    ``E`` (int64): ``i`` (m), ``j`` (m), ``lane`` (n), ``off`` (n, 0/1),
    ``at_end`` (n); ``n_long`` the vehicles whose standing time after the
    last substep exceeds ``jam_time`` (``World.record_min_gap``'s jam
    watch; from stop 51); ``n_road`` the vehicles crashed off the road here,
    their rows (in the order they crashed) the last ``n_road`` entries of
    ``E`` (from stop 53). (Two arrays instead of fifteen: numba boxes each
    returned array for about 0.35 us, a view of a row costs 0.1.)"""
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
    k = n_frames
    event = False
    road_rows = np.empty(0, dtype=np.int64)  # (rows crashed off the road here, in order, each at most once:
    # room for every row made at the first such frame)
    n_road = 0
    trig = np.empty((4, n))  # (cos, sin of the heading, steering, its tan: kinematic_substep_carry)
    # (the collision sweep's order along x and the ring's ghost rows, kept from frame to frame)
    order = np.zeros(0, dtype=np.int64)
    ghosts = np.zeros(0, dtype=np.int64)
    # (two sets of the nine state arrays, written in turn: frame f reads the
    # set frame f - 1 wrote (the inputs at f = 0) and writes the other; the
    # centres before a frame, read until the next, are in the set it read)
    buf = np.empty((2, 9, n))
    for f in range(n_frames):
        cx_before = cx
        v_before = speed
        o = buf[f % 2]
        kinematic_substep_into(o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8], x, y, heading, speed, accel,
                               steer, crashed, stopped_for, wheelbase, lat, dt, v_max, period, trig, f == 0)
        x, y, heading, speed, acc, st, stopped_for, cx, cy = o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8]
        sv, sdv, sa, ns, _ = motion_record(vid, v_before, speed, acc, stopped_speed, m_count, m_s1, m_s2)
        sums[f, 0] = sv
        sums[f, 1] = sdv
        sums[f, 2] = sa
        stopped[f] = ns
        i, j, order, ghosts = collision_pairs_kept(cx, cy, trig[0], trig[1], length, width, period, order, ghosts)
        lane, off, at_end, n_off, n_end = road_check(cx, cy, lane_width, n_lanes, total_lanes, lane_ends, ob_lane,
                                                     ob_lo, ob_hi, ramp_iv, edge_margin, road_end)
        event = i.shape[0] > 0 or n_end > 0
        crossed = 0
        for q in range(n):
            if exit_id[q] < 0:
                continue
            past = _wrap1(cx[q] - ex_x[q], period)
            if lane[q] == ramp_lane and past >= -1.0 and past < 10.0:
                event = True
            if lane[q] < n_lanes and _wrap1(cx_before[q] - de[q], period) < 0 and _wrap1(cx[q] - de[q], period) >= 0:
                crossed += 1
        # off the road (from stop 53): a vehicle already crashed changes
        # nothing there (the world's handler crashes only those that are not,
        # and a crashed vehicle stays where it stopped until the step's end),
        # so it is no event; in a frame with nothing else to handle, those not
        # yet crashed crash here as the handler would crash them (their rows
        # kept for its counts) and the frames go on. (Until stop 53 every
        # frame after a vehicle left the road went back to Python: a noisy
        # policy's most common event.)
        if n_off > 0 and not event:
            if road_rows.shape[0] == 0:
                road_rows = np.empty(n, dtype=np.int64)
            for q in range(n):
                if off[q] and not crashed[q]:
                    crashed[q] = True
                    road_rows[n_road] = q
                    n_road += 1
        if event:
            k = f + 1
            break
        missed += crossed
    for _ in range(k):
        time += dt
    vehicle_steps, speed_sum, realised, commanded, stopped_steps = motion_sums_add(
        k, n, sums, stopped, dt, vehicle_steps, speed_sum, realised, commanded, stopped_steps)
    S = np.empty((12, n))
    S[0] = x
    S[1] = y
    S[2] = heading
    S[3] = speed
    S[4] = acc
    S[5] = st
    S[6] = stopped_for
    S[7] = cx
    S[8] = cy
    S[9] = cx_before
    S[10] = trig[0]  # (libm's cos and sin of the new headings: the collision test's, kept for the observations)
    S[11] = trig[1]
    m = i.shape[0]
    nl = lane.shape[0]
    E = np.empty(2 * m + 3 * nl + n_road, dtype=np.int64)
    E[:m] = i
    E[m:2 * m] = j
    q = 2 * m
    for r in range(nl):
        E[q + r] = lane[r]
        E[q + nl + r] = 1 if off[r] else 0
        E[q + 2 * nl + r] = 1 if at_end[r] else 0
    E[q + 3 * nl:] = road_rows[:n_road]
    n_long = 0  # (vehicles standing longer than jam_time: the world's jam watch asks, from stop 51)
    for q in range(n):
        if stopped_for[q] > jam_time:
            n_long += 1
    return (k, event, S, time, vehicle_steps, speed_sum, realised, commanded, stopped_steps, missed, E, m, n_off,
            n_end, n_long, n_road)


@nb.njit(cache=True)
def _push(buf, m, f, kind, path, slot):
    """Append the row ``(f, kind, path, slot)`` to ``buf`` holding ``m`` rows (doubled when full)."""
    if m == buf.shape[0]:
        new = np.empty((2 * buf.shape[0], 4), dtype=np.int64)
        new[:m] = buf
        buf = new
    buf[m, 0] = f
    buf[m, 1] = kind
    buf[m, 2] = path
    buf[m, 3] = slot
    return buf


@nb.njit(cache=True)
def intersection_frames(n_frames, x, y, heading, speed, accel, steer, crashed, dt, wheelbase, v_max, t,
                        vid, leg, mv, length, width, tlane, entered, departed, cleared, wrong_exit, exit_leg, plane,
                        enter_time, out, app_dir, app_right, dep_right, exit_of, box_half, lane_width, n_lanes,
                        off_margin, left_u, departure_length, P0, D0, P1, D1, L, arc, C, TH0, R, SGN,
                        stopped_speed, m_count, m_s1, m_s2, pet_lo, pet_hi, pet_occ, pet_path, pet_busy, jam_sf,
                        jam_seconds, vehicle_steps, speed_sum, realised, commanded, stopped_steps, st_speed_sum,
                        st_abs_accel_sum, st_min_speed_in_box):
    """Up to ``n_frames`` frames of ``IntersectionWorld.substep`` with the
    same controls, each in that method's order: the integration
    (:func:`~icv_envs.sim._kernels.physics.kinematic_substep`: a crashed
    vehicle brakes at -6 m/s^2 with the wheels straight, no steering limit,
    no ring; from stop 43 as ``kinematic_substep_carry``, whose headings'
    cosines and sines the collision test's sweep along ``x`` takes, the same
    numbers) and the body centres, the motion moments
    (:func:`~icv_envs.sim._kernels.stats.motion_record`), the events
    (:func:`~icv_envs.sim._kernels.intersection.intersection_events`, at
    time ``t + dt``, ``t + 2 dt``, ... added frame by frame as the world's
    clock adds them), the route coordinate of the PET candidates on a turn
    arc (``IntersectionLayout.arc_project``: ``arctan2`` and ``mod`` as
    NumPy's), their conflict-area transitions
    (:func:`~icv_envs.sim._kernels.stats.pet_transitions`), the jam watch's
    standing times (``JamWatch.record``) and the collision pairs
    (:func:`~icv_envs.sim._kernels.intersection.box_collision_pairs`, from
    stop 48 as :func:`~icv_envs.sim._kernels.intersection.box_pairs_ordered`
    with the rows' order along ``x`` kept from frame to frame: the same
    pairs).
    It stops after the first frame in which something happened that the
    world handles in Python: a wrong exit, a vehicle clearing the box, a
    crash (a colliding pair or leaving the drivable surface), a vehicle
    removed or driven back out of its road, or a vehicle standing longer
    than ``jam_seconds`` (the queue test).

    The fleet's event arrays (``entered``, ``plane``, ``enter_time``,
    ``departed``, ``exit_leg``, ``wrong_exit``, ``cleared``), the motion
    moments, the PET tables ``pet_occ``/``pet_path`` and the standing times
    ``jam_sf`` (all indexed by id; they must hold every id) are updated in
    place.

    The run's accumulators are added to frame by frame, as single steps add
    them (the same additions of the same doubles, in order; from stop 42,
    before in Python): the motion totals ``vehicle_steps, speed_sum,
    realised, commanded, stopped_steps`` (``MotionStats.totals``, by
    :func:`~icv_envs.sim._kernels.motion_sums_add` as in
    :func:`quiet_substeps`) and the world's statistics
    ``speed_sum``, ``abs_accel_sum`` (``|commanded|``) and
    ``min_speed_in_box`` (Python's ``min``: the old value on a tie).

    Returns ``(k, event, S, times (k,), acc (6,), counts (2,),
    transitions (m, 4), pet_busy, B, i, j, jam_rows)``: ``k`` frames ran;
    ``S (10, n)`` the state after the last and its centres and approach
    coordinates by rows ``x, y, heading, speed, accel, steer, cx, cy, u,
    lat_leg``; the clock after each frame (``t + dt``, ``+ dt``, ...); the
    accumulators after the last, ``acc`` = ``speed_sum, realised,
    commanded`` (the motion totals'), ``speed_sum, abs_accel_sum,
    min_speed_in_box`` (the world's) and ``counts`` = ``vehicle_steps,
    stopped_steps``; the PET transitions ``(frame,
    0 left / 1 entered, path, slot)`` in the order ``PetStats.record``
    handles them; ``B (5, n)`` the last frame's events by rows ``crash,
    new_wrong, clear_now, removed, left``; its collision pairs and the rows
    standing longer than ``jam_seconds`` (the state and the events as two
    arrays, not fifteen: numba boxes each returned array for about 0.35 us,
    a view of a row costs 0.1)."""
    n = x.shape[0]
    times = np.zeros(n_frames)
    sums = np.zeros((n_frames, 3))
    stopped = np.zeros(n_frames, dtype=np.int64)
    trans = np.empty((16, 4), dtype=np.int64)
    m = 0
    dummy = np.zeros(n)
    jam_all = np.empty(n, dtype=np.int64)
    trig = np.empty((4, n))  # (cos, sin of the heading, steering, its tan: kinematic_substep_carry)
    order = np.zeros(0, dtype=np.int64)  # (the rows along x, sorted from frame to frame: box_pairs_ordered)
    buf = np.empty((2, 9, n))  # (the state's two sets of arrays, written in turn: quiet_substeps)
    for fr in range(n_frames):
        v_before = speed
        o = buf[fr % 2]
        kinematic_substep_into(o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7], o[8], x, y, heading, speed, accel,
                               steer, crashed, dummy, wheelbase, -1.0, dt, v_max, -1.0, trig, fr == 0)
        x, y, heading, speed, acc, st, cx, cy = o[0], o[1], o[2], o[3], o[4], o[5], o[7], o[8]
        t = t + dt
        times[fr] = t
        sv, sdv, sa, ns, _ = motion_record(vid, v_before, speed, acc, stopped_speed, m_count, m_s1, m_s2)
        sums[fr, 0] = sv
        sums[fr, 1] = sdv
        sums[fr, 2] = sa
        stopped[fr] = ns
        st_speed_sum += sv
        st_abs_accel_sum += sa
        (u, lat_leg, crash, new_wrong, clear_now, removed, left, pet_rows, pet_pid, pet_s, pet_arc,
         mb) = intersection_events(cx, cy, speed, leg, mv, length, crashed, tlane, entered, departed, cleared,
                                   wrong_exit, exit_leg, plane, enter_time, out, app_dir, app_right, dep_right,
                                   exit_of, box_half, lane_width, n_lanes, off_margin, left_u, departure_length, t,
                                   P0, D0, P1, D1, L, arc)
        if mb < st_min_speed_in_box:
            st_min_speed_in_box = mb
        npet = pet_rows.shape[0]
        pvid = np.empty(npet, dtype=np.int64)
        plen = np.empty(npet)
        for q in range(npet):
            r = pet_rows[q]
            pvid[q] = vid[r]
            plen[q] = length[r]
            if pet_arc[q]:
                pet_s[q] = arc_s1(pet_pid[q], cx[r], cy[r], C, TH0, R, SGN)
        lft, ent, pet_busy = pet_transitions(pvid, pet_pid, pet_s, plen, pet_lo, pet_hi, pet_occ, pet_path, pet_busy)
        for q in range(lft.shape[0]):
            trans = _push(trans, m, fr, 0, lft[q, 0], lft[q, 1])
            m += 1
        for q in range(ent.shape[0]):
            trans = _push(trans, m, fr, 1, ent[q, 0], ent[q, 1])
            m += 1
        n_jam = 0
        for q in range(n):
            k = vid[q]
            if speed[q] < stopped_speed:
                jam_sf[k] = jam_sf[k] + dt
                if jam_sf[k] > jam_seconds:
                    jam_all[n_jam] = q
                    n_jam += 1
            else:
                jam_sf[k] = 0.0
        jam_rows = jam_all[:n_jam].copy()
        i, j, order = box_pairs_ordered(cx, cy, heading, trig[0], trig[1], length, width, box_half, order)
        event = n_jam > 0 or i.shape[0] > 0
        for q in range(n):
            if new_wrong[q] or clear_now[q] or (crash[q] and not crashed[q]) or ((removed[q] or left[q]) and not crashed[q]):
                event = True
                break
        if event or fr == n_frames - 1:
            k = fr + 1
            # (the motion totals as quiet_substeps adds them: motion_sums_add)
            vehicle_steps, speed_sum, realised, commanded, stopped_steps = motion_sums_add(
                k, n, sums, stopped, dt, vehicle_steps, speed_sum, realised, commanded, stopped_steps)
            S = _rows10(x, y, heading, speed, acc, st, cx, cy, u, lat_leg)
            B = np.empty((5, n), dtype=np.bool_)
            B[0] = crash
            B[1] = new_wrong
            B[2] = clear_now
            B[3] = removed
            B[4] = left
            acc_out = np.empty(6)
            acc_out[0] = speed_sum
            acc_out[1] = realised
            acc_out[2] = commanded
            acc_out[3] = st_speed_sum
            acc_out[4] = st_abs_accel_sum
            acc_out[5] = st_min_speed_in_box
            counts = np.empty(2, dtype=np.int64)
            counts[0] = vehicle_steps
            counts[1] = stopped_steps
            return (k, event, S, times[:k], acc_out, counts, trans[:m], pet_busy, B, i, j, jam_rows)
    raise ValueError("n_frames must be >= 1")
