"""Compiled inner loops of the experts (numba, ``@njit(cache=True)``).

:func:`normalised_actions` turns the highway expert's controls into
normalised actions in one pass (five numpy calls and their temporaries
before), and :func:`safety_cap` is its safety envelope (about thirty numpy
calls before), :func:`lane_change_starts` its decision which lane changes
start (about eighty), :func:`exit_lanes` and :func:`lane_end_escape` the
lanes it heads for (about thirty). The rest serve the intersection experts:

:func:`corridor_index` builds the sorted entries of
:class:`icv_envs.policies.platoon_common.Corridors`, which the experts
rebuild two or three times per step from about eighty small array
operations (about 140 us at 65 vehicles, most of it numpy's per-call
overhead). Same rule as :mod:`icv_envs.sim._kernels`: the same IEEE-754
operations on the same values (comparisons, one subtraction and product
per lane test, ``corr * BIG + coord`` for the keys), no ``fastmath``; the
trigonometry of the footprint's reach stays in numpy (numba's ``sin`` and
numpy's SIMD ``sin`` may round differently), so the index is the same bit
for bit (``tests/test_trajectory_hash.py``). :func:`box_steering` is the
intersection experts' pure-pursuit steering (about forty numpy calls
before); its ``sin``, ``cos``, ``arctan``, ``sinh``, ``arcsinh`` and
``hypot`` are libm's, as NumPy's float64 loops up to AVX2, the level the
reference fingerprints are pinned at (the rule and its AVX-512 caveat:
:mod:`icv_envs.sim._kernels`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.formation._kernels import clip1
from icv_envs.platoon._kernels import depths_of
from icv_envs.sim._kernels.neighbours import leader_entries, leader_rows
from icv_envs.sim._kernels.formation import _exit_ahead1, _exit_lookahead1, _wrap1
from icv_envs.sim._kernels.physics import interval_ends_at, lanes_available, npy_mod

__all__ = ["anticipated_references", "box_steering", "corridor_index", "envelope_pairs", "exit_lanes", "expert_accelerations", "expert_lane_speeds",
           "follow_references", "free_speed_ratio", "lane_change_starts", "lane_changes_ended", "lane_end_escape", "normalised_actions",
           "platoon_accelerations", "preview_points", "repair_order", "safety_cap", "stop_flags", "tree_layers", "tree_references",
           "virtual_caps"]


@nb.njit(cache=True)
def corridor_index(appr, lane, lat_leg, reach, w, leg, s, signal_lane, box, pid, early, plane0, dep, dep_corr,
                   L, big):
    """Entries ``(rows, corr, coord, keys, signal_only, lead)`` of the corridor index, sorted by key then
    row. Candidate entries in the order of the numpy code: the approach lanes ``lane - 1, lane,
    lane + 1`` the footprint reaches into (``|lat_leg - (ln + 0.5) w| < reach``), the signal lane, the
    path of an in-box vehicle, its approach lane over its first metres (``early``), the departure lane
    (``dep``); of two entries of one vehicle in one corridor the first is kept (a vehicle whose body
    covers its signal lane is listed there physically)."""
    n = appr.shape[0]
    cap = 7 * n + 1
    rows = np.empty(cap, dtype=np.int64)
    corr = np.empty(cap, dtype=np.int64)
    coord = np.empty(cap, dtype=np.float64)
    sig = np.zeros(cap, dtype=np.bool_)
    m = 0
    for dl in (-1, 0, 1):
        for i in range(n):
            ln = lane[i] + dl
            if appr[i] and ln >= 0 and ln < 3 and abs(lat_leg[i] - (ln + 0.5) * w) < reach[i]:
                rows[m] = i
                corr[m] = 3 * leg[i] + ln
                coord[m] = s[i]
                m += 1
    for i in range(n):
        if appr[i] and signal_lane[i] >= 0:
            rows[m] = i
            corr[m] = 3 * leg[i] + signal_lane[i]
            coord[m] = s[i]
            sig[m] = True
            m += 1
    for i in range(n):
        if box[i]:
            rows[m] = i
            corr[m] = 24 + pid[i]
            coord[m] = s[i]
            m += 1
    for i in range(n):
        if early[i]:
            rows[m] = i
            corr[m] = 3 * leg[i] + plane0[i]
            coord[m] = s[i]
            m += 1
    for i in range(n):
        if dep[i]:
            rows[m] = i
            corr[m] = dep_corr[i]
            coord[m] = s[i] - L[i]
            m += 1
    # first occurrence of each (row, corridor)
    keep = np.ones(m, dtype=np.bool_)
    for a in range(m):
        if sig[a]:
            for b in range(a):
                if keep[b] and rows[b] == rows[a] and corr[b] == corr[a]:
                    keep[a] = False
                    break
    idx = np.flatnonzero(keep)
    rows, corr, coord, sig = rows[idx], corr[idx], coord[idx], sig[idx]
    keys = corr * big + coord
    # sort by key, ties by row (np.lexsort((rows, keys)))
    o = np.argsort(rows, kind="mergesort")
    o = o[np.argsort(keys[o], kind="mergesort")]
    rows, corr, coord, keys, sig = rows[o], corr[o], coord[o], keys[o], sig[o]
    k = rows.shape[0]
    lead = np.full(k, -1, dtype=np.int64)
    for a in range(k - 1):
        if corr[a + 1] == corr[a]:
            lead[a] = a + 1
    return rows, corr, coord, keys, sig, lead


@nb.njit(cache=True)
def corridor_neighbours(keys, corr, rows, coord, q_rows, q_corr, qk):
    """Per query: the nearest entry of another vehicle ahead (key > ``qk``) and behind (<=) in
    corridor ``q_corr``, looking at most 4 entries each way (a vehicle is listed at most once per
    corridor, so its own entry is the only one skipped). ``(lead_row, lead_coord, foll_row,
    foll_coord)``, -1 / +-inf when none."""
    k = q_rows.shape[0]
    m = keys.shape[0]
    lr = np.full(k, -1, dtype=np.int64)
    lc = np.full(k, np.inf)
    fr = np.full(k, -1, dtype=np.int64)
    fc = np.full(k, -np.inf)
    if m == 0:
        return lr, lc, fr, fc
    pos = np.searchsorted(keys, qk, side="right")
    for i in range(k):
        for j in range(4):
            p = pos[i] + j
            if p >= m or corr[p] != q_corr[i]:
                break
            if rows[p] != q_rows[i]:
                lr[i] = rows[p]
                lc[i] = coord[p]
                break
        for j in range(1, 5):
            p = pos[i] - j
            if p < 0 or corr[p] != q_corr[i]:
                break
            if rows[p] != q_rows[i]:
                fr[i] = rows[p]
                fc[i] = coord[p]
                break
    return lr, lc, fr, fc


@nb.njit(cache=True)
def repair_order(at, K, rows, seg, phase, lane, dist, leg):
    """:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._repair_order`'s
    pair test and repair loop, compiled: per node (``seg``, 0..K-1) and approach
    lane the nearest and farthest member distance over the members still
    approaching (``rows >= 0`` with ``phase == 0``); node ``k`` must come before
    node ``i`` of its leg when in a shared lane its nearest member is ahead of
    ``i``'s farthest (by more than 1e-6 m) and of ``i``'s nearest. The order
    ``at`` (node indices) is scanned later node ``b`` first, then earlier
    ``a``; the first such pair moves ``b`` to ``a``'s place and the scan
    restarts, at most ``4 len(at) + 4`` times. Returns the new order and the
    number of moves."""
    C = 1
    for q in range(rows.shape[0]):
        if rows[q] >= 0 and phase[rows[q]] == 0 and lane[rows[q]] + 1 > C:
            C = lane[rows[q]] + 1
    lo = np.full((K, C), np.inf)
    hi = np.full((K, C), -np.inf)
    any_app = False
    for q in range(rows.shape[0]):
        r = rows[q]
        if r < 0 or phase[r] != 0:
            continue
        any_app = True
        g = seg[q]
        c = lane[r]
        d = dist[r]
        if d < lo[g, c]:
            lo[g, c] = d
        if d > hi[g, c]:
            hi[g, c] = d
    at = at.copy()
    moves = 0
    if not any_app:
        return at, moves
    M = np.zeros((K, K), dtype=np.bool_)
    for k in range(K):
        for i in range(K):
            if leg[k] != leg[i]:
                continue
            for c in range(C):
                if lo[k, c] < hi[i, c] - 1e-6 and lo[k, c] < lo[i, c]:
                    M[k, i] = True
                    break
    n = at.shape[0]
    for _ in range(4 * n + 4):
        hit_b = -1
        hit_a = -1
        for b in range(n):
            for a in range(b):
                if M[at[b], at[a]]:
                    hit_b = b
                    hit_a = a
                    break
            if hit_b >= 0:
                break
        if hit_b < 0:
            break
        moved = at[hit_b]
        for q in range(hit_b, hit_a, -1):
            at[q] = at[q - 1]
        at[hit_a] = moved
        moves += 1
    return at, moves


@nb.njit(cache=True)
def normalised_actions(a, phi, a_max, a_min, steer_max):
    """The highway expert's controls as normalised actions
    (:meth:`icv_envs.policies.formation_expert.FormationExpert._normalise`):
    ``a / a_max`` for ``a >= 0``, else ``-a / a_min``; ``phi / steer_max``;
    both clipped to ``[-1, 1]`` as NumPy's ``clip`` does (NaN passes
    through). Returns ``(n, 2)`` float64."""
    n = a.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        u = a[i] / a_max if a[i] >= 0 else -a[i] / a_min
        s = phi[i] / steer_max
        for k in range(2):
            x = u if k == 0 else s
            if x == x:
                if x < -1.0:
                    x = -1.0
                elif x > 1.0:
                    x = 1.0
            out[i, k] = x
    return out


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


@nb.njit(cache=True)
def box_steering(x, y, heading, speed, klane, mv, pid, phase, s, u, lc_lane, lc_u0, lc_lat0, lc_lat1, lc_len, leg,
                 L, P0, D0, P1, D1, arc, TH0, SGN, R, C, box_half, out, app_dir, app_right, lane_width, preview_min,
                 preview_time, wheelbase, steer_max):
    """The intersection expert's steering
    (:meth:`icv_envs.policies.platoon_control.PlatoonControl._steering`)
    compiled, per vehicle in the order of the array code: the preview
    distance ``max(preview_min, v preview_time)`` ahead along the route
    (``IntersectionLayout.route_points`` of the kept lane's path on the
    approach, else of the vehicle's path: the approach or departure line,
    the turn arc in the box), before the stop line the lane centre or the
    lane-change curve (:func:`icv_envs.formation.bezier._lane_change_lateral`),
    then pure pursuit (:func:`icv_envs.formation.bezier._pure_pursuit_steering`)
    clipped to ``steer_max`` (paper Sec. 2.2, eq. (Bezier) and the preview
    law). Returns the steering angles."""
    n = x.shape[0]
    phi = np.empty(n)
    for i in range(n):
        v = speed[i]
        ld = max(preview_min, v * preview_time)
        sp = s[i] + ld
        appr = phase[i] == 0
        kl = min(max(klane[i], 0), 2)
        p = 3 * mv[i] + kl if appr else pid[i]
        Lp = L[p]
        if sp > Lp:
            t = sp - Lp
            px = P1[p, 0] + t * D1[p, 0]
            py = P1[p, 1] + t * D1[p, 1]
        else:
            px = P0[p, 0] + sp * D0[p, 0]
            py = P0[p, 1] + sp * D0[p, 1]
            if arc[p] and sp >= 0.0:
                th = TH0[p] + SGN[p] * sp / R[p]
                px = C[p, 0] + R[p] * np.cos(th)
                py = C[p, 1] + R[p] * np.sin(th)
        if appr and sp < 0.0:
            lat = (kl + 0.5) * lane_width
            up = u[i] + ld
            if lc_lane[i] >= 0:
                xa = up
                x0a = lc_u0[i]
                y0a = lc_lat0[i]
                y1a = lc_lat1[i]
                d = lc_len[i]
                sl = min(max((xa - x0a) / d, 0.0), 1.0)
                tt = 0.5 + np.sinh(np.arcsinh(4.0 * sl - 2.0) / 3.0)
                tt = tt - (((tt - 1.5) * tt + 1.5) * tt - sl) / ((3.0 * tt - 3.0) * tt + 1.5)
                tt = min(max(tt, 0.0), 1.0)
                if xa <= x0a:
                    lat = y0a
                elif xa >= x0a + d:
                    lat = y1a
                else:
                    lat = y0a + (y1a - y0a) * (tt * tt * (3.0 - 2.0 * tt))
            g = leg[i]
            ox = box_half * out[g, 0]
            oy = box_half * out[g, 1]
            px = ox + up * app_dir[g, 0] + lat * app_right[g, 0]
            py = oy + up * app_dir[g, 1] + lat * app_right[g, 1]
        dx = px - x[i]
        dy = py - y[i]
        dist = np.hypot(dx, dy)
        lateral = np.cos(heading[i]) * dy - np.sin(heading[i]) * dx
        if dist > 0.0:
            curv = 2.0 * lateral / (dist * dist)
        else:
            curv = 0.0
        a = np.arctan(wheelbase * curv)
        phi[i] = min(max(a, -steer_max), steer_max)
    return phi


@nb.njit(cache=True)
def envelope_pairs(lead, coord, rows, signal_only, length, speed, grp, co, phase, member_T, idm_T, member_s0,
                   idm_s0, a_max, idm_b, sqrt_ab2, gipps_b, gipps_tau, gipps_bt2, in_box, cap, cap_other):
    """The leader part of the intersection experts' safety envelope
    (:meth:`icv_envs.policies.platoon_control.PlatoonControl._envelope`)
    compiled, entry by entry of the corridor index (``lead``, ``coord``,
    ``rows``, ``signal_only``): a leader listed only by its turn signal and
    already alongside (bumper gap < 0) is passed for the next one, at most
    three times; then IDM's interaction term (time gap and standstill
    distance of a member of the leader's group or of two coordinated
    vehicles past the stop line, else IDM's) and Gipps' safe speed (``b =
    gipps_b``, reaction ``gipps_tau``, room ``gap - member_s0``), the
    smaller; in the box ``inf`` unless ``in_box``. The caps are lowered in
    place: ``cap`` towards every leader, ``cap_other`` towards leaders of
    another group. ``sqrt_ab2 = 2 sqrt(a_max idm_b)``, ``gipps_bt2 =
    (gipps_b gipps_tau)^2``, as the array code computes them. Returns the
    number of signal-only leaders passed."""
    passed = 0
    for e in range(lead.shape[0]):
        le = lead[e]
        if le < 0:
            continue
        me = rows[e]
        for _ in range(3):
            gap0 = coord[le] - coord[e] - 0.5 * (length[me] + length[rows[le]])
            if not (signal_only[le] and gap0 < 0.0):
                break
            passed += 1
            le = lead[le]
            if le < 0:
                break
        if le < 0:
            continue
        ld = rows[le]
        gap = coord[le] - coord[e] - 0.5 * (length[me] + length[ld])
        same = grp[me] == grp[ld] and grp[me] >= 0
        member = same or (co[me] and co[ld] and phase[ld] >= 1)
        T = member_T if member else idm_T
        s0 = member_s0 if member else idm_s0
        v = speed[me]
        dv = v - speed[ld]
        x = v * T + v * dv / sqrt_ab2
        s_star = s0 + (x if x > 0.0 else 0.0)
        g = gap if gap > 0.1 else 0.1
        r = s_star / g
        safe = a_max * (1.0 - r * r)
        room = gap - member_s0
        vl = speed[ld]
        vs = -gipps_b * gipps_tau + np.sqrt(gipps_bt2 + vl * vl + 2.0 * gipps_b * (room if room > 0.0 else 0.0))
        gp = (vs - v) / gipps_tau
        if gp < safe:
            safe = gp
        if not in_box and phase[me] == 1:
            safe = np.inf
        if safe < cap[me]:
            cap[me] = safe
        if not same and safe < cap_other[me]:
            cap_other[me] = safe
    return passed


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


@nb.njit(cache=True, error_model="numpy")
def _idm_free1(v, free_pow, a_max, T, s0, root):
    """``traffic.idm_acceleration`` of one vehicle without a leader (gap
    ``inf``, ``dv = 0``): ``a_max (1 - free_pow - (s*/inf)^2)`` with ``s* =
    s0 + max(0, v T + v 0 / root)``, ``root = 2 sqrt(a_max b)`` and
    ``free_pow`` the free term's power (numpy's)."""
    w = v * T + v * 0.0 / root
    s_star = s0 + (0.0 if 0.0 > w else w)
    q = s_star / np.inf
    return a_max * (1.0 - free_pow - q * q)


@nb.njit(cache=True)
def _feedback1(a_ref, x, x_ref, v, v_ref, kp, kv, lo, hi):
    """``formation.control._longitudinal_feedback`` of one vehicle:
    ``clip(a_ref + kp (x - x_ref) + kv (v - v_ref), lo, hi)``."""
    return clip1(a_ref + kp * (x - x_ref) + kv * (v - v_ref), lo, hi)


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def platoon_accelerations(v, free_pow, a_free, b, T, s0, mode, mode_follow, mode_tree, u, X, xref, vref, tight, vcap,
                          clip_err, kp, kv, comfort_lo, comfort_hi, a_min, a_max):
    """The intersection experts' longitudinal law
    (:meth:`icv_envs.policies.platoon_control.PlatoonControl._longitudinal`):
    every vehicle the IDM without a leader (``free_pow`` its free term's
    power, from numpy; the interaction term with an infinite gap, as
    ``traffic.idm_acceleration`` takes it; ``a_free`` its maximum
    acceleration), then followers (``mode_follow``) the feedback law on the
    reference ``xref`` (the error clipped to ``+-clip_err``) in the comfort
    range, and tree vehicles (``mode_tree``) the feedback law on ``-xref``
    in ``-X``, clipped to ``[a_min, a_max]``, then to ``[a_min or comfort_lo
    (tight or not), a_max]``, then capped by the virtual cap ``vcap``.
    Returns ``(acc, binding)``: ``binding`` the tree vehicles whose cap is
    more than 0.5 m/s^2 below their law."""
    n = v.shape[0]
    acc = np.empty(n)
    root = 2.0 * math.sqrt(a_free * b)
    binding = 0
    for i in range(n):
        acc[i] = _idm_free1(v[i], free_pow[i], a_free, T, s0, root)
        if mode[i] == mode_follow:
            # the reference error clipped to +-clip_err first
            x = u[i]
            xr = x + clip1(xref[i] - x, -clip_err, clip_err)
            acc[i] = _feedback1(0.0, x, xr, v[i], vref[i], kp, kv, comfort_lo, comfort_hi)
        elif mode[i] == mode_tree:
            x = -X[i]
            xr = x + clip1(-xref[i] - x, -clip_err, clip_err)
            a = _feedback1(0.0, x, xr, v[i], vref[i], kp, kv, a_min, a_max)
            a = clip1(a, a_min if tight[i] else comfort_lo, a_max)
            vc = vcap[i]
            if vc < a - 0.5:
                binding += 1
            acc[i] = a if a < vc else vc
    return acc, binding


@nb.njit(cache=True)
def virtual_caps(n, rows_all, kk, U, X, rear, rear_row, speed, D_safe, b, tau, bt2):
    """The virtual lane's safe-speed caps
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._virtual_cap`):
    for member ``rows_all[j]`` of node ``kk[j]``, Gipps' safe speed behind
    the rear vehicle of every earlier node ``i`` it conflicts with
    (``U[i, kk[j]]``), the smallest, as an acceleration cap ``(v_safe - v) /
    tau``; ``inf`` for every other vehicle (and for members without such a
    node); ``bt2 = (b tau)^2`` as the caller's Python computes it. The array
    code's operations in its order (``sqrt`` is exactly rounded everywhere;
    its ``maximum(G, 0)`` returns 0 on a tie)."""
    cap = np.full(n, np.inf)
    K = rear.shape[0]
    for j in range(rows_all.shape[0]):
        r = rows_all[j]
        k = kk[j]
        best = np.inf
        for i in range(K):
            if U[i, k]:
                G = X[r] - rear[i] - D_safe
                vr = speed[rear_row[i]]
                vs = -b * tau + math.sqrt(bt2 + vr * vr + 2.0 * b * (G if G > 0.0 else 0.0))
                if vs < best:
                    best = vs
        cap[r] = (best - speed[r]) / tau
    return cap


@nb.njit(cache=True)
def _layers_before(depths, offset, lens, top):
    """``before[m]``: the summed length of the longest node of every layer
    below ``m`` (layers ``0..top``; node ``k`` of depth ``depths[k + offset]``
    and length ``lens[k]``), as ``numpy.maximum.at`` then ``cumsum`` take them
    (the maximum returns the new length on a tie; the sum runs in order).
    ``before`` has ``top + 2`` entries."""
    layer_max = np.zeros(top + 1)
    for k in range(lens.shape[0]):
        d = depths[k + offset]
        layer_max[d] = layer_max[d] if layer_max[d] > lens[k] else lens[k]
    before = np.empty(top + 2)
    before[0] = 0.0
    s = 0.0
    for i in range(top + 1):
        s += layer_max[i]
        before[i + 1] = s
    return before


@nb.njit(cache=True)
def anticipated_references(cand, mv, leg, dist, X, speed, conflict, leg_of, mvs, rear_row, rear, depths, lens, x0,
                           D_t, den):
    """The references the adjusting zone's free vehicles ``cand`` would get
    if their nodes were made now
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._anticipate`):
    per candidate, the current nodes it conflicts with, up to the first
    node of its own leg with a vehicle behind it; its depth ``1 +`` their
    largest depth (0 without one); the layer reference ``x0 + depth D_t +``
    the longest node of every layer before it; the bound ``D_t`` behind the
    rear of those nodes (``-inf`` without one) and the first node attaining
    it; their maximum ``R``; the braking room ``v^2 / den``; the hold ``R -
    X``. Returns ``(ref, lb, pred, R, room, H)``. The array code's
    operations in its order (the layers' longest node and their running sum
    as ``maximum.at`` and ``cumsum`` take them; ``argmax``'s first index)."""
    nc = cand.shape[0]
    K = mvs.shape[0]
    C = np.zeros((nc, K), dtype=np.bool_)
    dnew = np.empty(nc, dtype=np.int64)
    top = 0
    for k in range(K):
        if depths[k] > top:
            top = depths[k]
    for j in range(nc):
        c = cand[j]
        first_behind = K
        for k in range(K):
            if leg_of[mvs[k]] == leg[c] and dist[rear_row[k]] >= dist[c]:
                first_behind = k
                break
        m = 0
        for k in range(K):
            ck = conflict[mv[c], mvs[k]] and k < first_behind
            C[j, k] = ck
            if ck and depths[k] > m:
                m = depths[k]
        dnew[j] = 1 + m
        if dnew[j] > top:
            top = dnew[j]
    before = _layers_before(depths, 0, lens, top)
    ref = np.empty(nc)
    lb = np.empty(nc)
    pred = np.zeros(nc, dtype=np.int64)
    R = np.empty(nc)
    room = np.empty(nc)
    H = np.empty(nc)
    for j in range(nc):
        c = cand[j]
        ref[j] = x0 + dnew[j] * D_t + before[dnew[j]]
        best = -np.inf
        arg = 0
        for k in range(K):
            v = rear[k] + D_t if C[j, k] else -np.inf
            if v > best:
                best = v
                arg = k
        lb[j] = best
        pred[j] = arg
        R[j] = ref[j] if ref[j] > lb[j] else lb[j]
        room[j] = speed[c] * speed[c] / den
        H[j] = R[j] - X[c]
    return ref, lb, pred, R, room, H


@nb.njit(cache=True)
def tree_layers(mvs, conflict, xf, lens, rear, D_t):
    """The virtual platoon's tree and references for nodes in order
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon.tree`): the
    conflict block of the nodes' movements, the tree-layers
    (:func:`icv_envs.platoon._kernels.depths_of`), the layer references of
    :func:`icv_envs.platoon.tree._reference_positions` (the first vehicles'
    ``X`` made nondecreasing first), the upper triangle ``U`` (earlier
    conflicting nodes), and per node the bound ``D_t`` behind the rear of
    its earlier conflicting nodes (``-inf`` without one) with the first node
    attaining it. Returns ``(depths, refs, U, lb, pred)``; the array code's
    operations in its order (``maximum.accumulate``, ``maximum.at`` and
    ``cumsum`` as numpy takes them; ``argmax``'s first index)."""
    K = mvs.shape[0]
    C = np.empty((K, K), dtype=np.bool_)
    for i in range(K):
        for j in range(K):
            C[i, j] = conflict[mvs[i], mvs[j]]
    depths = depths_of(C)
    # _reference_positions(maximum.accumulate(xf), lens, depths, D_t)
    top = 0
    for k in range(K + 1):
        if depths[k] > top:
            top = depths[k]
    before = _layers_before(depths, 1, lens, top)
    refs = np.empty(K + 1)
    x0 = xf[0] - D_t
    for k in range(K + 1):
        refs[k] = x0 + depths[k] * D_t + before[depths[k]]
    refs[0] = x0
    U = np.zeros((K, K), dtype=np.bool_)
    lb = np.empty(K)
    pred = np.zeros(K, dtype=np.int64)
    for j in range(K):
        best = -np.inf
        arg = 0
        for i in range(K):
            if i < j and C[i, j]:
                U[i, j] = True
                v = rear[i] + D_t
            else:
                v = -np.inf
            if v > best:
                best = v
                arg = i
        lb[j] = best
        pred[j] = arg
    return depths, refs, U, lb, pred


@nb.njit(cache=True)
def follow_references(k, rr, ref, vid, dist, klane, sig, phase, u, xg, speed, mode_follow, mode, xref, vref):
    """Formation following of
    :meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`,
    in place: followers ``k`` of the vehicles at rows ``rr`` (-1: gone).
    Two vehicles referring to each other (a safety net) lose the nearer
    one's reference (``ref = -1``; the test reads the references as they
    were before any is cleared); a follower ahead of its reference vehicle
    in that vehicle's lane or in the lane it signals into (``sig``), still
    approaching, drives free; the others follow (``mode_follow``) at ``u``
    of the reference vehicle minus their offset ``xg``, at its speed.
    Returns ``(cycles broken, followers ahead of their reference)``."""
    m = k.shape[0]
    cyc = np.zeros(m, dtype=np.bool_)
    for j in range(m):
        r = rr[j]
        q = r if r > 0 else 0
        cyc[j] = r >= 0 and ref[q] == vid[k[j]] and dist[k[j]] < dist[q]
    n_cyc = 0
    n_ahead = 0
    for j in range(m):
        if cyc[j]:
            n_cyc += 1
            ref[k[j]] = -1
    for j in range(m):
        if cyc[j] or rr[j] < 0:
            continue
        i = k[j]
        r = rr[j]
        in_its_lanes = klane[i] == klane[r] or klane[i] == sig[r]
        if in_its_lanes and dist[i] < dist[r] and phase[i] == 0:
            n_ahead += 1
            continue
        mode[i] = mode_follow
        xref[i] = u[r] - xg[i]
        vref[i] = speed[r]
    return n_cyc, n_ahead


@nb.njit(cache=True)
def tree_references(rows_all, kk, first_of, refs, lb_of, pred_of, rear_row, X, xg, speed, v0, hold_gap, mode_tree,
                    mode, xref, vref, tight, hold):
    """The virtual platoon's references of the live members ``rows_all`` of
    nodes ``kk``, in place (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`):
    a node's first vehicle its layer reference (never ahead of itself) at
    ``v0``, the others their offset behind the first vehicle at its speed;
    the bound behind an earlier conflicting node's rear (``lb_of``) binds
    where it lies ahead of that (``tight``: full braking), at the speed of
    that rear vehicle; ``hold`` where the vehicle is already more than
    ``hold_gap`` (+1e-9) inside that bound."""
    for j in range(rows_all.shape[0]):
        r = rows_all[j]
        c = kk[j]
        first = first_of[c]
        if r == first:
            a = refs[c + 1]
            paper = a if a > X[r] else X[r]
            vpaper = v0
        else:
            paper = X[first] + xg[r] - xg[first]
            vpaper = speed[first]
        lb = lb_of[c]
        bind = lb > paper
        mode[r] = mode_tree
        hold[r] = X[r] < lb - hold_gap - 1e-9
        xref[r] = lb if bind else paper
        vref[r] = speed[rear_row[pred_of[c]]] if bind else vpaper
        tight[r] = bind


@nb.njit(cache=True)
def stop_flags(phase, allowed, mv, klane, lc_lane, tlane, dist, R1, coordinated, hold, advised, u, length):
    """Who may not enter the box (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`):
    an approaching vehicle in a lane its movement may not leave from
    (``allowed[mv, clip(klane, 0, 2)]``), changing lanes or not yet in its
    target lane; inside ``R1`` without coordination; held; advised (rows
    ``advised``); none already at the line (``u > -length / 2``). Returns
    ``(stop, held approaching vehicles)``."""
    n = phase.shape[0]
    stop = np.empty(n, dtype=np.bool_)
    held = 0
    for i in range(n):
        lane = klane[i]
        if lane < 0:
            lane = 0
        if lane > 2:
            lane = 2
        appr = phase[i] == 0
        s = appr and (not allowed[mv[i], lane] or lc_lane[i] >= 0 or klane[i] != tlane[i])
        s = s or (appr and dist[i] <= R1 and not coordinated[i])
        s = s or (appr and hold[i])
        if appr and hold[i]:
            held += 1
        stop[i] = s
    for j in range(advised.shape[0]):
        stop[advised[j]] = True
    for i in range(n):
        stop[i] = stop[i] and not (u[i] > -0.5 * length[i])
    return stop, held
