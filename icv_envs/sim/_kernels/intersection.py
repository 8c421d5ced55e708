"""The intersection world's per-frame event tests, compiled (issue 10): the
rules of :mod:`icv_envs.sim.intersection_world` (entering the box, leaving
it by an exit leg, clearing it, removal, leaving the drivable surface,
driving back out of the approach road) and the selection and route
coordinates of the vehicles near the box for the PET occupancy update. The
rules every kernel here follows are in :mod:`icv_envs.sim._kernels`; the
only transcendental of the projection (``arctan2`` on the turn arcs) stays
in NumPy, so nothing here calls libm."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.sim._kernels.neighbours import (_rect_overlap_cs, collision_pairs, collision_pairs_cs, cos_sin,
                                             stable_order)
from icv_envs.sim._kernels.physics import npy_mod

__all__ = ["arc_project_rows", "intersection_events", "box_collision_pairs", "box_collision_pairs_cs", "rows_of_ids",
           "route_rows"]

PET_REACH = 20.0  # metres before the stop line / past the box edge inside which a vehicle is a PET candidate


@nb.njit(cache=True, inline="always")
def arc_s1(p, cx, cy, C, TH0, R, SGN):
    """Route coordinate of the point ``(cx, cy)`` on turn arc ``p``
    (``IntersectionLayout.arc_project``: the angle around the arc's centre,
    ``arctan2`` and ``mod`` as NumPy's, as arc length from the stop line)."""
    ang = math.atan2(cy - C[p, 1], cx - C[p, 0]) - TH0[p]
    ang = npy_mod(ang + math.pi, 2.0 * math.pi) - math.pi
    return R[p] * ang * SGN[p]


@nb.njit(cache=True)
def arc_project_rows(q, cx, cy, C, TH0, R, SGN):
    """``IntersectionLayout.arc_project`` of points ``(cx[k], cy[k])`` on turn
    arcs ``q[k]`` in one pass (from stop 50; NumPy's ``arctan2`` before):
    the route coordinate (:func:`arc_s1`'s operations) and the signed offset
    to the right, ``SGN (hypot(qx, qy) - R)``. ``atan2`` and ``hypot`` are
    libm's: NumPy's at ``X86_V3`` (the rule of :mod:`icv_envs.sim._kernels`;
    NumPy's AVX-512 ``arctan2`` rounds some values differently). Returns
    ``(s, lat)``."""
    n = q.shape[0]
    s = np.empty(n)
    lat = np.empty(n)
    for k in range(n):
        p = q[k]
        s[k] = arc_s1(p, cx[k], cy[k], C, TH0, R, SGN)
        lat[k] = SGN[p] * (math.hypot(cx[k] - C[p, 0], cy[k] - C[p, 1]) - R[p])
    return s, lat


@nb.njit(cache=True)
def intersection_events(cx, cy, speed, leg, mv, length, crashed, tlane, entered, departed, cleared, wrong_exit,
                        exit_leg, plane, enter_time, out, app_dir, app_right, dep_right, exit_of, box_half,
                        lane_width, n_lanes, off_margin, left_u, departure_length, t,
                        P0, D0, P1, D1, L, arc):
    """One frame's events, in the order of ``IntersectionWorld.substep``,
    for body centres ``(cx, cy)`` after the integration at time ``t``.

    Updated in place (the fleet's own arrays): ``entered`` (and ``plane``,
    ``enter_time`` of the vehicles whose centre crossed the stop line),
    ``departed`` and ``exit_leg`` (those whose centre left the box square,
    by the leg of largest outward projection), ``wrong_exit``, ``cleared``
    (whole body past the box edge).

    Returns ``(u, lat_leg, crash, new_wrong, clear_now, removed, left,
    pet_rows, pet_pid, pet_s, pet_arc, min_box)``: the approach-axis
    coordinates; per row, a crash by leaving the drivable surface, a wrong
    exit this frame, cleared this frame, past ``departure_length``, driven
    back out of the approach road (``u < left_u``); the not-crashed rows
    within :data:`PET_REACH` of the box (sorted), their path ids and route
    coordinates (``IntersectionLayout.project``; for rows with ``pet_arc``,
    in the box on a turn, ``pet_s`` is left to the caller); the least speed
    in the box (``inf`` if nobody is in it)."""
    n = cx.shape[0]
    u = np.empty(n)
    lat = np.empty(n)
    crash = np.zeros(n, dtype=np.bool_)
    new_wrong = np.zeros(n, dtype=np.bool_)
    clear_now = np.zeros(n, dtype=np.bool_)
    removed = np.zeros(n, dtype=np.bool_)
    left = np.zeros(n, dtype=np.bool_)
    near = np.zeros(n, dtype=np.bool_)
    hi_lat = n_lanes * lane_width + off_margin
    top = float(n_lanes - 1)
    min_box = np.inf
    b = box_half
    for i in range(n):
        g = leg[i]
        dx = cx[i] - b * out[g, 0]
        dy = cy[i] - b * out[g, 1]
        ui = dx * app_dir[g, 0] + dy * app_dir[g, 1]
        li = dx * app_right[g, 0] + dy * app_right[g, 1]
        u[i] = ui
        lat[i] = li
        if not entered[i] and ui >= 0.0:
            entered[i] = True
            fl = np.floor(li / lane_width)
            if fl < 0.0:
                fl = 0.0
            elif fl > top:
                fl = top
            plane[i] = np.int64(fl)
            enter_time[i] = t
        appr = not entered[i]
        if appr and (li < -off_margin or li > hi_lat):
            crash[i] = True
        inside = max(abs(cx[i]), abs(cy[i])) <= b
        if entered[i] and not departed[i] and not inside:
            e = 0
            best = cx[i] * out[0, 0] + cy[i] * out[0, 1]
            for k in range(1, out.shape[0]):
                p = cx[i] * out[k, 0] + cy[i] * out[k, 1]
                if p > best:
                    best = p
                    e = k
            exit_leg[i] = e
            departed[i] = True
            if e != exit_of[mv[i]]:
                wrong_exit[i] = True
                new_wrong[i] = True
        if departed[i]:
            e = exit_leg[i]
            past = cx[i] * out[e, 0] + cy[i] * out[e, 1] - b
            lat_e = (cx[i] - b * out[e, 0]) * dep_right[e, 0] + (cy[i] - b * out[e, 1]) * dep_right[e, 1]
            if lat_e < -off_margin or lat_e > hi_lat:
                crash[i] = True
            if not cleared[i] and past >= 0.5 * length[i]:
                cleared[i] = True
                clear_now[i] = True
            removed[i] = past >= departure_length
            near[i] = past < PET_REACH
        else:
            near[i] = ui >= -PET_REACH
        if entered[i] and not departed[i]:
            if speed[i] < min_box:
                min_box = speed[i]
        left[i] = appr and ui < left_u
    m = 0
    for i in range(n):
        if near[i] and not crashed[i]:
            m += 1
    pet_rows = np.empty(m, dtype=np.int64)
    pet_pid = np.empty(m, dtype=np.int64)
    pet_s = np.empty(m)
    pet_arc = np.zeros(m, dtype=np.bool_)
    q = 0
    for i in range(n):
        if not (near[i] and not crashed[i]):
            continue
        p = 3 * mv[i] + (plane[i] if plane[i] >= 0 else tlane[i])
        pet_rows[q] = i
        pet_pid[q] = p
        if departed[i]:
            qx = cx[i] - P1[p, 0]
            qy = cy[i] - P1[p, 1]
            pet_s[q] = L[p] + qx * D1[p, 0] + qy * D1[p, 1]
        else:
            px = cx[i] - P0[p, 0]
            py = cy[i] - P0[p, 1]
            pet_s[q] = px * D0[p, 0] + py * D0[p, 1]
            pet_arc[q] = entered[i] and arc[p]
        q += 1
    return u, lat, crash, new_wrong, clear_now, removed, left, pet_rows, pet_pid, pet_s, pet_arc, min_box


@nb.njit(cache=True)
def box_collision_pairs(cx, cy, heading, length, width, box_half):
    """``IntersectionWorld.collision_pairs`` compiled whole: the sweep and
    prune of :func:`~icv_envs.sim._kernels.neighbours.collision_pairs` run
    along ``x`` over the vehicles on the east-west legs and along ``y`` over
    those on the north-south legs (the box region, within 10 m of the box
    square, in both), the pairs of the two sweeps joined, deduplicated and
    sorted as ``(min, max)`` row pairs."""
    ch, sh = cos_sin(heading)
    return box_collision_pairs_cs(cx, cy, heading, ch, sh, length, width, box_half)


@nb.njit(cache=True)
def box_collision_pairs_cs(cx, cy, heading, ch, sh, length, width, box_half):
    """:func:`box_collision_pairs` with the headings' cosines ``ch`` and
    sines ``sh`` given (the physics frames have them, from stop 43): the
    sweep along ``x`` takes them; the one along ``y`` turns the headings
    (``pi/2 - heading``) and takes their own.

    From stop 48 the pairs are found as :func:`_box_pairs_bounded` finds
    them (a pair of bodies too far apart for any heading is never tested,
    and the turned headings' sines and cosines are taken only for the pairs
    close enough, instead of for every vehicle of the sweep along ``y``:
    the same pairs, 2-3x faster at the box's 50 vehicles); a non-finite
    position, heading or size takes the two sweeps as before
    (:func:`_box_pairs_sweeps`), whose NaN rules it keeps."""
    i, j, _ = box_pairs_ordered(cx, cy, heading, ch, sh, length, width, box_half, np.zeros(0, dtype=np.int64))
    return i, j


@nb.njit(cache=True)
def box_pairs_ordered(cx, cy, heading, ch, sh, length, width, box_half, order):
    """:func:`box_collision_pairs_cs` given ``order``, the rows' order along
    ``x`` of the frame before (any permutation of the rows; an empty array
    the first time), sorted again by
    :func:`~icv_envs.sim._kernels.neighbours.stable_order` (an insertion
    sort: linear when it was sorted a frame before;
    :func:`~icv_envs.sim._kernels.frames.intersection_frames` keeps it from
    frame to frame, as the highway's frames keep theirs). Returns ``(i, j,
    order)``."""
    n = cx.shape[0]
    if n < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), order
    for q in range(n):
        if not (math.isfinite(cx[q]) and math.isfinite(cy[q]) and math.isfinite(heading[q])
                and math.isfinite(ch[q]) and math.isfinite(sh[q]) and math.isfinite(length[q])
                and math.isfinite(width[q])):
            i, j = _box_pairs_sweeps(cx, cy, heading, ch, sh, length, width, box_half)
            return i, j, order
    order = stable_order(cx, order)
    i, j = _box_pairs_bounded(cx, cy, heading, ch, sh, length, width, box_half, order)
    return i, j, order


