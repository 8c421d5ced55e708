"""The highway formation expert's lane-change decisions, compiled
(:class:`icv_envs.policies.formation_expert.FormationExpert`, paper Sec.
3.4: the Bezier lane change of a member to its assigned lane, and of a free
vehicle to the lane it heads for): :func:`lane_change_starts` decides
which lane changes start now (the gaps in the target lane, the rear
vehicle's IDM reaction, the room before a lane end; about eighty numpy
calls before it was compiled), :func:`lane_changes_ended` which running
ones end or re-plan. Moved from ``formation_expert.py`` at stop 38
unchanged. Rules: :mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.sim._kernels.formation import _wrap1
from icv_envs.sim._kernels.neighbours import leader_entries
from icv_envs.sim._kernels.physics import interval_ends_at, lanes_available, npy_mod

__all__ = ["lane_change_starts", "lane_changes_ended"]


@nb.njit(cache=True, inline="always")
def _min_nan(a, b):
    """``numpy.minimum`` of two floats (NaN propagates)."""
    return a if (a <= b or a != a) else b


@nb.njit(cache=True, inline="always")
def _max_nan(a, b):
    """``numpy.maximum`` of two floats (NaN propagates)."""
    return a if (a >= b or a != a) else b


@nb.njit(cache=True, inline="always")
def _idm_interaction(v, gap, dv, T, a_max, s0, idm_denom):
    """``traffic.idm_acceleration(..., free_term=False)`` of one vehicle:
    ``a_max (1 - (s* / max(gap, 0.1))^2)``, ``s* = s0 + max(0, v T + v dv /
    idm_denom)`` (``idm_denom = 2 sqrt(a_max b)``), numpy's operations in
    its order (the square is the exact product)."""
    s_star = s0 + _max_nan(0.0, v * T + v * dv / idm_denom)
    r = s_star / _max_nan(gap, 0.1)
    return a_max * (1.0 - r * r)


@nb.njit(cache=True, inline="always")
def _in_intervals(x, iv):
    """Whether ``x`` lies in one of the closed intervals ``iv[k] = (lo, hi)``."""
    for k in range(iv.shape[0]):
        if x >= iv[k, 0] and x <= iv[k, 1]:
            return True
    return False


@nb.njit(cache=True)
def _leader_gaps(ent, i_rows, i_x, x, lr, length, v, v_none):
    """Per query, from its leader entry ``ent`` (:func:`leader_entries`;
    -1: none): the bumper gap ``x_lead - x - (length_lead + lr) / 2`` and
    the leader's speed, ``(inf, v_none)`` for none."""
    m = ent.shape[0]
    gap = np.full(m, np.inf)
    vl = np.empty(m)
    for q in range(m):
        p = ent[q]
        if p >= 0:
            ld = i_rows[p]
            gap[q] = i_x[p] - x[q] - 0.5 * (length[ld] + lr[q])
            vl[q] = v[ld]
        else:
            vl[q] = v_none[q]
    return gap, vl


@nb.njit(cache=True, inline="always")
def _rear_refused(a, b, xw, lw, vw, member_b, period, lc_min_gap, idm_s0, member_time_gap, idm_T, a_max, idm_denom,
                  b_safe):
    """Of two vehicles starting into one lane, front ``a`` and rear ``b``
    (indices into the candidates' positions ``xw``, lengths ``lw`` and
    speeds ``vw``): may the rear one not follow the front one there? Too
    near (one body, ``lc_min_gap``, ``2 s0`` and a member time gap), a gap
    at most ``lc_min_gap``, or an IDM interaction term at most
    ``-b_safe``."""
    d = _wrap1(xw[a] - xw[b], period)
    g = d - 0.5 * (lw[a] + lw[b])
    T = member_time_gap if member_b else idm_T
    acc = _idm_interaction(vw[b], _max_nan(g, 1e-3), vw[b] - vw[a], T, a_max, idm_s0, idm_denom)
    return d < lw[b] + lc_min_gap + 2.0 * idm_s0 + vw[b] * member_time_gap or g <= lc_min_gap or acc <= -b_safe


