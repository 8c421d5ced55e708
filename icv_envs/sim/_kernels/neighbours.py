"""Who is near whom, compiled: the collision sweep and the whole
collision detection, the lane-sorted index and its leader search (the
rules every kernel here follows: :mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.sim._kernels.physics import lane_of1
from icv_envs.sim._kernels.stats import headway_record

__all__ = ["own_lane_gap_rows", "sweep_candidates", "collision_pairs", "collision_pairs_cs", "collision_pairs_kept",
           "stable_order", "build_lane_index", "build_lane_index_pair",
           "leader_entries", "leader_rows", "lane_gap_pass"]


@nb.njit(cache=True)
def sweep_candidates(xs, ys, hxs, hys, reach):
    """Broad phase of :func:`icv_envs.sim.traffic.find_collisions` over
    vehicles sorted by ``xs``: pairs ``(a, a + k)`` closer in ``x`` than
    ``reach`` whose axis-aligned bounding boxes overlap. Returns the sorted
    positions ``a`` and the offsets ``k``, ordered by ``k`` then ``a``.

    Each ``a`` is compared with the vehicles after it until the first one
    ``reach`` or more ahead: ``xs[a + k] - xs[a]`` never decreases with
    ``k`` (rounding is monotone; NaN sorts last and compares false), so this
    visits every pair the former pass over ``k = 1, 2, ...`` (until no pair
    ``k`` places apart was in reach) visited, in O(n + pairs in reach)
    instead of O(n k_max): one dense cluster anywhere on the road (a
    formation four lanes wide) made every ``k`` pass cover the whole road
    (442 vehicles on the ring: 30-32 us -> 2.8 us per substep). The pairs
    are then put in the former order (a stable sort by ``k``)."""
    n = xs.shape[0]
    cap = 2 * n + 16
    out_a = np.empty(cap, dtype=np.int64)
    out_k = np.empty(cap, dtype=np.int64)
    m = 0
    for a in range(n):
        xa = xs[a]
        for b in range(a + 1, n):
            dx = xs[b] - xa
            if not dx < reach:
                break
            if dx < hxs[b] + hxs[a] and abs(ys[b] - ys[a]) < hys[b] + hys[a]:
                if m == cap:
                    cap *= 2
                    na = np.empty(cap, dtype=np.int64)
                    nk = np.empty(cap, dtype=np.int64)
                    na[:m] = out_a[:m]
                    nk[:m] = out_k[:m]
                    out_a, out_k = na, nk
                out_a[m] = a
                out_k[m] = b - a
                m += 1
    out_a = out_a[:m]
    out_k = out_k[:m]
    if m > 1:
        o = np.argsort(out_k, kind="mergesort")
        return out_a[o], out_k[o]
    return out_a, out_k


@nb.njit(cache=True, inline="always")
def _rect_overlap_cs(c1x, c1y, u1x, u1y, l1, w1, c2x, c2y, u2x, u2y, l2, w2):
    """:func:`icv_envs.sim.traffic.rect_overlap` for one pair (same
    operations), from the headings' cosines ``u1x``, ``u2x`` and sines
    ``u1y``, ``u2y``."""
    dx = c2x - c1x
    dy = c2y - c1y
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
def cos_sin(heading):
    """``math.cos`` and ``math.sin`` of each heading (libm's, as every
    kernel here calls them), as two arrays."""
    n = heading.shape[0]
    ch = np.empty(n)
    sh = np.empty(n)
    for q in range(n):
        ch[q] = math.cos(heading[q])
        sh[q] = math.sin(heading[q])
    return ch, sh


@nb.njit(cache=True)
def stable_order(x, order):
    """``np.argsort(x, kind="mergesort")`` (ascending, ties by index, NaN
    last) from ``order``, a permutation of ``x``'s indices, sorted in place
    by insertion when ``x`` holds no NaN (linear when ``order`` was sorted
    a frame before: vehicles overtake few others in one frame), else
    NumPy's sort. Returns the sorted order (``order`` itself, or a new
    array when its length is not ``x``'s)."""
    n = x.shape[0]
    if order.shape[0] != n:
        return np.argsort(x, kind="mergesort")
    for q in range(n):
        if x[q] != x[q]:
            return np.argsort(x, kind="mergesort")
    for p in range(1, n):
        a = order[p]
        v = x[a]
        t = p
        while t > 0:
            b = order[t - 1]
            if x[b] > v or (x[b] == v and b > a):
                order[t] = b
                t -= 1
            else:
                break
        order[t] = a
    return order


