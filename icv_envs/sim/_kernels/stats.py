"""Run statistics, compiled: NumPy's pairwise summation, the motion and
headway statistics and the intersection's PET occupancy update (the rules
every kernel here follows: :mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["pairwise_sum", "motion_record", "motion_sums_add", "headway_record", "pet_transitions", "id_range"]


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
def motion_sums_add(k, n, sums, stopped, dt, vehicle_steps, speed_sum, realised, commanded, stopped_steps):
    """``k`` substeps' sums of :func:`motion_record` (``sums (k, 3)``:
    speeds, ``|dv|``, ``|commanded|``; ``stopped (k,)``; ``n`` vehicles
    each) added to the run's accumulators in substep order, as
    :meth:`icv_envs.sim.metrics.MotionStats.add` adds one substep's
    (``|dv| / dt``): the same additions of the same doubles. Returns the
    accumulators ``(vehicle_steps, speed_sum, realised, commanded,
    stopped_steps)``."""
    for f in range(k):
        vehicle_steps += n
        speed_sum += sums[f, 0]
        realised += sums[f, 1] / dt
        commanded += sums[f, 2]
        stopped_steps += stopped[f]
    return vehicle_steps, speed_sum, realised, commanded, stopped_steps


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
    occupied slots) and ``path`` (per id, its path) are updated in place.
    The candidates are merged from the two lists when both are ascending
    (the fleet's rows are sorted by id; from stop 48), else sorted and
    searched (``np.unique``, ``np.searchsorted``): the same candidates."""
    P, K = lo.shape
    m = 0
    keep = np.empty(vid.shape[0], dtype=np.int64)
    for i in range(vid.shape[0]):
        if pid[i] < P:
            keep[m] = i
            m += 1
    # the candidates: the listed ids and ``busy``, sorted, each once; both
    # lists ascending (the fleet's rows are sorted by id; ``busy`` is this
    # function's output): merged, else sorted and searched as until stop 47
    n_busy = busy.shape[0]
    ascending = True
    for q in range(1, m):
        if not vid[keep[q]] > vid[keep[q - 1]]:
            ascending = False
            break
    for q in range(1, n_busy):
        if not busy[q] > busy[q - 1]:
            ascending = False
            break
    at = np.empty(m, dtype=np.int64)  # the candidate of each listed vehicle
    if ascending:
        cand = np.empty(m + n_busy, dtype=np.int64)
        C = 0
        a = 0
        b = 0
        while a < m or b < n_busy:
            if b == n_busy or (a < m and vid[keep[a]] <= busy[b]):
                v = vid[keep[a]]
                if b < n_busy and busy[b] == v:
                    b += 1
                at[a] = C
                a += 1
            else:
                v = busy[b]
                b += 1
            cand[C] = v
            C += 1
        cand = cand[:C]
    else:
        ids = np.empty(m + n_busy, dtype=np.int64)
        for q in range(m):
            ids[q] = vid[keep[q]]
        ids[m:] = busy
        cand = np.unique(ids)
        C = cand.shape[0]
        for q in range(m):
            at[q] = np.searchsorted(cand, vid[keep[q]])
    new = np.zeros((C, K), dtype=np.bool_)
    for q in range(m):
        i = keep[q]
        c = at[q]
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
def id_range(vid):
    """``(vid.min(), vid.max())`` of a non-empty 1-D int64 array in one pass
    (two NumPy reductions cost ~1.5 us on a world's few dozen ids; one
    ``max`` ~0.8 us)."""
    lo = vid[0]
    hi = vid[0]
    for i in range(1, vid.shape[0]):
        v = vid[i]
        if v < lo:
            lo = v
        if v > hi:
            hi = v
    return lo, hi