@nb.njit(cache=True)
def _box_pairs_sweeps(cx, cy, heading, ch, sh, length, width, box_half):
    """The two sweeps of :func:`box_collision_pairs_cs` as written until
    stop 47: along ``x`` over the vehicles on the east-west legs and in the
    box region, along ``y`` over those on the north-south legs and in the
    box region, joined, deduplicated and sorted."""
    n = cx.shape[0]
    reach = box_half + 10.0
    keys = np.empty(0, dtype=np.int64)
    for swap in range(2):
        m = 0
        rows = np.empty(n, dtype=np.int64)
        for q in range(n):
            ax = abs(cx[q])
            ay = abs(cy[q])
            if max(ax, ay) < reach or (ay > ax if swap else ax >= ay):
                rows[m] = q
                m += 1
        if m < 2:
            continue
        rows = rows[:m]
        if swap:
            i, j = collision_pairs(cy[rows], cx[rows], 0.5 * math.pi - heading[rows], length[rows], width[rows], -1.0)
        else:
            i, j = collision_pairs_cs(cx[rows], cy[rows], ch[rows], sh[rows], length[rows], width[rows], -1.0)
        k = np.empty(len(i), dtype=np.int64)
        for q in range(len(i)):
            a = rows[i[q]]
            b = rows[j[q]]
            k[q] = min(a, b) * (n + 1) + max(a, b)
        keys = np.concatenate((keys, k))
    if not len(keys):
        return keys, keys.copy()
    keys = np.unique(keys)
    return keys // (n + 1), keys % (n + 1)


