"""The observations' inner loops, compiled: the neighbour search along
the road, the ``Kinematics`` rows, and the highway env's feature rows and
reward terms (the rules every kernel here follows:
:mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.formation._kernels import clip1
from icv_envs.sim._kernels.formation import _wrap1
from icv_envs.sim._kernels.physics import interval_ends_at, lane_of1, npy_mod

__all__ = ["nearest_along_road", "nearest_euclidean", "corridor_leaders", "kinematics_rows", "formation_feature_rows",
           "formation_reward_terms", "formation_reward_total", "formation_post_rows", "intersection_feature_rows",
           "intersection_reward_rows", "intersection_post_rows"]


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
    pick = np.empty(C, dtype=np.int64)
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
                if cr < 0 or cr >= n:  # (Python's modulo, only where it changes cr)
                    cr = cr % n
            else:
                valid = cr >= 0 and cr < n
            cand[c] = order[min(max(cr, 0), n - 1)]
            d = cx[cand[c]] - x0
            if periodic:
                d = npy_mod(d + half, length) - half
            d = abs(d)
            dist[c] = d if (valid and d < pd) else np.inf
        # a stable sort of the 2K distances by insertion: np.argsort's
        # mergesort order, without its allocations per row (no NaN here:
        # they became inf above)
        for c in range(C):
            d = dist[c]
            j = c
            while j > 0 and dist[pick[j - 1]] > d:
                pick[j] = pick[j - 1]
                j -= 1
            pick[j] = c
        for q in range(K):
            sel[r, q] = cand[pick[q]]
            present[r, q] = np.isfinite(dist[pick[q]])
    return sel, present


@nb.njit(cache=True)
def nearest_euclidean(x, y, rows, K, pd):
    """The intersection observation's neighbour search
    (:meth:`icv_envs.envs.intersection.IntersectionEnv._neighbours`)
    compiled: for each query row ``o``, the ``K`` vehicles nearest by
    ``hypot(x - x[o], y - y[o])`` (the observer itself and vehicles farther
    than ``pd`` excluded), nearest first, ties by row (the array code left
    the order of exact ties to ``np.argpartition``'s selection). One pass
    per row keeps a sorted buffer of the ``K`` best. Returns ``(sel,
    present)`` of shape ``(len(rows), K)``; absent slots hold row 0 and
    ``present`` False (the ``Kinematics`` rows skip them)."""
    n = x.shape[0]
    m = rows.shape[0]
    sel = np.zeros((m, K), dtype=np.int64)
    present = np.zeros((m, K), dtype=np.bool_)
    if K <= 0:
        return sel, present
    best = np.empty(K)
    for r in range(m):
        o = rows[r]
        x0 = x[o]
        y0 = y[o]
        cnt = 0
        for j in range(n):
            if j == o:
                continue
            dx = x[j] - x0
            dy = y[j] - y0
            # (hypot is at least the larger leg, rounded or not: a leg beyond
            # pd decides without it)
            if abs(dx) > pd or abs(dy) > pd:
                continue
            d = np.hypot(dx, dy)
            if not d <= pd:  # (farther than pd, or NaN: absent, as inf was)
                continue
            if cnt == K and d >= best[K - 1]:
                continue
            # insert after every kept entry with a distance <= d (rows come in
            # ascending order: ties stay by row)
            q = cnt if cnt < K else K - 1
            while q > 0 and best[q - 1] > d:
                if q < K:
                    best[q] = best[q - 1]
                    sel[r, q] = sel[r, q - 1]
                q -= 1
            best[q] = d
            sel[r, q] = j
            if cnt < K:
                cnt += 1
        for q in range(cnt):
            present[r, q] = True
    return sel, present


@nb.njit(cache=True)
def corridor_leaders(lead, rows, coord, length, speed, n):
    """Per vehicle (``n`` rows): the bumper gap to its nearest leader over
    the corridors it is listed in and its speed minus that leader's, from a
    corridor index's entries (``rows``, ``coord``, ``lead`` the entry of each
    entry's leader, -1 none; :class:`icv_envs.policies.platoon_common.Corridors`):
    ``coord[lead] - coord - (length[me] + length[leader]) / 2`` per entry,
    the least per vehicle (inf without a leader; of equal gaps the first
    entry's leader, as the array code's stable sort chose), ``dv`` 0 without
    one. The intersection env's ``_leaders``; the array code it replaced is
    its reference in ``tests/test_kernels.py``."""
    gap = np.full(n, np.inf)
    dv = np.zeros(n)
    best = np.full(n, -1, dtype=np.int64)
    for e in range(lead.shape[0]):
        k = lead[e]
        if k < 0:
            continue
        me = rows[e]
        ld = rows[k]
        g = coord[k] - coord[e] - 0.5 * (length[me] + length[ld])
        if best[me] < 0 or g < gap[me]:
            gap[me] = g
            best[me] = ld
    for i in range(n):
        if best[i] >= 0:
            dv[i] = speed[i] - speed[best[i]]
    return gap, dv


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
    # per column, once: relative to the observer (x, y, vx, vy unless
    # absolute), dx folded round the ring, the neighbours' scale
    rel = np.zeros(J, dtype=np.bool_)
    fold = np.zeros(J, dtype=np.bool_)
    scale = np.empty(J)
    for j in range(J):
        f = idx[j]
        rel[j] = (not absolute) and f >= 1 and f <= 4
        fold[j] = rel[j] and f == 1 and period > 0.0
        scale[j] = s_abs[f] if absolute else s_rel[f]
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
                if rel[j]:
                    val = val - F[o, f]
                    if fold[j]:
                        val = npy_mod(val + half, period) - half
                if normalize:
                    val = val / scale[j]
                    if clip:
                        val = min(max(val, -1.0), 1.0)
                out[r, 1 + q, j] = val
    return out


@nb.njit(cache=True)
def _kinematics_columns(F, i, x, y, v, c, s):
    """Row ``i``'s first seven features, the layout both envs share:
    presence, x, y, vx = v cos, vy = v sin, cos, sin of the heading."""
    F[i, 0] = 1.0
    F[i, 1] = x
    F[i, 2] = y
    F[i, 3] = v * c
    F[i, 4] = v * s
    F[i, 5] = c
    F[i, 6] = s


@nb.njit(cache=True)
def formation_feature_rows(cx, cy, speed, ch, sh, x_ref, lane_ref, v_ref, member, lane_width, total_lanes, period,
                           n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv):
    """The feature rows of
    :meth:`icv_envs.envs.highway_rows.HighwayRows._features`
    in one pass, the trigonometry (``ch``, ``sh``: ``cos``/``sin`` of the
    headings) given from NumPy: ``1, x, y, v ch, v sh, ch, sh``; for
    members the target errors ``wrap(x_ref - x)`` (``period < 0``: a
    straight road), ``lane_ref * lane_width - y``, ``v_ref - v`` and 1,
    zeros for free vehicles; column 11 = 1 (the caller writes the exits');
    column 12 ``clip((interval_end(lane, x) - x) / 200, 0, 1)`` in the own
    lane ``clip(rint(y / lane_width), 0, total_lanes - 1)``, the interval
    end taken at ``mod(x, period)`` and moved back by ``x - mod(x, period)``
    on a ring (``RoadLayout.interval_end``). Returns ``(n, 13)`` float64."""
    n = cx.shape[0]
    F = np.zeros((n, 13))
    lane = np.empty(n, dtype=np.int64)
    for i in range(n):
        _kinematics_columns(F, i, cx[i], cy[i], speed[i], ch[i], sh[i])
        if member[i]:
            F[i, 7] = _wrap1(x_ref[i] - cx[i], period)
            F[i, 8] = lane_ref[i] * lane_width - cy[i]
            F[i, 9] = v_ref[i] - speed[i]
            F[i, 10] = 1.0
        F[i, 11] = 1.0
        lane[i] = lane_of1(cy[i], lane_width, total_lanes)
    ends = interval_ends_at(lane, cx, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    for i in range(n):
        u = (ends[i] - cx[i]) / 200.0
        if u == u:
            u = min(max(u, 0.0), 1.0)
        F[i, 12] = u
    return F


@nb.njit(cache=True)
def formation_reward_terms(rows, speed, v_max, gap, crashed_now, ua, F, spacing, lane_width, w_progress, w_safety,
                           w_comfort):
    """The reward terms of
    :meth:`icv_envs.envs.highway_formation.HighwayFormationEnv._rewards_rows`
    in one pass over ``rows``, but the ``exp`` (NumPy's): progress
    ``v / v_max``; safety ``-clip(1 - gap / (2 + v), 0, 1)``, -1 for
    ``crashed_now``; comfort ``-0.5 (u_a^2 + u_s^2)``; the exponent of the
    formation term ``-(dx / spacing)^2 - (dy / lane_width)^2`` with the
    member flag; and the weighted sum of the first three. Returns
    ``(progress, safety, comfort, exponent, member, partial)``."""
    m = rows.shape[0]
    progress = np.empty(m)
    safety = np.empty(m)
    comfort = np.empty(m)
    expo = np.empty(m)
    member = np.empty(m, dtype=np.bool_)
    partial = np.empty(m)
    for q in range(m):
        r = rows[q]
        progress[q] = speed[r] / v_max
        x = 1.0 - gap[r] / (2.0 + speed[r] * 1.0)
        if x == x:
            x = min(max(x, 0.0), 1.0)
        safety[q] = -1.0 if crashed_now[q] else -x
        a0, a1 = ua[q, 0], ua[q, 1]
        comfort[q] = -0.5 * (a0 * a0 + a1 * a1)
        dx = F[r, 7] / spacing
        dy = F[r, 8] / lane_width
        expo[q] = -(dx * dx) - dy * dy
        member[q] = F[r, 10] > 0
        partial[q] = w_progress * progress[q] + w_safety * safety[q] + w_comfort * comfort[q]
    return progress, safety, comfort, expo, member, partial


@nb.njit(cache=True)
def formation_reward_total(member, expo, partial, w_formation):
    """The highway reward from :func:`formation_reward_terms`' exponent,
    member flags and partial sum, in one pass (from stop 49; NumPy's
    ``where(member, exp(expo), 0.0)`` and ``partial + w * form`` before):
    the formation term ``exp(expo)`` for members, 0 for the others, and the
    total ``partial + w_formation * form``. Returns them as the rows of one
    ``(2, n)`` array (total, form). The ``exp`` is libm's: NumPy's at
    ``X86_V3``, the reference fingerprints' level, bit for bit (the rule of
    :mod:`icv_envs.sim._kernels`)."""
    n = expo.shape[0]
    out = np.empty((2, n))
    for i in range(n):
        f = math.exp(expo[i]) if member[i] else 0.0
        out[1, i] = f
        out[0, i] = partial[i] + w_formation * f
    return out


@nb.njit(cache=True)
def formation_post_rows(cx, cy, speed, ch, sh, x_ref, lane_ref, v_ref, member, lane_width, total_lanes, period,
                        n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, rows, r_speed, v_max, gap, crashed_now, ua,
                        spacing, r_lane_width, w_progress, w_safety, w_comfort, K, pd, periodic, road_length, idx, V,
                        s_abs, s_rel, absolute, normalize, clip, o_period, w_formation):
    """What the highway env's step builds from the state after its
    physics, in one call, each kernel with the arguments its separate call
    gets, in their order: :func:`formation_feature_rows` (``cx`` ..
    ``ramp_iv``), :func:`formation_reward_terms` of ``rows`` (``rows`` ..
    ``w_comfort``, the feature rows after the sixth), and the ``Kinematics``
    observations: when ``V > 1`` and there are two vehicles or more,
    :func:`nearest_along_road` on a contiguous copy of the x column
    (``K`` .. ``road_length``), then :func:`kinematics_rows` (``idx`` ..
    ``o_period``), and the reward's total and formation term
    (:func:`formation_reward_total` with ``w_formation``; a second call
    until stop 50). For ``HighwayRows._post_rows`` (HighwayFormation) on
    roads without exits (the exits' column is written in Python between the
    features and the observation). Returns ``(T, obs)``, ``T`` the reward
    and its terms by rows ``total, progress, safety, comfort, formation``
    (one array instead of five: numba boxes each returned array for about
    0.35 us, a view of a row costs 0.1)."""
    F = formation_feature_rows(cx, cy, speed, ch, sh, x_ref, lane_ref, v_ref, member, lane_width, total_lanes, period,
                               n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    progress, safety, comfort, expo, member_q, partial = formation_reward_terms(
        rows, r_speed, v_max, gap, crashed_now, ua, F, spacing, r_lane_width, w_progress, w_safety, w_comfort)
    if V > 1 and cx.shape[0] > 1:
        sel, present = nearest_along_road(F[:, 1].copy(), rows, K, pd, periodic, road_length)
    else:
        sel = np.zeros((rows.shape[0], 0), dtype=np.int64)
        present = np.zeros((rows.shape[0], 0), dtype=np.bool_)
    obs = kinematics_rows(F, rows, sel, present, idx, V, s_abs, s_rel, absolute, normalize, clip, o_period)
    tf = formation_reward_total(member_q, expo, partial, w_formation)
    T = np.empty((5, rows.shape[0]))
    T[0] = tf[0]
    T[1] = progress
    T[2] = safety
    T[3] = comfort
    T[4] = tf[1]
    return T, obs


@nb.njit(cache=True)
def intersection_feature_rows(cx, cy, speed, c, s, dist, has, d, dv, phase, lat_leg, klane, lane_width, lat, mv, R1,
                              R2, go):
    """The intersection env's absolute features (``IntersectionEnv._features``,
    ``OBS_FEATURES`` in order) from the heading's cosine ``c`` and sine
    ``s`` (numpy's): presence, centre, velocity, heading, distance to the
    centre, the expert's reference error and speed error (0 without a
    reference), lateral offset (from the kept lane's centre on the
    approach, from the path in the box), turn (-1, 0, 1), zone (0 before
    ``R2``, 1/3 in the adjusting zone, 2/3 inside ``R1``, 1 past the stop
    line), may go. The array code's operations in its order
    (tests/test_expert_kernels.py)."""
    n = cx.shape[0]
    F = np.zeros((n, 14))
    for i in range(n):
        _kinematics_columns(F, i, cx[i], cy[i], speed[i], c[i], s[i])
        F[i, 7] = dist[i]
        F[i, 8] = d[i] if has[i] else 0.0
        F[i, 9] = dv[i] if has[i] else 0.0
        appr = phase[i] == 0
        lane = klane[i]
        if lane < 0:
            lane = 0
        if lane > 2:
            lane = 2
        F[i, 10] = lat_leg[i] - (lane + 0.5) * lane_width if appr else lat[i]
        F[i, 11] = (mv[i] % 3) - 1.0
        if appr:
            F[i, 12] = 0.0 if dist[i] > R2 else (1.0 / 3.0 if dist[i] > R1 else 2.0 / 3.0)
        else:
            F[i, 12] = 1.0
        F[i, 13] = go[i]
    return F


@nb.njit(cache=True, inline="always")
def _tracking_exponent(dx):
    """``-(dx / 10)^2``: the argument of the tracking reward's ``exp``."""
    e = dx / 10.0
    return -(e * e)


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def intersection_reward_rows(rows, speed, lo, span, gap, crashed, ua, F, w_progress, w_safety, w_comfort,
                             w_tracking):
    """The intersection env's reward terms of ``rows``
    (``IntersectionEnv._rewards_rows``): progress ``clip((v - lo) / span, 0,
    1)``, safety ``-clip(1 - gap / (2 + v), 0, 1)`` (-1 on a collision),
    comfort ``-(u_a^2 + u_s^2) / 2`` of the last actions ``ua`` (rows
    aligned with ``rows``), tracking ``exp(-(dx / 10)^2)`` where the
    reference error ``dx = F[:, 8]`` is not 0 (libm's ``exp`` from stop 49,
    NumPy's at ``X86_V3``; NumPy's, passed in, before), and their weighted
    sum. Returns ``(total, progress, safety, comfort, tracking)``."""
    m = rows.shape[0]
    total = np.empty(m)
    progress = np.empty(m)
    safety = np.empty(m)
    comfort = np.empty(m)
    track = np.empty(m)
    for k in range(m):
        i = rows[k]
        p = clip1((speed[i] - lo) / span, 0.0, 1.0)
        q = clip1(1.0 - gap[i] / (2.0 + speed[i]), 0.0, 1.0)
        sf = -1.0 if crashed[i] else -q
        cf = -0.5 * (ua[k, 0] * ua[k, 0] + ua[k, 1] * ua[k, 1])
        tr = math.exp(_tracking_exponent(F[i, 8])) if F[i, 8] != 0.0 else 0.0
        progress[k] = p
        safety[k] = sf
        comfort[k] = cf
        track[k] = tr
        total[k] = w_progress * p + w_safety * sf + w_comfort * cf + w_tracking * tr
    return total, progress, safety, comfort, track


@nb.njit(cache=True, error_model="numpy")
def intersection_post_rows(cx, cy, speed, c, s, dist, has, d, dv, phase, lat_leg, klane, lane_width, lat, mv, R1, R2,
                           go, rows, lo, span, gap, crashed, ua, w_progress, w_safety, w_comfort, w_tracking, K, pd,
                           idx, V, s_abs, s_rel, absolute, normalize, clip, o_period):
    """What the intersection env's step builds from the state after its
    physics and coordination, in one call (from stop 42), each kernel with
    the arguments its separate call gets, in their order:
    :func:`intersection_feature_rows` (``cx`` .. ``go``),
    :func:`intersection_reward_rows` of ``rows`` (``rows`` .. ``w_tracking``;
    until stop 49 the tracking term's ``exp`` came from NumPy, an argument),
    and the ``Kinematics``
    observations: when ``V > 1`` and there are two vehicles or more,
    :func:`nearest_euclidean` of the ``K`` nearest on contiguous copies of
    the centre columns, then :func:`kinematics_rows` (``idx`` ..
    ``o_period``). For ``IntersectionEnv._post_rows`` (the observation
    without the leader columns). Returns ``(T, obs)``, ``T`` the reward
    terms by rows ``total, progress, safety, comfort, tracking``."""
    F = intersection_feature_rows(cx, cy, speed, c, s, dist, has, d, dv, phase, lat_leg, klane, lane_width, lat, mv,
                                  R1, R2, go)
    total, progress, safety, comfort, track = intersection_reward_rows(
        rows, speed, lo, span, gap, crashed, ua, F, w_progress, w_safety, w_comfort, w_tracking)
    if V > 1 and cx.shape[0] > 1:
        sel, present = nearest_euclidean(F[:, 1].copy(), F[:, 2].copy(), rows, K, pd)
    else:
        sel = np.zeros((rows.shape[0], 0), dtype=np.int64)
        present = np.zeros((rows.shape[0], 0), dtype=np.bool_)
    obs = kinematics_rows(F, rows, sel, present, idx, V, s_abs, s_rel, absolute, normalize, clip, o_period)
    T = np.empty((5, rows.shape[0]))
    T[0] = total
    T[1] = progress
    T[2] = safety
    T[3] = comfort
    T[4] = track
    return T, obs
