"""The highway formation expert's compiled loops
(:class:`icv_envs.policies.formation_expert.FormationExpert`, paper Sec. 2.2
and 3.4):
:func:`safety_cap` is its safety envelope (about thirty numpy calls
before), :func:`lane_change_starts` its decision which lane changes start
(about eighty), :func:`exit_lanes` and :func:`lane_end_escape` the lanes it
heads for (about thirty); then the arithmetic of ``compute``'s lane-change
state, preview points and longitudinal law around the numpy calls that stay
(:func:`lane_changes_ended`, :func:`preview_points`,
:func:`expert_lane_speeds`, :func:`free_speed_ratio`,
:func:`expert_accelerations`). Rules: :mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.policies._kernels.laws import _feedback1, _idm_free1, normalised_actions
from icv_envs.sim._kernels.formation import _exit_ahead1, _exit_lookahead1, _wrap1
from icv_envs.sim._kernels.neighbours import leader_entries, leader_rows
from icv_envs.sim._kernels.physics import interval_ends_at, lanes_available, npy_mod

__all__ = ["desired_lane_rows", "exit_lanes", "expert_accelerations", "expert_control_rows", "expert_lane_speeds",
           "free_speed_ratio", "free_speed_ratio_rows", "lane_change_starts", "lane_changes_ended", "lane_end_escape",
           "preview_points", "safety_cap"]


@nb.njit(cache=True)
def safety_cap(keys, i_rows, i_lanes, i_x, offset, cx, v, length, lc_lane, lane, desired, member, exiting, acc,
               period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, lc_min_length, member_time_gap, idm_T,
               a_max, idm_s0, idm_denom, clip_lo, clip_hi):
    """The highway expert's safety envelope
    (:meth:`icv_envs.policies.formation_expert.FormationExpert._safety_cap`)
    in one pass: the queries are the lane index's entries (every lane a
    body occupies) and then each vehicle changing lanes in its target lane
    (ascending rows); per query the leader there (:func:`leader_rows`) or
    the end of the lane ahead as a standing leader (own or target lane, not
    a lane being left, not the exit ramp of an exiting vehicle; a vehicle
    that must leave a lane before it ends stops ``k * lc_min_length``
    before it), whichever is nearer; the IDM interaction term
    ``a_max (1 - (s* / max(gap, 0.1))^2)``, ``s* = s0 + max(0, v T + v dv /
    idm_denom)``, ``idm_denom = 2 sqrt(a_max b)``; ``acc`` capped by the
    smallest per vehicle and clipped to ``[clip_lo, clip_hi]``. NumPy's
    ``minimum``/``maximum`` semantics (NaN kept). Returns the new ``acc``."""
    n = cx.shape[0]
    ni = i_rows.shape[0]
    n_act = 0
    for i in range(n):
        if lc_lane[i] >= 0:
            n_act += 1
    nq = ni + n_act
    q_rows = np.empty(nq, dtype=np.int64)
    q_lanes = np.empty(nq, dtype=np.int64)
    for q in range(ni):
        q_rows[q] = i_rows[q]
        q_lanes[q] = i_lanes[q]
    q = ni
    for i in range(n):
        if lc_lane[i] >= 0:
            q_rows[q] = i
            q_lanes[q] = lc_lane[i]
            q += 1
    lead, lx = leader_rows(keys, i_rows, i_lanes, i_x, offset, q_rows, q_lanes, cx)
    xq = np.empty(nq)
    dq = np.empty(nq, dtype=np.int64)
    for q in range(nq):
        xq[q] = cx[q_rows[q]]
        dq[q] = desired[q_rows[q]]
    end = interval_ends_at(q_lanes, xq, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    end_desired = interval_ends_at(dq, xq, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    cap = np.full(n, np.inf)
    for q in range(nq):
        r = q_rows[q]
        ql = q_lanes[q]
        lr = lead[q]
        if lr >= 0:
            gap = lx[q] - cx[r] - 0.5 * (length[lr] + length[r])
            dv = v[r] - v[lr]
        else:
            gap = np.inf
            dv = 0.0
        leaving = lc_lane[r] >= 0 and lc_lane[r] != ql
        exit_ramp_end = ql == n_lanes and exiting[r]
        own_or_target = ql == lane[r] or ql == lc_lane[r]
        if leaving or exit_ramp_end or not own_or_target:
            gap_end = np.inf
        else:
            gap_end = end[q] - cx[r] - 0.5 * length[r]
        k_q = abs(dq[q] - ql)
        if k_q > 0 and not leaving and not exit_ramp_end and own_or_target and end[q] < end_desired[q]:
            gap_end = end[q] - k_q * lc_min_length - cx[r]
        if gap_end < gap:
            gap = gap_end
            dv = v[r]
        T = member_time_gap if member[r] else idm_T
        u = v[r] * T + v[r] * dv / idm_denom
        s_star = idm_s0 + (0.0 if 0.0 >= u else u)
        g = gap if gap >= 0.1 else 0.1
        ratio = s_star / g
        safe = a_max * (1.0 - ratio * ratio)
        c = cap[r]
        cap[r] = c if (c <= safe or c != c) else safe
    out = np.empty(n)
    for i in range(n):
        a = acc[i]
        a = a if (a <= cap[i] or a != a) else cap[i]
        if a == a:
            a = a if a > clip_lo else clip_lo
            a = a if a < clip_hi else clip_hi
        out[i] = a
    return out


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
def exit_lanes(member, lane_ref, lane, exit_id, cx, has_ramp, n_exits, n_lanes, diverge_iv, exit_x, period,
               exit_lookahead, per_lane):
    """The highway expert's desired lanes before its ``_desired_lanes`` hook
    (:meth:`icv_envs.policies.formation_expert.FormationExpert.compute`):
    members their target lane, the others their own; with a ramp lane
    (``n_lanes``), a vehicle with an exit is exiting once on its off-ramp
    (in the ramp lane between the diverge start and the exit, member or
    not) or, not a member, within its exit lookahead (``exit_lookahead +
    per_lane`` per main lane still to cross) of the diverge start and not
    past the diverge end; exiting vehicles head for the ramp lane, other
    free vehicles in the ramp lane for the outermost main lane.
    ``RoadLayout.wrap``/``exit_ahead``/``exit_lookahead``'s operations in
    their order. Returns ``(desired, exiting)``."""
    n = cx.shape[0]
    desired = np.empty(n, dtype=np.int64)
    exiting = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        desired[i] = lane_ref[i] if member[i] else lane[i]
    if not has_ramp:
        return desired, exiting
    ramp = n_lanes
    if n_exits:
        for i in range(n):
            e = exit_id[i]
            if e < 0:
                continue
            ds = diverge_iv[e, 0]
            past = _wrap1(cx[i] - ds, period)
            ex = lane[i] == ramp and past >= 0 and past <= exit_x[e] - ds
            if not member[i]:
                dist = _exit_ahead1(e, cx[i], diverge_iv, period)
                la = _exit_lookahead1(lane[i], ramp, exit_lookahead, per_lane)
                ex = ex or (dist < la and dist >= -(diverge_iv[e, 1] - ds))
            exiting[i] = ex
    for i in range(n):
        if exiting[i]:
            desired[i] = ramp
        elif lane[i] == ramp and not member[i]:
            desired[i] = n_lanes - 1
    return desired, exiting


@nb.njit(cache=True)
def lane_end_escape(desired, lane, member, exiting, cx, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv,
                    lc_max_length):
    """Free vehicles (not members, not exiting, keeping their main lane)
    whose lane ends ahead head for the nearest main lane that continues at
    least 50 m further (ties: the left lane), starting ``(k + 1)
    lc_max_length`` before the end for ``k`` lane changes
    (:meth:`icv_envs.policies.formation_expert.FormationExpert.compute`);
    ``RoadLayout.interval_end``'s operations. Returns the new desired lanes."""
    n = cx.shape[0]
    out = desired.copy()
    # the interval ends in one call each (the own lanes', then every main
    # lane's for the vehicles whose own lane ends): the road's rule over
    # arrays (sim/_kernels/physics.lanes_available's note)
    rows = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if not (member[i] or exiting[i] or desired[i] != lane[i] or lane[i] >= n_lanes):
            rows[m] = i
            m += 1
    rows = rows[:m]
    ends = interval_ends_at(lane[rows], cx[rows], period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    fin = np.empty(m, dtype=np.int64)
    nf = 0
    for q in range(m):
        if np.isfinite(ends[q]):
            fin[nf] = q
            nf += 1
    all_lanes = np.empty(nf * n_lanes, dtype=np.int64)
    all_x = np.empty(nf * n_lanes)
    for f in range(nf):
        for l in range(n_lanes):
            all_lanes[f * n_lanes + l] = l
            all_x[f * n_lanes + l] = cx[rows[fin[f]]]
    ends_all = interval_ends_at(all_lanes, all_x, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    for f in range(nf):
        i = rows[fin[f]]
        ln = lane[i]
        end = ends[fin[f]]
        best = -1
        best_key = np.inf
        k = np.inf
        for l in range(n_lanes):
            e = ends_all[f * n_lanes + l]
            d = float(abs(l - ln)) if e > end + 50.0 else np.inf
            key = d + 1e-3 * l
            if best < 0 or key < best_key:  # numpy's argmin: the first smallest
                best = l
                best_key = key
                k = d
        if np.isfinite(k) and end - cx[i] < (k + 1.0) * lc_max_length:
            out[i] = best
    return out


# ----------------------------------------- the highway expert's array code
# (FormationExpert.compute's lane-change state, preview points and
# longitudinal law, each the arithmetic of the array code it replaced, in
# its order, around the numpy calls that stay: the Bezier curve's arcsinh
# and sinh, the IDM's power; numpy's maximum(a, b) and minimum(a, b) return
# b on a tie (a -0.0 against a 0.0), its clip keeps the value on a tie;
# the replaced code is frozen in tests/test_expert_kernels.py)


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


@nb.njit(cache=True)
def preview_points(x, v, lane, lane_width, preview_min, preview_time):
    """The steering's preview points: ``x + max(preview_min, v
    preview_time)`` ahead on the lane centre ``lane * lane_width``."""
    n = x.shape[0]
    px = np.empty(n)
    py = np.empty(n)
    for i in range(n):
        vt = v[i] * preview_time
        ld = preview_min if preview_min > vt else vt
        px[i] = x[i] + ld
        py[i] = lane[i] * lane_width
    return px, py


@nb.njit(cache=True)
def expert_lane_speeds(lane_speed, lane, exiting, blocked, member, n_lanes, exit_speed, slowdown, v_min):
    """The speed a vehicle heads for: its lane's (``lane_speed``), the exit
    speed on the main road when exiting, ``slowdown`` less (not below
    ``v_min``) for a free vehicle refused a lane change, ``v_min`` at most
    for one refused on its way to its exit."""
    n = lane_speed.shape[0]
    out = np.empty(n)
    for i in range(n):
        s = lane_speed[i]
        if exiting[i] and lane[i] < n_lanes:
            s = exit_speed
        if blocked[i] and not member[i]:
            u = s - slowdown
            s = u if u > v_min else v_min
            if exiting[i]:
                s = s if s < v_min else v_min
        out[i] = s
    return out


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def free_speed_ratio(rows, v, v0):
    """``v / max(v0, 0.1)`` of ``rows``: the base of the IDM's free-road term."""
    n = rows.shape[0]
    r = np.empty(n)
    for k in range(n):
        i = rows[k]
        r[k] = v[i] / (v0[i] if v0[i] > 0.1 else 0.1)
    return r


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def expert_accelerations(n, free_rows, free_pow, v, a_max, b, T, s0, m_rows, cx, x_ref, v_ref, a_ref, length, kp, kv,
                         lo, hi, v_min):
    """The longitudinal law before the safety envelope: free vehicles the
    IDM without a leader (``free_pow`` the free term's power, aligned with
    ``free_rows``; the interaction term with an infinite gap, as
    ``traffic.idm_acceleration`` takes it), members the feedback law on
    their reference (``x_ref`` folded to the nearest image on a ring of
    ``length``; ``length < 0`` a straight road) clipped to ``[lo, hi]`` and
    floored at ``v_min - v``."""
    acc = np.empty(n)
    root = 2.0 * math.sqrt(a_max * b)
    for k in range(free_rows.shape[0]):
        i = free_rows[k]
        acc[i] = _idm_free1(v[i], free_pow[k], a_max, T, s0, root)
    for k in range(m_rows.shape[0]):
        i = m_rows[k]
        xe = cx[i] + _wrap1(x_ref[i] - cx[i], length)
        u = _feedback1(a_ref[i], cx[i], xe, v[i], v_ref[i], kp, kv, lo, hi)
        floor = 1.0 * (v_min - v[i])
        acc[i] = u if u > floor else floor
    return acc


# ---------------------------------------------------------------------------
# ``FormationExpert.compute``'s runs of kernels with no numpy call between
# them, each run in one call (the separate calls' arguments passed through;
# used while the expert's hooks are its own: FormationExpert._fused)


@nb.njit(cache=True)
def desired_lane_rows(member, lane_ref, lane, exit_id, cx, has_ramp, n_exits, n_lanes, diverge_iv, exit_x, period,
                      exit_lookahead, per_lane, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, lc_max_length):
    """:func:`exit_lanes` then :func:`lane_end_escape` on its answer (the
    expert's ``_desired_lanes`` hook between them being the identity).
    Returns ``(desired, exiting)``."""
    desired, exiting = exit_lanes(member, lane_ref, lane, exit_id, cx, has_ramp, n_exits, n_lanes, diverge_iv, exit_x,
                                  period, exit_lookahead, per_lane)
    desired = lane_end_escape(desired, lane, member, exiting, cx, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi,
                              ramp_iv, lc_max_length)
    return desired, exiting


@nb.njit(cache=True, error_model="numpy")  # (free_speed_ratio's division, as there)
def free_speed_ratio_rows(use_table, table, lane, n_lanes, has_ramp, ramp_speed, desired_speed, exiting, blocked, member,
                          exit_speed, slowdown, v_min, free_rows, v):
    """The lane speeds of ``FormationExpert._lane_speeds`` (``table`` at the
    lane clipped to its range with ``use_table``, else ``ramp_speed`` in the
    ramp lane of a road that has one and ``desired_speed`` elsewhere), then
    :func:`expert_lane_speeds` and :func:`free_speed_ratio` of ``free_rows``
    (the base of the IDM's free term, whose power the caller takes)."""
    n = lane.shape[0]
    ls = np.empty(n)
    top = table.shape[0] - 1
    for i in range(n):
        if use_table:
            j = lane[i]
            if j < 0:
                j = 0
            elif j > top:
                j = top
            ls[i] = table[j]
        else:
            ls[i] = ramp_speed if (lane[i] == n_lanes and has_ramp) else desired_speed
    lane_speed = expert_lane_speeds(ls, lane, exiting, blocked, member, n_lanes, exit_speed, slowdown, v_min)
    return free_speed_ratio(free_rows, v, lane_speed)


@nb.njit(cache=True)
def expert_control_rows(n, free_rows, free_pow, v, a_max, b, T, s0, m_rows, cx, x_ref, v_ref, a_ref, period, kp, kv,
                        lo, hi, v_min, keys, i_rows, i_lanes, i_x, offset, length, lc_lane, lane, desired, member,
                        exiting, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, lc_min_length, member_time_gap,
                        idm_T, idm_s0, idm_denom, clip_lo, clip_hi, phi, a_min, steer_max):
    """:func:`expert_accelerations`, the safety envelope
    (:func:`safety_cap`) on them, and the normalised actions
    (:func:`~icv_envs.policies._kernels.laws.normalised_actions` with
    ``phi``). Returns ``(n, 2)`` float64."""
    acc = expert_accelerations(n, free_rows, free_pow, v, a_max, b, T, s0, m_rows, cx, x_ref, v_ref, a_ref, period,
                               kp, kv, lo, hi, v_min)
    acc = safety_cap(keys, i_rows, i_lanes, i_x, offset, cx, v, length, lc_lane, lane, desired, member, exiting, acc,
                     period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, lc_min_length, member_time_gap, idm_T,
                     a_max, idm_s0, idm_denom, clip_lo, clip_hi)
    return normalised_actions(acc, phi, a_max, a_min, steer_max)