@nb.njit(cache=True)
def _box_pairs_bounded(cx, cy, heading, ch, sh, length, width, box_half, order):
    """The pairs of :func:`_box_pairs_sweeps` for finite inputs, each
    sweep's pair tested as that sweep tests it, but only the pairs a bound
    leaves.

    A sweep reports the pair ``(i, j)`` of its vehicles (``i`` first in its
    stable order along its axis) when their boxes aligned with its axes
    overlap (``d < h_i + h_j`` along the axis, ``|d'| < h'_i + h'_j``
    across it, the half extents ``h = (l |cos| + w |sin|) / 2``, ``h' =
    (l |sin| + w |cos|) / 2`` of its headings) and the separating-axis test
    finds no gap; its reach, twice the largest ``h``, only stops the scan
    where that overlap fails. Every half extent is at most ``r = (|l| +
    |w|) / 2`` whatever the heading (``|cos|, |sin| <= 1``, and rounding is
    monotone), so a pair farther apart than ``r_i + r_j`` along ``x`` or
    ``y`` is in neither sweep's report. The pairs within those bounds (the
    vehicles sorted along ``x``, each scanned against those after it while
    the gap along ``x`` is below its own ``r`` plus the largest; ``order``
    the rows sorted along ``x``) are tested
    exactly as each sweep whose vehicles they both are tests them: its
    half extents (the sweep along ``y`` with ``cos``, ``sin`` of ``pi/2 -
    heading``, coordinates swapped), its overlap test in its operand order
    and :func:`_rect_overlap_cs` with its first vehicle first. Returns the
    pairs as ``(min, max)`` rows, sorted, each once."""
    n = cx.shape[0]
    reach = box_half + 10.0
    r = np.empty(n)
    sx = np.empty(n, dtype=np.bool_)
    sy = np.empty(n, dtype=np.bool_)
    rmax = 0.0
    for q in range(n):
        r[q] = 0.5 * (abs(length[q]) + abs(width[q]))
        if r[q] > rmax:
            rmax = r[q]
        ax = abs(cx[q])
        ay = abs(cy[q])
        near = max(ax, ay) < reach
        sx[q] = near or ax >= ay
        sy[q] = near or ay > ax
    keys = np.empty(0, dtype=np.int64)
    m = 0
    for p in range(n):
        a = order[p]
        for t in range(p + 1, n):
            b = order[t]
            gx = cx[b] - cx[a]
            if not gx < r[a] + rmax:
                break
            rs = r[a] + r[b]
            if not (gx < rs and abs(cy[b] - cy[a]) < rs):
                continue
            lo = min(a, b)
            hi = max(a, b)
            hit = False
            if sx[a] and sx[b]:
                hit = _sweep_pair(cx, cy, ch, sh, length, width, lo, hi)
            if not hit and sy[a] and sy[b]:
                ca = math.cos(0.5 * math.pi - heading[lo])
                sa = math.sin(0.5 * math.pi - heading[lo])
                cb = math.cos(0.5 * math.pi - heading[hi])
                sb = math.sin(0.5 * math.pi - heading[hi])
                hit = _sweep_pair2(cy[lo], cx[lo], ca, sa, length[lo], width[lo], cy[hi], cx[hi], cb, sb, length[hi],
                                   width[hi], lo, hi)
            if hit:
                if m == keys.shape[0]:
                    grown = np.empty(2 * m + 4, dtype=np.int64)
                    grown[:m] = keys[:m]
                    keys = grown
                keys[m] = lo * (n + 1) + hi
                m += 1
    if not m:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    keys = np.unique(keys[:m])
    return keys // (n + 1), keys % (n + 1)


