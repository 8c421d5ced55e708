"""Compiled inner loops of the simulation core (numba, ``@njit(cache=True)``).

What lives here: the loops that array operations cannot express without
Python-level iteration (the collision sweep, which stops at the first
sort-order offset with no pair in reach; the formation layer's segment
reductions and drivable-lane windows), and the per-step work whose cost was
the Python overhead of tens of small numpy calls rather than arithmetic
(issue 10): the fused physics substep (:func:`kinematic_substep`,
:func:`road_check`), the run statistics (:func:`motion_record`,
:func:`headway_record`), collision detection as a whole
(:func:`collision_pairs`), the lane-sorted index and leader search
(:func:`build_lane_index`, :func:`leader_rows`) and the observation's
neighbour search (:func:`nearest_along_road`). They take and return plain
arrays (no Python objects inside), and they perform the same IEEE-754
operations, in the same order, as the numpy code they replace (reductions
included: :func:`pairwise_sum` is NumPy's own summation order), so
trajectories stay bit-identical (``tests/test_trajectory_hash.py``; each
kernel is also tested against the numpy code it replaced in
``tests/test_kernels.py``). Floating-point reassociation (``fastmath``) is
off for the same reason.

Transcendental functions (``sin``, ``cos``, ``tan``, ``atan``) come from
libm here, as in NumPy's float64 loops up to AVX2 (``X86_V3``), the level
the reference fingerprints are pinned at. On an AVX-512 machine NumPy takes
``tan`` and ``atan`` from its SIMD library, which can round the last bit
differently; there the compiled substep's ``tan`` and ``atan`` are libm's
(as on an AVX2 machine), not NumPy's SIMD ones. On the development machine
(AVX-512) the 600 s ring run (HighwayRamps, formation method, VGR 1/3,
seed 0) gave identical run metrics before and after the change.

Why numba: the loops are short, data-dependent and branchy (early exits,
variable-length outputs), which is what a JIT compiles well and what numpy
vectorisation cannot do without materialising every candidate; ``cache=True``
keeps the compiled code on disk, so only the first import on a machine pays
the compile time (a few seconds). numba's cache does not hold recursive
functions, so :func:`pairwise_sum` runs its halving on an explicit stack.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["sweep_candidates", "segment_max", "drivable_lane_bits", "npy_mod", "kinematic_substep", "road_check",
           "pairwise_sum", "motion_record", "collision_pairs",
           "build_lane_index", "leader_rows", "headway_record",
           "nearest_along_road", "interval_ends", "pet_transitions",
           "lanes_available", "kinematics_rows"]


@nb.njit(cache=True)
def sweep_candidates(xs, ys, hxs, hys, reach):
    """Broad phase of :func:`icv_envs.sim.traffic.find_collisions` over
    vehicles sorted by ``xs``: pairs ``(a, a + k)`` whose axis-aligned
    bounding boxes overlap, for ``k = 1, 2, ...`` until no pair ``k`` places
    apart is closer in ``x`` than ``reach``. Returns the sorted positions
    ``a`` and the offsets ``k``, ordered by ``k`` then ``a``."""
    n = xs.shape[0]
    cap = 2 * n + 16
    out_a = np.empty(cap, dtype=np.int64)
    out_k = np.empty(cap, dtype=np.int64)
    m = 0
    for k in range(1, n):
        any_near = False
        for a in range(n - k):
            dx = xs[a + k] - xs[a]
            if dx < reach:
                any_near = True
                if dx < hxs[a + k] + hxs[a] and abs(ys[a + k] - ys[a]) < hys[a + k] + hys[a]:
                    if m == cap:
                        cap *= 2
                        na = np.empty(cap, dtype=np.int64)
                        nk = np.empty(cap, dtype=np.int64)
                        na[:m] = out_a[:m]
                        nk[:m] = out_k[:m]
                        out_a, out_k = na, nk
                    out_a[m] = a
                    out_k[m] = k
                    m += 1
        if not any_near:
            break
    return out_a[:m], out_k[:m]


@nb.njit(cache=True)
def segment_max(values, starts, ends):
    """``max(values[starts[g]:ends[g]])`` per segment (``-inf`` if empty)."""
    out = np.full(starts.shape[0], -np.inf)
    for g in range(starts.shape[0]):
        best = -np.inf
        for i in range(starts[g], ends[g]):
            if values[i] > best:
                best = values[i]
        out[g] = best
    return out


@nb.njit(cache=True)
def drivable_lane_bits(a, span, x0, x1, periodic, length, lane_ends, ob_lane, ob_lo, ob_hi, allowed):
    """Vectorised :meth:`icv_envs.sim.road.RoadLayout.drivable_main_lanes`
    over many windows, as bit sets (bit ``l`` set = lane ``l`` drivable
    over the whole window and in ``allowed``). On a ring, ``a`` is the
    window start folded onto the road and ``span`` its clipped length (both
    computed by the caller with numpy, as the scalar code does); on a
    straight road ``x0``/``x1`` are the window ends."""
    G = a.shape[0]
    n_lanes = lane_ends.shape[0]
    out = np.zeros(G, dtype=np.int64)
    p0s = np.empty(2)
    p1s = np.empty(2)
    for g in range(G):
        if periodic:
            if a[g] + span[g] <= length:
                npc = 1
                p0s[0] = a[g]
                p1s[0] = a[g] + span[g]
            else:
                npc = 2
                p0s[0] = a[g]
                p1s[0] = length
                p0s[1] = 0.0
                p1s[1] = a[g] + span[g] - length
        else:
            npc = 1
            lo = max(x0[g], 0.0)
            p0s[0] = lo
            p1s[0] = max(x1[g], lo)
        bits = 0
        for lane in range(n_lanes):
            if not allowed[lane]:
                continue
            ok = True
            for p in range(npc):
                if not lane_ends[lane] > p1s[p]:
                    ok = False
                    break
                for o in range(ob_lane.shape[0]):
                    if ob_lane[o] == lane and ob_hi[o] >= p0s[p] and ob_lo[o] <= p1s[p]:
                        ok = False
                        break
                if not ok:
                    break
            if ok:
                bits |= 1 << lane
        out[g] = bits
    return out


@nb.njit(cache=True, inline="always")
def npy_mod(a, b):
    """``numpy.mod`` of two floats, NumPy's own algorithm (``npy_divmod``):
    ``fmod`` then a shift by ``b`` when the signs differ, ``+0`` with the
    sign of ``b`` for an exact multiple."""
    m = np.fmod(a, b)
    if m != 0.0:
        if (b < 0.0) != (m < 0.0):
            m += b
    else:
        m = math.copysign(0.0, b)
    return m


@nb.njit(cache=True)
def kinematic_substep(x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase, lat_accel_max,
                      dt, v_max, period):
    """One forward-Euler step of the rear-axle kinematic bicycle model for
    every vehicle, fused (:meth:`icv_envs.sim.world.World.substep` with
    :meth:`icv_envs.sim.traffic.Traffic.step` and
    :func:`icv_envs.sim.traffic.limit_steering`, paper Sec. 2.2): a crashed
    vehicle brakes at -6 m/s^2 with the wheels straight; the steering angle
    is limited by the lateral acceleration ``v^2 tan(phi) / L <=
    lat_accel_max`` (``lat_accel_max < 0``: no limit); speed is kept in
    ``[0, v_max]``; ``x`` is folded onto a ring of length ``period``
    (``period <= 0``: no ring). Also the standing time (speed < 0.1 m/s)
    and the body centres of the new state (``wheelbase / 2`` ahead of the
    rear axle, ``cx`` folded on a ring), as :meth:`Traffic.center`.

    Returns ``(x, y, heading, speed, accel, steer, stopped_for, cx, cy)``
    as new arrays (the inputs are not touched)."""
    n = x.shape[0]
    nx = np.empty(n)
    ny = np.empty(n)
    nh = np.empty(n)
    nv = np.empty(n)
    na = np.empty(n)
    ns = np.empty(n)
    nst = np.empty(n)
    cx = np.empty(n)
    cy = np.empty(n)
    lat_wb = lat_accel_max * wheelbase
    half = 0.5 * wheelbase
    for i in range(n):
        a = accel[i]
        s = steer[i]
        if crashed[i]:
            a = -6.0
            s = 0.0
        v = speed[i]
        if lat_accel_max >= 0.0:
            v2 = max(v * v, 1e-9)
            pm = math.atan(lat_wb / v2)
            s = min(max(s, -pm), pm)
        h = heading[i]
        xi = x[i] + v * math.cos(h) * dt
        nyi = y[i] + v * math.sin(h) * dt
        hi = h + v * math.tan(s) / wheelbase * dt
        vi = min(max(v + a * dt, 0.0), v_max)
        if period > 0.0:
            xi = npy_mod(xi, period)
        nx[i] = xi
        ny[i] = nyi
        nh[i] = hi
        nv[i] = vi
        na[i] = a
        ns[i] = s
        nst[i] = stopped_for[i] + dt if vi < 0.1 else 0.0
        c = xi + half * math.cos(hi)
        if period > 0.0:
            c = npy_mod(c, period)
        cx[i] = c
        cy[i] = nyi + half * math.sin(hi)
    return nx, ny, nh, nv, na, ns, nst, cx, cy


@nb.njit(cache=True)
def road_check(cx, cy, lane_width, n_lanes, total_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, edge_margin,
               road_end):
    """Per vehicle: the lane whose centre is nearest
    (:meth:`icv_envs.sim.road.RoadLayout.lane_of`) and whether the body
    centre is off the drivable surface there: the lane is not available at
    ``cx`` (:meth:`RoadLayout.available`: a main lane past its end or inside
    an obstacle's interval, a ramp lane outside every ramp interval) or
    more than ``lane_width / 2 + edge_margin`` beside the lane centre.
    ``cx`` is already folded onto a ring. Also whether it has reached the
    end of a straight road (``cx >= road_end``; ``inf`` on a ring), and
    then it is not off the road. Returns ``(lane, off, at_end, n_off,
    n_at_end)``."""
    n = cx.shape[0]
    lane = np.empty(n, dtype=np.int64)
    off = np.empty(n, dtype=np.bool_)
    at_end = np.empty(n, dtype=np.bool_)
    n_off = 0
    n_end = 0
    for i in range(n):
        li = np.rint(cy[i] / lane_width)
        li = min(max(li, 0.0), total_lanes - 1.0)
        ln = np.int64(li)
        lane[i] = ln
        x = cx[i]
        ok = False
        if ln < n_lanes:
            ok = x >= 0.0 and x < lane_ends[ln]
            if ok:
                for o in range(ob_lane.shape[0]):
                    if ob_lane[o] == ln and x >= ob_lo[o] and x <= ob_hi[o]:
                        ok = False
                        break
        elif ln == n_lanes:
            for r in range(ramp_iv.shape[0]):
                if x >= ramp_iv[r, 0] and x <= ramp_iv[r, 1]:
                    ok = True
                    break
        o = (not ok) or abs(cy[i] - ln * lane_width) > 0.5 * lane_width + edge_margin
        e = x >= road_end
        at_end[i] = e
        off[i] = o and not e
        n_off += off[i]
        n_end += e
    return lane, off, at_end, n_off, n_end


@nb.njit(cache=True)
def _pairwise_leaf(a, lo, n):
    """NumPy's pairwise summation of ``a[lo:lo + n]`` for ``n <= 128``."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    m = n - (n % 8)
    while i < m:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@nb.njit(cache=True)
def pairwise_sum(a, lo, n):
    """``a[lo:lo + n].sum()`` by NumPy's own pairwise summation
    (``pairwise_sum_DOUBLE``: 8 accumulators in blocks of up to 128 values;
    above, the sum of the two halves split at a multiple of 8), so a
    compiled reduction rounds exactly as ``numpy.sum`` does. The halving
    recursion runs on an explicit stack (numba's on-disk cache does not
    hold recursive functions)."""
    if n <= 128:
        return _pairwise_leaf(a, lo, n)
    f_lo = np.empty(64, dtype=np.int64)
    f_n = np.empty(64, dtype=np.int64)
    f_phase = np.empty(64, dtype=np.int64)  # 0 start, 1 awaiting left, 2 left done, 3 awaiting right
    f_left = np.empty(64)
    sp = 0
    f_lo[0] = lo
    f_n[0] = n
    f_phase[0] = 0
    while True:
        l0 = f_lo[sp]
        m = f_n[sp]
        n2 = m // 2
        n2 -= n2 % 8
        if f_phase[sp] == 0:
            f_phase[sp] = 1
            cl, cn = l0, n2
        else:  # phase 2
            f_phase[sp] = 3
            cl, cn = l0 + n2, m - n2
        if cn > 128:
            sp += 1
            f_lo[sp] = cl
            f_n[sp] = cn
            f_phase[sp] = 0
            continue
        v = _pairwise_leaf(a, cl, cn)
        while True:  # hand the finished sum up the stack
            if f_phase[sp] == 1:
                f_left[sp] = v
                f_phase[sp] = 2
                break
            v = f_left[sp] + v
            if sp == 0:
                return v
            sp -= 1


@nb.njit(cache=True)
def motion_record(vid, v0, v1, commanded, stopped_speed, count, s1, s2):
    """One substep of :meth:`icv_envs.sim.metrics.MotionStats.record`: the
    per-vehicle speed moments ``count[vid] += 1``, ``s1[vid] += v1``,
    ``s2[vid] += v1^2`` (in place, in row order), and the sums of ``v1``,
    ``|v1 - v0|`` and ``|commanded|`` (NumPy's pairwise order), the count
    of ``v1 < stopped_speed`` and the largest id. Nothing is accumulated
    when an id is negative (the count is -1, then the id) or beyond the
    arrays (-2, then the largest id)."""
    n = vid.shape[0]
    dv = np.empty(n)
    ac = np.empty(n)
    stopped = 0
    top = -1
    for i in range(n):
        if vid[i] < 0:  # the caller raises
            return 0.0, 0.0, 0.0, -1, vid[i]
        top = max(top, vid[i])
    if top >= count.shape[0]:  # the caller grows the arrays and calls again
        return 0.0, 0.0, 0.0, -2, top
    for i in range(n):
        v = v1[i]
        dv[i] = abs(v - v0[i])
        ac[i] = abs(commanded[i])
        if v < stopped_speed:
            stopped += 1
        k = vid[i]
        count[k] += 1
        s1[k] += v
        s2[k] += v * v
    return pairwise_sum(v1, 0, n), pairwise_sum(dv, 0, n), pairwise_sum(ac, 0, n), stopped, top


@nb.njit(cache=True, inline="always")
def _rect_overlap(c1x, c1y, h1, l1, w1, c2x, c2y, h2, l2, w2):
    """:func:`icv_envs.sim.traffic.rect_overlap` for one pair (same operations)."""
    dx = c2x - c1x
    dy = c2y - c1y
    u1x = math.cos(h1)
    u1y = math.sin(h1)
    u2x = math.cos(h2)
    u2y = math.sin(h2)
    for k in range(4):
        if k == 0:
            ax, ay = u1x, u1y
        elif k == 1:
            ax, ay = -u1y, u1x
        elif k == 2:
            ax, ay = u2x, u2y
        else:
            ax, ay = -u2y, u2x
        d = abs(dx * ax + dy * ay)
        r1 = 0.5 * l1 * abs(ax * u1x + ay * u1y) + 0.5 * w1 * abs(-ax * u1y + ay * u1x)
        r2 = 0.5 * l2 * abs(ax * u2x + ay * u2y) + 0.5 * w2 * abs(-ax * u2y + ay * u2x)
        if not d < r1 + r2:
            return False
    return True


@nb.njit(cache=True)
def _collision_pairs_line(cx, cy, heading, length, width):
    n = cx.shape[0]
    hx = np.empty(n)
    hy = np.empty(n)
    for q in range(n):
        c = abs(math.cos(heading[q]))
        s = abs(math.sin(heading[q]))
        hx[q] = 0.5 * (length[q] * c + width[q] * s)
        hy[q] = 0.5 * (length[q] * s + width[q] * c)
    order = np.argsort(cx, kind="mergesort")
    xs = cx[order]
    ys = cy[order]
    hxs = hx[order]
    hys = hy[order]
    reach = 2.0 * hxs.max()
    a, k = sweep_candidates(xs, ys, hxs, hys, reach)
    out_i = np.empty(a.shape[0], dtype=np.int64)
    out_j = np.empty(a.shape[0], dtype=np.int64)
    m = 0
    for p in range(a.shape[0]):
        i = order[a[p]]
        j = order[a[p] + k[p]]
        if _rect_overlap(cx[i], cy[i], heading[i], length[i], width[i], cx[j], cy[j], heading[j], length[j],
                         width[j]):
            out_i[m] = i
            out_j[m] = j
            m += 1
    return out_i[:m], out_j[:m]


@nb.njit(cache=True)
def collision_pairs(cx, cy, heading, length, width, period):
    """:func:`icv_envs.sim.traffic.find_collisions` compiled whole: the
    sweep-and-prune broad phase over the x order (stable sort), the
    separating-axis test on the candidates, and on a ring (``period > 0``)
    the ghosts one lap on of the vehicles near the seam, with the pairs
    mapped back to rows, deduplicated as ``(min, max)`` and sorted. Same
    pairs in the same order as the numpy code."""
    n = cx.shape[0]
    if n < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if period > 0.0:
        lim = 2.0 * length.max() + 1.0
        nn = 0
        for q in range(n):
            if cx[q] < lim:
                nn += 1
        if nn:
            idx = np.empty(n + nn, dtype=np.int64)
            ex = np.empty(n + nn)
            for q in range(n):
                idx[q] = q
                ex[q] = cx[q]
            p = n
            for q in range(n):
                if cx[q] < lim:
                    idx[p] = q
                    ex[p] = cx[q] + period
                    p += 1
            gi, gj = _collision_pairs_line(ex, cy[idx], heading[idx], length[idx], width[idx])
            keys = np.empty(gi.shape[0], dtype=np.int64)
            m = 0
            for p in range(gi.shape[0]):
                a = idx[gi[p]]
                b = idx[gj[p]]
                if a != b:
                    keys[m] = min(a, b) * n + max(a, b)
                    m += 1
            keys = np.unique(keys[:m])
            return keys // n, keys % n
    return _collision_pairs_line(cx, cy, heading, length, width)


@nb.njit(cache=True)
def build_lane_index(cx, cy, width, length, heading, footprint, lane_width, n_lanes, reserved_lane, periodic,
                     road_length, ghost):
    """:func:`icv_envs.sim.traffic.lane_index` compiled: the (row, lane)
    pairs of :func:`~icv_envs.sim.traffic.occupied_lanes` (offsets -1, 0, +1
    from the nearest lane, each pass in row order; the rotated footprint
    when ``footprint``), then the reserved lanes not already listed
    (``reserved_lane[i]`` in ``[0, n_lanes)``; an empty array for none),
    then on a ring the ghosts within ``ghost`` of the seam, sorted by
    ``key = lane * offset + x`` (stable). Returns ``(keys, rows, lanes, x,
    offset)``, the fields of :class:`~icv_envs.sim.traffic.LaneIndex`."""
    n = cx.shape[0]
    cap = 3 * n + n
    rows = np.empty(cap, dtype=np.int64)
    lanes = np.empty(cap, dtype=np.int64)
    base = np.empty(n, dtype=np.int64)
    reach = np.empty(n)
    for i in range(n):
        base[i] = np.int64(np.rint(cy[i] / lane_width))
        if footprint:
            half = 0.5 * (length[i] * abs(math.sin(heading[i])) + width[i] * abs(math.cos(heading[i])))
        else:
            half = 0.5 * width[i]
        reach[i] = 0.5 * lane_width + half - 0.0
    m = 0
    for d in (-1, 0, 1):
        for i in range(n):
            lane = base[i] + d
            if lane >= 0 and lane < n_lanes and abs(cy[i] - lane * lane_width) < reach[i]:
                rows[m] = i
                lanes[m] = lane
                m += 1
    m_occ = m
    for i in range(reserved_lane.shape[0]):
        r = reserved_lane[i]
        if r >= 0 and r < n_lanes:
            dup = False
            for q in range(m_occ):
                if rows[q] == i and lanes[q] == r:
                    dup = True
                    break
            if not dup:
                rows[m] = i
                lanes[m] = r
                m += 1
    xs = np.empty(m)
    for q in range(m):
        xs[q] = cx[rows[q]]
    if periodic and m:
        L = road_length
        g = min(ghost, 0.5 * L)
        n_lo = 0
        n_hi = 0
        for q in range(m):
            if xs[q] < g:
                n_lo += 1
            if xs[q] > L - g:
                n_hi += 1
        tot = m + n_lo + n_hi
        r2 = np.empty(tot, dtype=np.int64)
        l2 = np.empty(tot, dtype=np.int64)
        x2 = np.empty(tot)
        r2[:m] = rows[:m]
        l2[:m] = lanes[:m]
        x2[:m] = xs
        p = m
        for q in range(m):
            if xs[q] < g:
                r2[p] = rows[q]
                l2[p] = lanes[q]
                x2[p] = xs[q] + L
                p += 1
        for q in range(m):
            if xs[q] > L - g:
                r2[p] = rows[q]
                l2[p] = lanes[q]
                x2[p] = xs[q] - L
                p += 1
        rows_f, lanes_f, xs_f = r2, l2, x2
    else:
        rows_f, lanes_f, xs_f = rows[:m].copy(), lanes[:m].copy(), xs
    offset = 4.0 * (abs(road_length) + 1e4)
    k = rows_f.shape[0]
    keys = np.empty(k)
    for q in range(k):
        keys[q] = lanes_f[q] * offset + xs_f[q]
    order = np.argsort(keys, kind="mergesort")
    return keys[order], rows_f[order], lanes_f[order], xs_f[order], offset


@nb.njit(cache=True)
def leader_rows(keys, i_rows, i_lanes, i_x, offset, q_rows, q_lanes, cx):
    """:func:`icv_envs.sim.traffic.leaders` compiled: per query, the first
    entry at or after ``q_lane * offset + cx[q_row]`` in the index that is
    in the query's lane and is not the vehicle itself (its own entry is
    skipped; at most 3 entries are looked at, as in the numpy code).
    Returns the leader rows (-1: none) and their unfolded positions
    (``inf``: none)."""
    nq = q_rows.shape[0]
    out = np.full(nq, -1, dtype=np.int64)
    xo = np.full(nq, np.inf)
    nk = keys.shape[0]
    if nk == 0:
        return out, xo
    for q in range(nq):
        ql = q_lanes[q]
        qr = q_rows[q]
        pos = np.searchsorted(keys, ql * offset + cx[qr])
        for j in range(3):
            p = pos + j
            if p >= nk or i_lanes[p] != ql:
                break
            if i_rows[p] != qr:
                out[q] = i_rows[p]
                xo[q] = i_x[p]
                break
    return out, xo


@nb.njit(cache=True)
def headway_record(gap, v, hist, bin_width, stopped_speed):
    """One call of :meth:`icv_envs.sim.metrics.HeadwayStats.record`: the
    smallest finite ``gap`` (``inf``: none), the smallest time headway
    ``max(gap, 0) / v`` over the vehicles with a leader moving at least
    ``stopped_speed`` (``inf``: none), their count; each of those headways
    is added to ``hist`` (in place) in bin ``min(int(th / bin_width),
    len(hist) - 1)``."""
    g_min = np.inf
    th_min = np.inf
    count = 0
    last = hist.shape[0] - 1
    for i in range(gap.shape[0]):
        g = gap[i]
        if not np.isfinite(g):
            continue
        if g < g_min:
            g_min = g
        if v[i] >= stopped_speed:
            th = max(g, 0.0) / v[i]
            if th < th_min:
                th_min = th
            hist[min(np.int64(th / bin_width), last)] += 1
            count += 1
    return g_min, th_min, count


@nb.njit(cache=True)
def nearest_along_road(cx, rows, K, pd, periodic, length):
    """The observation's neighbour search
    (:meth:`icv_envs.envs.highway_formation.HighwayFormationEnv._neighbours`)
    compiled: for each query row, the ``K`` vehicles nearest by
    longitudinal distance among the ``K`` before and ``K`` after it in the
    x order (stable), within ``pd`` (round a ring of ``length`` each vehicle
    at most once), nearest first, ties by candidate order (rear first).
    Returns ``(sel, present)`` of shape ``(len(rows), K)``; absent slots
    hold a candidate row and ``present`` False."""
    n = cx.shape[0]
    m = rows.shape[0]
    order = np.argsort(cx, kind="mergesort")
    rank = np.empty(n, dtype=np.int64)
    for q in range(n):
        rank[order[q]] = q
    C = 2 * K
    offs = np.empty(C, dtype=np.int64)
    for q in range(K):
        offs[q] = q - K
        offs[K + q] = q + 1
    sel = np.empty((m, K), dtype=np.int64)
    present = np.empty((m, K), dtype=np.bool_)
    cand = np.empty(C, dtype=np.int64)
    dist = np.empty(C)
    half = 0.5 * length
    lim_lo = (n - 1) // 2
    lim_hi = (n - 1) // 2 + (n - 1) % 2
    for r in range(m):
        row = rows[r]
        x0 = cx[row]
        for c in range(C):
            o = offs[c]
            cr = rank[row] + o
            if periodic:
                valid = abs(o) <= (lim_hi if o > 0 else lim_lo)
                cr = cr % n
            else:
                valid = cr >= 0 and cr < n
            cand[c] = order[min(max(cr, 0), n - 1)]
            d = cx[cand[c]] - x0
            if periodic:
                d = npy_mod(d + half, length) - half
            d = abs(d)
            dist[c] = d if (valid and d < pd) else np.inf
        pick = np.argsort(dist, kind="mergesort")
        for q in range(K):
            sel[r, q] = cand[pick[q]]
            present[r, q] = np.isfinite(dist[pick[q]])
    return sel, present


@nb.njit(cache=True)
def interval_ends(lane, x, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv):
    """:meth:`icv_envs.sim.road.RoadLayout._interval_end` compiled, over
    flat arrays: where the drivable stretch of ``lane`` containing (or
    following) ``x`` ends. A main lane: its end, or the rear of the
    nearest obstacle in it whose front is at or ahead of ``x``, whichever
    comes first; the ramp lane (``n_lanes``): the end of the first ramp
    interval whose end is at or ahead of ``x`` (``inf`` if none, ``-inf``
    without ramps); any other lane: ``-inf``."""
    n = lane.shape[0]
    out = np.empty(n)
    for i in range(n):
        ln = lane[i]
        xi = x[i]
        if ln >= 0 and ln < n_lanes:
            cand = np.inf
            for o in range(ob_lane.shape[0]):
                if ob_lane[o] == ln and ob_hi[o] >= xi and ob_lo[o] < cand:
                    cand = ob_lo[o]
            e = lane_ends[ln]
            out[i] = e if e <= cand else cand
        elif ln == n_lanes and ramp_iv.shape[0]:
            cand = np.inf
            for r in range(ramp_iv.shape[0]):
                if ramp_iv[r, 1] >= xi and ramp_iv[r, 1] < cand:
                    cand = ramp_iv[r, 1]
            out[i] = cand
        else:
            out[i] = -np.inf
    return out


@nb.njit(cache=True)
def pet_transitions(vid, pid, s, length, lo, hi, occ, path, busy):
    """The occupancy update of
    :meth:`icv_envs.sim.intersection_metrics.PetStats.record`, compiled:
    vehicles ``vid`` on paths ``pid`` (rows of ``lo``/``hi``, the conflict
    areas' extents along each path; larger ids are skipped) at route
    coordinate ``s`` occupy the areas their body ``[s - length/2, s +
    length/2]`` overlaps (open intervals). Over the candidate ids (the
    listed vehicles and ``busy``, those inside an area until now, sorted)
    it returns the slots left, then the slots entered, each as ``(path,
    slot)`` pairs in increasing (id, slot) order (the left ones on their
    previous path), and the new ``busy``; the tables ``occ`` (per id, its
    occupied slots) and ``path`` (per id, its path) are updated in place."""
    P, K = lo.shape
    m = 0
    keep = np.empty(vid.shape[0], dtype=np.int64)
    for i in range(vid.shape[0]):
        if pid[i] < P:
            keep[m] = i
            m += 1
    ids = np.empty(m + busy.shape[0], dtype=np.int64)
    for q in range(m):
        ids[q] = vid[keep[q]]
    ids[m:] = busy
    cand = np.unique(ids)
    C = cand.shape[0]
    new = np.zeros((C, K), dtype=np.bool_)
    for q in range(m):
        i = keep[q]
        c = np.searchsorted(cand, vid[i])
        x = s[i]
        h = 0.5 * length[i]
        p = pid[i]
        for k in range(K):
            new[c, k] = (x - h < hi[p, k]) and (x + h > lo[p, k])
    prev = np.empty(C, dtype=np.int64)
    for c in range(C):
        prev[c] = path[cand[c]]
    for q in range(m):
        path[vid[keep[q]]] = pid[keep[q]]
    n_l = 0
    n_e = 0
    for c in range(C):
        for k in range(K):
            o = occ[cand[c], k]
            if o and not new[c, k]:
                n_l += 1
            elif new[c, k] and not o:
                n_e += 1
    left = np.empty((n_l, 2), dtype=np.int64)
    entered = np.empty((n_e, 2), dtype=np.int64)
    a = 0
    b = 0
    nb_ = 0
    new_busy = np.empty(C, dtype=np.int64)
    for c in range(C):
        v = cand[c]
        any_new = False
        for k in range(K):
            o = occ[v, k]
            if o and not new[c, k]:
                left[a, 0] = prev[c]
                left[a, 1] = k
                a += 1
            elif new[c, k] and not o:
                entered[b, 0] = path[v]
                entered[b, 1] = k
                b += 1
            occ[v, k] = new[c, k]
            any_new = any_new or new[c, k]
        if any_new:
            new_busy[nb_] = v
            nb_ += 1
    return left, entered, new_busy[:nb_]


@nb.njit(cache=True)
def lanes_available(lane, x, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv):
    """:meth:`icv_envs.sim.road.RoadLayout.available` compiled, over flat
    arrays (``x`` already folded onto a ring): a main lane from 0 to its end,
    outside every obstacle's closed interval in it; the ramp lane
    (``n_lanes``) inside a ramp interval (closed); any other lane never."""
    n = lane.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        ln = lane[i]
        xi = x[i]
        if ln >= 0 and ln < n_lanes:
            ok = xi >= 0.0 and xi < lane_ends[ln]
            if ok:
                for o in range(ob_lane.shape[0]):
                    if ob_lane[o] == ln and xi >= ob_lo[o] and xi <= ob_hi[o]:
                        ok = False
                        break
            out[i] = ok
        elif ln == n_lanes:
            for r in range(ramp_iv.shape[0]):
                if xi >= ramp_iv[r, 0] and xi <= ramp_iv[r, 1]:
                    out[i] = True
                    break
    return out


@nb.njit(cache=True)
def kinematics_rows(F, rows, sel, present, idx, V, s_abs, s_rel, absolute, normalize, clip, period):
    """The ``Kinematics`` observation
    (:meth:`icv_envs.envs.observations.Kinematics.observe_rows`) compiled:
    row 0 the observer's own features (``F[rows]``), rows ``1..K`` its
    neighbours ``sel`` (zeros where not ``present``); unless ``absolute``,
    a neighbour's x, y, vx, vy (columns 1-4) relative to the observer's,
    its dx folded round a ring of length ``period`` (``period <= 0``: no
    ring); with ``normalize`` divided by ``s_abs`` (own row, absolute) or
    ``s_rel``, with ``clip`` clipped to [-1, 1]; the columns ``idx``, as
    float32 in a ``(len(rows), V, len(idx))`` array (slots past ``K``
    zeros). The same float64 operations as the array code, then one
    rounding to float32."""
    m = rows.shape[0]
    J = idx.shape[0]
    K = sel.shape[1]
    out = np.zeros((m, V, J), dtype=np.float32)
    half = 0.5 * period
    for r in range(m):
        o = rows[r]
        for j in range(J):
            val = F[o, idx[j]]
            if normalize:
                val = val / s_abs[idx[j]]
                if clip:
                    val = min(max(val, -1.0), 1.0)
            out[r, 0, j] = val
        for q in range(K):
            if not present[r, q]:
                continue
            c = sel[r, q]
            for j in range(J):
                f = idx[j]
                val = F[c, f]
                if not absolute:
                    if f >= 1 and f <= 4:
                        val = val - F[o, f]
                    if f == 1 and period > 0.0:
                        val = npy_mod(val + half, period) - half
                if normalize:
                    val = val / (s_abs[f] if absolute else s_rel[f])
                    if clip:
                        val = min(max(val, -1.0), 1.0)
                out[r, 1 + q, j] = val
    return out