@nb.njit(cache=True)
def _collision_pairs_line_order(cx, cy, ch, sh, length, width, order):
    """The sweep and the separating-axis test of :func:`collision_pairs`
    along one line, from the headings' cosines ``ch`` and sines ``sh``
    (the physics frames have them from the integration, from stop 43) and
    the stable order along ``cx`` (:func:`stable_order`'s:
    ``np.argsort(cx, kind="mergesort")``)."""
    n = cx.shape[0]
    hx = np.empty(n)
    hy = np.empty(n)
    for q in range(n):
        c = abs(ch[q])
        s = abs(sh[q])
        hx[q] = 0.5 * (length[q] * c + width[q] * s)
        hy[q] = 0.5 * (length[q] * s + width[q] * c)
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
        if _rect_overlap_cs(cx[i], cy[i], ch[i], sh[i], length[i], width[i], cx[j], cy[j], ch[j], sh[j], length[j],
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
    ch, sh = cos_sin(heading)
    return collision_pairs_cs(cx, cy, ch, sh, length, width, period)


@nb.njit(cache=True)
def collision_pairs_cs(cx, cy, ch, sh, length, width, period):
    """:func:`collision_pairs` from the headings' cosines ``ch`` and sines
    ``sh`` (``math.cos``/``math.sin`` of the headings: the same pairs)."""
    i, j, _, _ = collision_pairs_kept(cx, cy, ch, sh, length, width, period, np.zeros(0, dtype=np.int64),
                                      np.zeros(0, dtype=np.int64))
    return i, j


@nb.njit(cache=True)
def collision_pairs_kept(cx, cy, ch, sh, length, width, period, order, ghosts):
    """:func:`collision_pairs_cs` given the stable order along ``x`` of the
    frame before (``order``, over the rows and on a ring their ghosts, and
    ``ghosts``, the rows that had one; empty arrays the first time): the
    rows are sorted from it (:func:`stable_order`) when they and the ghosts
    are the same, else by NumPy's sort; the same order either way (the
    insertion sort gives it from any permutation; the test only spares it
    a start far from sorted), so the same pairs in the same order (from
    stop 48; :func:`~icv_envs.sim._kernels.frames.quiet_substeps` keeps
    them from frame to frame: at 440 vehicles NumPy's sort costs about 6
    us a frame, the insertion sort 0.6). Returns ``(i, j, order, ghosts)``."""
    n = cx.shape[0]
    if n < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), order, ghosts
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
            g = idx[n:].copy()
            same = g.shape[0] == ghosts.shape[0]
            if same:
                for q in range(g.shape[0]):
                    if g[q] != ghosts[q]:
                        same = False
                        break
            order = stable_order(ex, order if same else np.zeros(0, dtype=np.int64))
            gi, gj = _collision_pairs_line_order(ex, cy[idx], ch[idx], sh[idx], length[idx], width[idx], order)
            keys = np.empty(gi.shape[0], dtype=np.int64)
            m = 0
            for p in range(gi.shape[0]):
                a = idx[gi[p]]
                b = idx[gj[p]]
                if a != b:
                    keys[m] = min(a, b) * n + max(a, b)
                    m += 1
            keys = np.unique(keys[:m])
            return keys // n, keys % n, order, g
    order = stable_order(cx, order if ghosts.shape[0] == 0 else np.zeros(0, dtype=np.int64))
    i, j = _collision_pairs_line_order(cx, cy, ch, sh, length, width, order)
    return i, j, order, np.zeros(0, dtype=np.int64)


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
    for i in range(reserved_lane.shape[0]):
        r = reserved_lane[i]
        if r >= 0 and r < n_lanes:
            # already listed by the passes above: one of the lanes base-1..base+1
            # that the body reaches (their test, not a search of the list)
            dup = r - base[i] >= -1 and r - base[i] <= 1 and abs(cy[i] - r * lane_width) < reach[i]
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
def build_lane_index_pair(cx, cy, width, length, heading, footprint, lane_width, n_lanes, reserved_lane, periodic,
                          road_length, ghost):
    """Both views of :func:`build_lane_index` in one call: the body-only
    one (no reserved lanes) and the one with ``reserved_lane``, each
    exactly as its own call builds it. Returns the two ``(keys, rows,
    lanes, x)`` and the common ``offset``."""
    k0, r0, l0, x0, offset = build_lane_index(cx, cy, width, length, heading, footprint, lane_width, n_lanes,
                                              reserved_lane[:0], periodic, road_length, ghost)
    k1, r1, l1, x1, _ = build_lane_index(cx, cy, width, length, heading, footprint, lane_width, n_lanes,
                                         reserved_lane, periodic, road_length, ghost)
    return k0, r0, l0, x0, k1, r1, l1, x1, offset