@nb.njit(cache=True, inline="always")
def _sweep_pair(cx, cy, ch, sh, length, width, lo, hi):
    """The sweep along ``x``'s test of rows ``lo < hi`` (:func:`_box_pairs_bounded`)."""
    return _sweep_pair2(cx[lo], cy[lo], ch[lo], sh[lo], length[lo], width[lo], cx[hi], cy[hi], ch[hi], sh[hi],
                        length[hi], width[hi], lo, hi)


@nb.njit(cache=True, inline="always")
def _sweep_pair2(x1, y1, c1, s1, l1, w1, x2, y2, c2, s2, l2, w2, lo, hi):
    """One sweep's test of the pair of rows ``lo < hi`` in its coordinates
    (``x`` along its axis): the overlap of the boxes aligned with its axes
    as :func:`~icv_envs.sim._kernels.neighbours.sweep_candidates` computes
    it (the gap from the vehicle first in the stable order along ``x``,
    ``lo`` on a tie), then :func:`_rect_overlap_cs` with that vehicle
    first."""
    hx1 = 0.5 * (l1 * abs(c1) + w1 * abs(s1))
    hy1 = 0.5 * (l1 * abs(s1) + w1 * abs(c1))
    hx2 = 0.5 * (l2 * abs(c2) + w2 * abs(s2))
    hy2 = 0.5 * (l2 * abs(s2) + w2 * abs(c2))
    if x2 < x1:  # hi is first along x
        return (x1 - x2 < hx1 + hx2 and abs(y1 - y2) < hy1 + hy2
                and _rect_overlap_cs(x2, y2, c2, s2, l2, w2, x1, y1, c1, s1, l1, w1))
    return (x2 - x1 < hx2 + hx1 and abs(y2 - y1) < hy2 + hy1
            and _rect_overlap_cs(x1, y1, c1, s1, l1, w1, x2, y2, c2, s2, l2, w2))