@nb.njit(cache=True)
def lane_change_starts(active, cx, cy, v, length, lane, desired, member, keys, i_rows, i_lanes, i_x, offset, period,
                       n_lanes, n_tot, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, merge_iv, diverge_iv, has_ramp,
                       W, lc_duration, lc_min_length, lc_max_length, lc_length_min, lc_time_min, idm_s0,
                       member_time_gap, idm_T, a_max, idm_denom, b_safe, lc_min_gap):
    """Which lane changes start this step
    (:meth:`icv_envs.policies.formation_expert.FormationExpert.compute`,
    "start lane changes"), in one pass over the vehicles that want one
    (settled on their lane centre, not changing lanes, ``desired`` another
    lane): one lane towards ``desired``; the target lane must exist here
    (``RoadLayout.available``; the ramp lane only inside a diverge segment,
    leaving it only inside a merge segment); the curve, ``clip(v
    lc_duration, lc_min_length, lc_max_length)`` shortened to the room
    before the own lane ends (twice the distance) and before the target
    lane ends (less ``s0 / 2`` and ``lc_min_length`` per lane change still
    needed after this one), no shorter than ``max(lc_length_min, v
    lc_time_min)``; gap acceptance against the leader and the follower in
    the target lane (gaps above ``lc_min_gap``, ``s0 / 2`` behind a standing
    follower, IDM interaction terms above ``-b_safe`` for both); the old
    lane's leader still ``s0`` ahead half way along the curve at constant
    speeds; and of several vehicles starting into one lane, the rear one
    only if it could follow the front one there (checked again against the
    previous kept one once some are dropped). The operations of the array
    code it replaced, in its order (``tests/test_kernels.py``). Returns the
    rows that start (ascending), their target lanes and curve lengths, and
    the mask of vehicles whose manoeuvre was allowed but refused by the
    gaps (``blocked``)."""
    n = cx.shape[0]
    nk = keys.shape[0]
    w_rows = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if (not active[i]) and abs(cy[i] - lane[i] * W) < 0.6 and desired[i] >= 0 and desired[i] != lane[i]:
            w_rows[m] = i
            m += 1
    blocked = np.zeros(n, dtype=np.bool_)
    nxt = np.empty(m, dtype=np.int64)
    clen = np.empty(m)
    ok = np.empty(m, dtype=np.bool_)
    vw = np.empty(m)
    xw = np.empty(m)
    lw = np.empty(m)
    xq = np.empty(m)
    for q in range(m):
        r = w_rows[q]
        step = desired[r] - lane[r]
        nx = lane[r] + (1 if step > 0 else (-1 if step < 0 else 0))
        vw[q] = v[r]
        xw[q] = cx[r]
        lw[q] = length[r]
        clen[q] = _min_nan(_max_nan(vw[q] * lc_duration, lc_min_length), lc_max_length)  # numpy's clip
        ok[q] = nx >= 0 and nx < n_tot
        nx = 0 if nx < 0 else (n_tot - 1 if nx > n_tot - 1 else nx)
        nxt[q] = nx
        xq[q] = npy_mod(xw[q], period) if period > 0.0 else xw[q]
    own_lane = np.empty(m, dtype=np.int64)
    for q in range(m):
        own_lane[q] = lane[w_rows[q]]
    end_own = interval_ends_at(own_lane, xw, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    end_nxt = interval_ends_at(nxt, xw, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    avail = lanes_available(nxt, xq, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    wr = w_rows[:m]
    # the leaders in the target lane and in the own lane, each in one call
    gaps_f, vls = _leader_gaps(leader_entries(keys, i_rows, i_lanes, offset, nxt, wr, xw), i_rows, i_x, xw, lw,
                               length, v, vw)
    gaps_o, vos = _leader_gaps(leader_entries(keys, i_rows, i_lanes, offset, own_lane, wr, xw), i_rows, i_x, xw, lw,
                               length, v, np.zeros(m))
    possible = np.empty(m, dtype=np.bool_)
    for q in range(m):
        r = w_rows[q]
        if not avail[q]:
            ok[q] = False
        k_after = abs(desired[r] - nxt[q])
        room_own = 2.0 * (end_own[q] - xw[q] - 0.5 * lw[q])
        room_nxt = end_nxt[q] - xw[q] - 0.5 * idm_s0 - k_after * lc_min_length
        clen[q] = _min_nan(clen[q], _min_nan(room_own, room_nxt))
        if not clen[q] >= _max_nan(lc_length_min, vw[q] * lc_time_min):
            ok[q] = False
        if has_ramp:
            if nxt[q] == n_lanes and not _in_intervals(xq[q], diverge_iv):
                ok[q] = False
            if own_lane[q] == n_lanes and not _in_intervals(xq[q], merge_iv):
                ok[q] = False
        possible[q] = ok[q]
        # gap acceptance in the target lane: the leader (traffic.leaders) and
        # the follower (traffic.followers: the last entry before the key, if
        # in the lane and not the vehicle itself)
        gap_f, vl = gaps_f[q], vls[q]
        gap_r = np.inf
        vf = 0.0
        Tf = idm_T
        if nk:
            pf = np.searchsorted(keys, nxt[q] * offset + xw[q]) - 1
            if pf >= 0 and i_lanes[pf] == nxt[q] and i_rows[pf] != r:
                fo = i_rows[pf]
                gap_r = xw[q] - i_x[pf] - 0.5 * (length[fo] + lw[q])
                vf = v[fo]
                if member[fo]:
                    Tf = member_time_gap
        Tw = member_time_gap if member[r] else idm_T
        own = _idm_interaction(vw[q], gap_f, vw[q] - vl, Tw, a_max, idm_s0, idm_denom)
        fol = _idm_interaction(vf, gap_r, vf - vw[q], Tf, a_max, idm_s0, idm_denom)
        min_r = 0.5 * idm_s0 if vf < 0.5 else lc_min_gap
        if not (gap_f > lc_min_gap and gap_r > min_r and own > -b_safe and fol > -b_safe):
            ok[q] = False
        # the old lane's leader half way along the curve
        gap_o, v_o = gaps_o[q], vos[q]
        vm = _max_nan(vw[q], 1.0)
        t_half = 0.5 * clen[q] / vm
        gap_o = gap_o + v_o * t_half - vm * t_half
        if not gap_o >= idm_s0:
            ok[q] = False
    # two vehicles starting into one lane: keep the front one unless the rear
    # one could follow it there (lanes ascending, front first)
    nc = 0
    for q in range(m):
        if ok[q]:
            nc += 1
    if nc > 1:
        cand = np.empty(nc, dtype=np.int64)
        c = 0
        for q in range(m):
            if ok[q]:
                cand[c] = q
                c += 1
        neg = np.empty(nc)
        for c in range(nc):
            neg[c] = -xw[cand[c]]
        o1 = np.argsort(neg, kind="mergesort")  # np.lexsort((-xw, nxt)): stable by -xw, then by lane
        ln1 = np.empty(nc, dtype=np.int64)
        for c in range(nc):
            ln1[c] = nxt[cand[o1[c]]]
        o2 = np.argsort(ln1, kind="mergesort")
        o = np.empty(nc, dtype=np.int64)
        for c in range(nc):
            o[c] = cand[o1[o2[c]]]
        drop = np.zeros(nc, dtype=np.bool_)
        for k in range(nc - 1):
            a, b = o[k], o[k + 1]
            if (not drop[k] and nxt[b] == nxt[a]
                    and _rear_refused(a, b, xw, lw, vw, member[w_rows[b]], period, lc_min_gap, idm_s0,
                                      member_time_gap, idm_T, a_max, idm_denom, b_safe)):
                drop[k + 1] = True
        any_drop = False
        for k in range(nc):
            if drop[k]:
                any_drop = True
        if any_drop:
            last = np.full(n_tot, -1, dtype=np.int64)
            for i in range(nc):
                if drop[i]:
                    continue
                j = last[nxt[o[i]]]
                if j >= 0 and _rear_refused(o[j], o[i], xw, lw, vw, member[w_rows[o[i]]], period, lc_min_gap,
                                            idm_s0, member_time_gap, idm_T, a_max, idm_denom, b_safe):
                    drop[i] = True
                    continue
                last[nxt[o[i]]] = i
        for k in range(nc):
            if drop[k]:
                ok[o[k]] = False
    ns = 0
    for q in range(m):
        if ok[q]:
            ns += 1
        elif possible[q]:
            blocked[w_rows[q]] = True
    start = np.empty(ns, dtype=np.int64)
    s_lane = np.empty(ns, dtype=np.int64)
    s_len = np.empty(ns)
    c = 0
    for q in range(m):
        if ok[q]:
            start[c] = w_rows[q]
            s_lane[c] = nxt[q]
            s_len[c] = clen[q]
            c += 1
    return start, s_lane, s_len, blocked


@nb.njit(cache=True)
def lane_changes_ended(rows, y_plan, x, y, cy, v, lc_x0, lc_len, lc_y1, lc_lane, tol):
    """Clear the lane changes (``lc_lane = -1``, in place) of vehicles
    ``rows`` that strayed more than ``tol`` from their curve (``y_plan``,
    aligned with ``rows``) or ended: past the curve and within 0.3 m of the
    new lane's centre (rear axle), or slower than 0.5 m/s with the body
    centre ``cy`` within 0.3 m of it."""
    for k in range(rows.shape[0]):
        i = rows[k]
        stray = abs(y_plan[k] - y[i]) > tol
        done = x[i] >= lc_x0[i] + lc_len[i] and abs(y[i] - lc_y1[i]) < 0.3
        done = done or (v[i] < 0.5 and abs(cy[i] - lc_y1[i]) < 0.3)
        if stray or done:
            lc_lane[i] = -1