@nb.njit(cache=True)
def leader_entries(keys, i_rows, i_lanes, offset, q_lanes, q_rows, q_x):
    """The index entry of each query's leader: for query ``q``, row
    ``q_rows[q]`` in lane ``q_lanes[q]`` from position ``q_x[q]``, the first
    entry at or after ``q_lane * offset + q_x`` that is in that lane and is
    not the row itself (at most 3 entries looked at, as in the numpy code
    of :func:`icv_envs.sim.traffic.leaders`), or -1.

    One call for all queries, so that :func:`leader_rows`,
    :func:`own_lane_gap_rows` and the expert's lane-change test share one
    copy of the rule. (Unlike the road's rules,
    ``sim/_kernels/physics.lanes_available``, this one was not slow as a
    per-query helper: ``own_lane_gap_rows`` went 50 -> 46 us at 440
    vehicles; the binary search is its cost.)"""
    nk = keys.shape[0]
    nq = q_rows.shape[0]
    out = np.full(nq, -1, dtype=np.int64)
    if nk == 0:
        return out
    for q in range(nq):
        ql = q_lanes[q]
        qr = q_rows[q]
        pos = np.searchsorted(keys, ql * offset + q_x[q])
        for j in range(3):
            p = pos + j
            if p >= nk or i_lanes[p] != ql:
                break
            if i_rows[p] != qr:
                out[q] = p
                break
    return out


@nb.njit(cache=True)
def leader_rows(keys, i_rows, i_lanes, i_x, offset, q_rows, q_lanes, cx):
    """:func:`icv_envs.sim.traffic.leaders` compiled: per query, the leader
    entry of :func:`leader_entries` from ``cx[q_row]``. Returns the leader
    rows (-1: none) and their unfolded positions (``inf``: none)."""
    nq = q_rows.shape[0]
    out = np.full(nq, -1, dtype=np.int64)
    xo = np.full(nq, np.inf)
    if keys.shape[0] == 0:
        return out, xo
    qx = np.empty(nq)
    for q in range(nq):
        qx[q] = cx[q_rows[q]]
    ent = leader_entries(keys, i_rows, i_lanes, offset, q_lanes, q_rows, qx)
    for q in range(nq):
        p = ent[q]
        if p >= 0:
            out[q] = i_rows[p]
            xo[q] = i_x[p]
    return out, xo


@nb.njit(cache=True)
def own_lane_gap_rows(keys, i_rows, i_lanes, i_x, offset, cx, cy, length, lane_width, total_lanes):
    """:meth:`icv_envs.sim.world.World.own_lane_gaps` compiled: each
    vehicle's own lane (:meth:`~icv_envs.sim.road.RoadLayout.lane_of`:
    ``rint(cy / lane_width)`` clipped to ``[0, total_lanes - 1]``), its
    leader there (:func:`leader_rows`) and the bumper-to-bumper gap
    ``x_lead - cx - 0.5 (length_lead + length)`` (``inf``, row -1: none)."""
    n = cx.shape[0]
    gap = np.full(n, np.inf)
    lead = np.full(n, -1, dtype=np.int64)
    if keys.shape[0] == 0:
        return gap, lead
    own = np.empty(n, dtype=np.int64)
    for q in range(n):
        own[q] = lane_of1(cy[q], lane_width, total_lanes)
    ent = leader_entries(keys, i_rows, i_lanes, offset, own, np.arange(n), cx)
    for q in range(n):
        p = ent[q]
        if p >= 0:
            r = i_rows[p]
            lead[q] = r
            gap[q] = i_x[p] - cx[q] - 0.5 * (length[r] + length[q])
    return gap, lead


@nb.njit(cache=True)
def lane_gap_pass(cx, cy, width, length, heading, lane_width, n_lanes, periodic, road_length, ghost, speed, hist,
                  bin_width, stopped_speed):
    """The first lane-index query of a policy step, when nobody holds a
    reservation (from stop 43, ``World.record_min_gap``): the body-only
    index (:func:`build_lane_index` with the footprint, no reserved lanes,
    over ``n_lanes``: the road's total lanes), each vehicle's own-lane gap
    and leader (:func:`own_lane_gap_rows` on that index, the same lanes)
    and the headway statistics' record of the gaps
    (:func:`~icv_envs.sim._kernels.stats.headway_record`, ``hist`` updated
    in place): the three calls the world made one after the other, with the
    same arguments, in one. Returns ``(keys, xs, I, offset, gap, lead,
    g_min, th_min, count)``, ``I`` the index's rows and lanes as the rows
    of one ``(2, m)`` array (numba boxes each returned array for about
    0.35 us)."""
    keys, rows, lanes, xs, offset = build_lane_index(cx, cy, width, length, heading, True, lane_width, n_lanes,
                                                     np.zeros(0, dtype=np.int64), periodic, road_length, ghost)
    gap, lead = own_lane_gap_rows(keys, rows, lanes, xs, offset, cx, cy, length, lane_width, n_lanes)
    g_min, th_min, count = headway_record(gap, speed, hist, bin_width, stopped_speed)
    I = np.empty((2, rows.shape[0]), dtype=np.int64)
    I[0] = rows
    I[1] = lanes
    return keys, xs, I, offset, gap, lead, g_min, th_min, count