@nb.njit(cache=True)
def rows_of_ids(table, vids):
    """``table[vids]`` (an id -> row table, -1 for ids not present), -1 for
    ids outside the table: the fleet's row lookup, asked for a handful of ids
    at a time about forty times per intersection step."""
    out = np.empty(vids.shape[0], dtype=np.int64)
    n = table.shape[0]
    for q in range(vids.shape[0]):
        v = vids[q]
        out[q] = table[v] if 0 <= v < n else -1
    return out


@nb.njit(cache=True)
def route_rows(x, y, heading, half_wheelbase, leg, mv, plane, tlane, entered, departed, out, app_dir, app_right,
               box_half, lane_width, n_lanes, P0, D0, P1, D1, L, arc, C, TH0, R, SGN):
    """``IntersectionWorld.route`` compiled, per vehicle in the order of the
    array code: the body centre ``(x, y) + wheelbase/2 (cos, sin)(heading)``;
    the approach-axis coordinates ``u``, ``lat_leg`` and lane of its leg;
    the phase (0 approach, 1 in the box, 2 departed); the path (its locked
    lane, else the expected one); the route coordinate and offset
    (``IntersectionLayout.project``: along the approach or departure line,
    on a turn arc by the angle around its centre, ``arctan2``, ``mod`` and
    ``hypot`` as NumPy's); ``X = L/2 - s``, ``dist = box_half - s`` and the
    path length ``L``.

    Returns ``(Fl, In)``: the rows ``cx, cy, u, lat_leg, s, lat, X, dist,
    L`` of one float array and ``lane, pid, phase`` of one int64 array (two
    boxed arrays instead of twelve: numba boxes each returned array for
    about 0.35 us, a view of a row costs 0.1)."""
    n = x.shape[0]
    Fl = np.empty((9, n))
    In = np.empty((3, n), dtype=np.int64)
    cx = Fl[0]
    cy = Fl[1]
    u = Fl[2]
    lat_leg = Fl[3]
    s = Fl[4]
    lat = Fl[5]
    X = Fl[6]
    dist = Fl[7]
    Lr = Fl[8]
    lane = In[0]
    pid = In[1]
    phase = In[2]
    top = float(n_lanes - 1)
    for i in range(n):
        c = x[i] + half_wheelbase * np.cos(heading[i])
        d = y[i] + half_wheelbase * np.sin(heading[i])
        cx[i] = c
        cy[i] = d
        g = leg[i]
        ox = box_half * out[g, 0]
        oy = box_half * out[g, 1]
        u[i] = (c - ox) * app_dir[g, 0] + (d - oy) * app_dir[g, 1]
        ll = (c - ox) * app_right[g, 0] + (d - oy) * app_right[g, 1]
        lat_leg[i] = ll
        fl = np.floor(ll / lane_width)
        lane[i] = np.int64(min(max(fl, 0.0), top))
        ph = 2 if departed[i] else (1 if entered[i] else 0)
        phase[i] = ph
        p = 3 * mv[i] + (plane[i] if plane[i] >= 0 else tlane[i])
        pid[i] = p
        if ph == 2:
            qx = c - P1[p, 0]
            qy = d - P1[p, 1]
            si = L[p] + qx * D1[p, 0] + qy * D1[p, 1]
            li = qx * D1[p, 1] - qy * D1[p, 0]
        elif ph == 1 and arc[p]:
            si = arc_s1(p, c, d, C, TH0, R, SGN)
            li = SGN[p] * (math.hypot(c - C[p, 0], d - C[p, 1]) - R[p])
        else:
            px = c - P0[p, 0]
            py = d - P0[p, 1]
            si = px * D0[p, 0] + py * D0[p, 1]
            li = px * D0[p, 1] - py * D0[p, 0]
        s[i] = si
        lat[i] = li
        Lr[i] = L[p]
        X[i] = 0.5 * L[p] - si
        dist[i] = box_half - si
    return Fl, In
