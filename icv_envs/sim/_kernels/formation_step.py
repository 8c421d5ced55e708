"""The formation layer's step outside SciPy's assignment, compiled in a few
passes (``FormationManager.update`` and ``_reform``, paper Sec. 3.2-3.3; the
rules every kernel here follows: :mod:`icv_envs.sim._kernels`): membership
and front targets (:func:`membership_pass`), the front-target hold, lane
windows and stall clocks (:func:`hold_pass`), the re-plan test
(:func:`off_reference_rows`), the re-forming's frame and costs
(:func:`reform_costs`) and its slots (:func:`reform_slots`); from stop 50
the step but the re-forming in one call (:func:`update_pass`: membership,
the members' join profiles, the hold, the re-plan test, the re-plans and
the references) and a re-plan in one call (:func:`plan_pass`: the plans'
inputs, the search's start, the search and the store). Each performs
the operations of the array code it replaced in the same order (frozen in
``tests/test_formation_update.py``); the per-vehicle rules and lane windows
they use live in :mod:`icv_envs.sim._kernels.formation`."""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.formation._kernels import min_cost_assignment, plan_search_store, profile_eval
from icv_envs.sim._kernels.formation import (_wrap1, drivable_lane_bits, eligible_free_rows, hold_targets,
                                             leaving_rows, plan_inputs_rows, reference_rows, room_ahead)
from icv_envs.sim._kernels.physics import lane_of1, npy_mod

__all__ = ["hold_pass", "membership_pass", "off_reference_rows", "plan_pass", "reform_costs", "reform_members",
           "reform_slots",
           "update_pass"]


@nb.njit(cache=True)
def membership_pass(group, tgt_lane, vid, crashed, cx, cy, lc_lane, exit_id, slot_gid, A_all, L_all, cnt_all,
                    stall_all, g_live, next_gid, advance, length, n_exits, lane_width, total_lanes, n_lanes, has_ramp,
                    diverge_iv, exit_lookahead, per_lane, max_size, join_distance, create_new, new_formation_gap,
                    formation_gap):
    """``FormationManager.update`` up to the front-target hold, in one pass
    (the order and arithmetic of the array code it replaced, frozen in
    ``tests/test_formation_update.py``):

    1. the front targets of the live formations ``g_live`` advance by
       ``advance`` (``speed * dt``; folded onto the ring, ``length < 0``: a
       straight road);
    2. members about to exit leave (:func:`leaving_rows`; their group and
       target lane become -1, their plan's slot -1);
    3. formations whose member count differs from ``cnt_all`` are marked;
    4. the free vehicles that may join (:func:`eligible_free_rows`) join the
       open formations (``0 < members < max_size``) in id order: each takes
       the vehicles still free within ``[-length - join_distance,
       join_distance]`` of its front target, in row order, up to its room;
    5. with ``create_new``, the free vehicles left on a main lane, front-most
       first (a stable order), found a formation each where no formation
       (those just founded included) is within ``new_formation_gap`` of
       them; the new ids follow ``next_gid`` (``A_all`` etc. must have room
       for one per vehicle, and one more);
    6. ``room[k]``: the distance from formation ``k``'s front target to the
       rear of the nearest formation ahead minus ``formation_gap``
       (:func:`room_ahead`; nan: none ahead).

    ``group``, ``tgt_lane``, ``slot_gid`` and the formation arrays are
    updated in place. Returns ``(changed, next_gid, g_arr, room)``: the
    marked formation ids as a mask over ``A_all``'s ids, the next id, the
    live formations after step 5 (ascending) and their room."""
    cap = A_all.shape[0]
    chg = np.zeros(cap, dtype=np.bool_)
    n = cx.shape[0]
    G0 = g_live.shape[0]
    for k in range(G0):
        g = g_live[k]
        x = A_all[g] + advance
        A_all[g] = npy_mod(x, length) if length >= 0.0 else x
    if n and n_exits:
        leave = leaving_rows(group, exit_id, cx, cy, lc_lane, lane_width, total_lanes, n_lanes, has_ramp, diverge_iv,
                             length, exit_lookahead, per_lane)
        for q in range(leave.shape[0]):
            r = leave[q]
            chg[group[r]] = True
            group[r] = -1
            tgt_lane[r] = -1
            slot_gid[vid[r]] = -1
    counts = np.zeros(cap, dtype=np.int64)
    for r in range(n):
        if group[r] >= 0:
            counts[group[r]] += 1
    for k in range(G0):
        g = g_live[k]
        if counts[g] != cnt_all[g]:
            chg[g] = True
    if n:
        free = eligible_free_rows(group, crashed, cx, cy, lc_lane, exit_id, lane_width, total_lanes, n_lanes,
                                  has_ramp, n_exits, diverge_iv, length, exit_lookahead, per_lane)
    else:
        free = np.zeros(0, dtype=np.int64)
    nf = free.shape[0]
    still = np.ones(nf, dtype=np.bool_)
    left = nf
    if nf and G0:
        for k in range(G0):
            if left == 0:
                break
            g = g_live[k]
            size = counts[g]
            if not (size > 0 and size < max_size):
                continue
            lo = -L_all[g] - join_distance
            room_left = max_size - size
            for j in range(nf):
                if room_left == 0:
                    break
                if not still[j]:
                    continue
                rel = _wrap1(cx[free[j]] - A_all[g], length)
                if rel >= lo and rel <= join_distance:
                    group[free[j]] = g
                    chg[g] = True
                    still[j] = False
                    left -= 1
                    room_left -= 1
    gid_next = next_gid
    if create_new and left:
        # the free vehicles left on a main lane, by -cx ascending, ties in row order (a stable sort)
        cand = np.empty(left, dtype=np.int64)
        nc = 0
        for j in range(nf):
            if still[j] and lane_of1(cy[free[j]], lane_width, total_lanes) < n_lanes:
                r = free[j]
                key = -cx[r]
                p = nc
                while p > 0 and -cx[cand[p - 1]] > key:
                    cand[p] = cand[p - 1]
                    p -= 1
                cand[p] = r
                nc += 1
        for q in range(nc):
            r = cand[q]
            if group[r] >= 0:
                continue
            clear = True
            for k in range(G0 + gid_next - next_gid):
                g = g_live[k] if k < G0 else next_gid + (k - G0)
                rel = _wrap1(cx[r] - A_all[g], length)
                if -L_all[g] - new_formation_gap < rel and rel < new_formation_gap:
                    clear = False
                    break
            if clear:
                g = gid_next
                gid_next += 1
                A_all[g] = cx[r]
                L_all[g] = 0.0
                cnt_all[g] = 0
                stall_all[g] = 0.0
                group[r] = g
                chg[g] = True
    G = G0 + gid_next - next_gid
    g_arr = np.empty(G, dtype=np.int64)
    g_arr[:G0] = g_live
    for k in range(G0, G):
        g_arr[k] = next_gid + (k - G0)
    room = np.full(G, np.nan)
    if G > 1:
        A = np.empty(G)
        Lf = np.empty(G)
        for k in range(G):
            A[k] = A_all[g_arr[k]]
            Lf[k] = L_all[g_arr[k]]
        nearest = room_ahead(A, Lf, length)
        for k in range(G):
            if np.isfinite(nearest[k]):
                room[k] = nearest[k] - formation_gap
    return chg, gid_next, g_arr, room


@nb.njit(cache=True)
def hold_pass(grp, g_arr, A_all, L_all, bits_all, stall_all, chg_all, room, tb, cx, d_members, vid, deadline, time,
              max_lead, brake_step, stall_error, length, dt, stall_time, lookahead, road_length, lane_ends, ob_lane,
              ob_lo, ob_hi, allowed):
    """The front-target hold of ``FormationManager.update`` after the join profiles, in one
    call: :func:`hold_targets` over the live formations ``g_arr`` (front
    targets braked in ``A_all``); a formation with members and not marked
    in ``chg_all`` whose drivable lane set over ``[A - L - 10, A +
    lookahead]`` (:func:`drivable_lane_bits`, the window start folded with
    NumPy's ``mod`` on a ring) differs from ``bits_all`` is marked; then the
    stall clocks: a formation with a late member and not marked runs its
    clock by ``dt`` and is marked (clock back to 0) once it reaches
    ``stall_time``; any other formation with members restarts it. The
    arithmetic of the array code it replaced, element by element.
    ``length``: the ring's length, or -1 on a straight road;
    ``road_length``: the road's length either way (it caps a window's span)."""
    periodic = length >= 0.0
    G = g_arr.shape[0]
    slot_of_gid = np.full(g_arr[G - 1] + 1, -1, dtype=np.int64)
    A = np.empty(G)
    chg = np.empty(G, dtype=np.bool_)
    for k in range(G):
        slot_of_gid[g_arr[k]] = k
        A[k] = A_all[g_arr[k]]
        chg[k] = chg_all[g_arr[k]]
    has, brake, late = hold_targets(grp, slot_of_gid, A, chg, room, tb, cx, d_members, vid, deadline, time, max_lead,
                                    brake_step, stall_error, length)
    nchk = 0
    for k in range(G):
        if brake[k]:
            A_all[g_arr[k]] = A[k]
        if has[k] and not chg[k]:
            nchk += 1
    if nchk:
        ks = np.empty(nchk, dtype=np.int64)
        a = np.zeros(nchk)
        span = np.empty(nchk)
        x0 = np.empty(nchk)
        x1 = np.empty(nchk)
        q = 0
        for k in range(G):
            if has[k] and not chg[k]:
                ks[q] = k
                x0[q] = A[k] - L_all[g_arr[k]] - 10.0
                x1[q] = A[k] + lookahead
                span[q] = min(max(x1[q] - x0[q], 0.0), road_length)
                if periodic:
                    a[q] = npy_mod(x0[q], road_length)
                q += 1
        bits = drivable_lane_bits(a, span, x0, x1, periodic, road_length, lane_ends, ob_lane, ob_lo, ob_hi, allowed)
        for q in range(nchk):
            g = g_arr[ks[q]]
            if bits[q] != bits_all[g]:
                chg_all[g] = True
    for k in range(G):
        if not has[k]:
            continue
        g = g_arr[k]
        lt = late[k] and not chg_all[g]
        s = stall_all[g] + dt if lt else 0.0
        if lt and s >= stall_time:
            chg_all[g] = True
            s = 0.0
        stall_all[g] = s


@nb.njit(cache=True)
def off_reference_rows(group, m, cx, anchor_of, tb, d, length, replan_error):
    """Members ``m`` (with join-profile offsets ``d``) farther than
    ``replan_error`` from their reference: ``|wrap(cx - ((anchor_of[group] -
    tb) + d))| > replan_error`` (``FormationManager.update``'s re-plan test,
    its arithmetic element by element; ``length < 0``: a straight road).
    Returns their rows, in the order of ``m``."""
    n = m.shape[0]
    out = np.empty(n, dtype=np.int64)
    k = 0
    for q in range(n):
        r = m[q]
        if abs(_wrap1(cx[r] - ((anchor_of[group[r]] - tb[r]) + d[q]), length)) > replan_error:
            out[k] = r
            k += 1
    return out[:k]


@nb.njit(cache=True)
def update_pass(group, tgt_lane, vid, crashed, cx, cy, lc_lane, exit_id, slot_gid, A_all, L_all, cnt_all, stall_all,
                g_live, next_gid, advance, length, n_exits, lane_width, total_lanes, n_lanes, has_ramp, diverge_iv,
                exit_lookahead, per_lane, max_size, join_distance, create_new, new_formation_gap, formation_gap,
                bits_all, tb, deadline, time, max_lead, brake_step, stall_error, dt, stall_time, lookahead,
                road_length, lane_ends, ob_lane, ob_lo, ob_hi, allowed, replan_error, speed, accel, v_form, period,
                accel_lim, decel, jerk, t_min, grow, cap, band_lo, band_hi, cap_free, tau, t0_tab, T_tab, d0_tab,
                v0_tab, a0_tab, c3_tab, c4_tab, c5_tab, fd_tab, fv_tab, fa_tab):
    """``FormationManager.update`` but the re-forming, in one call (from
    stop 50; four to seven calls and the Python between them before, the
    same operations in the same order): :func:`membership_pass` (``group``
    .. ``formation_gap``); the members (rows with ``group >= 0``, ascending)
    and their join profiles at ``time``
    (:func:`~icv_envs.formation._kernels.profile_eval` on the plans' tables
    ``t0_tab`` .. ``fa_tab``); with live formations, :func:`hold_pass` with
    the profiles' offsets (``bits_all`` .. ``allowed``; ``length`` the
    ring's length or -1). When no formation was marked for re-forming (the
    re-forming moves slots; the rest of the step is then made in Python):
    :func:`off_reference_rows` of the members (``replan_error``), the plans
    of those (:func:`plan_pass`: ``speed`` .. ``tau``, ``period`` the
    traffic's ring length or -1) and, after them, the members' profiles
    again, then the references of every vehicle
    (:func:`~icv_envs.sim._kernels.formation.reference_rows`).

    Returns ``(changed, next_gid, M, P, off, R, lane_ref, member)``: the
    marked formation ids below ``next_gid``, ascending; the next id; ``M
    (2, m)`` the members' rows and ids; ``P (3, m)`` their profiles ``(d,
    v, a)`` (after the plans); ``off`` the members that were re-planned;
    ``reference_rows``' results (empty when a formation was marked)."""
    chg, gid_next, g_arr, room = membership_pass(
        group, tgt_lane, vid, crashed, cx, cy, lc_lane, exit_id, slot_gid, A_all, L_all, cnt_all, stall_all, g_live,
        next_gid, advance, length, n_exits, lane_width, total_lanes, n_lanes, has_ramp, diverge_iv, exit_lookahead,
        per_lane, max_size, join_distance, create_new, new_formation_gap, formation_gap)
    anchors = A_all[:gid_next + 1]  # (FormationManager._anchor_lut)
    rows = np.flatnonzero(group >= 0)
    m = rows.shape[0]
    M = np.empty((2, m), dtype=np.int64)
    for q in range(m):
        M[0, q] = rows[q]
        M[1, q] = vid[rows[q]]
    P = profile_eval(M[1], time, t0_tab, T_tab, fd_tab, fv_tab, fa_tab, d0_tab, v0_tab, a0_tab, c3_tab, c4_tab,
                     c5_tab)
    if m and g_arr.shape[0]:
        hold_pass(group, g_arr, A_all, L_all, bits_all, stall_all, chg, room, tb, cx, P[0], vid, deadline, time,
                  max_lead, brake_step, stall_error, length, dt, stall_time, lookahead, road_length, lane_ends,
                  ob_lane, ob_lo, ob_hi, allowed)
    changed = np.flatnonzero(chg[:gid_next])
    off = np.zeros(0, dtype=np.int64)
    if changed.shape[0]:
        R = np.empty((3, 0))
        return changed, gid_next, M, P, off, R, np.empty(0, dtype=np.int64), np.empty(0, dtype=np.bool_)
    if m:
        off = off_reference_rows(group, M[0], cx, anchors, tb, P[0], length, replan_error)
        if off.shape[0]:
            plan_pass(off, group, tb, anchors, cx, speed, accel, vid, v_form, length, time, accel_lim, decel, jerk,
                      t_min, grow, cap, band_lo, band_hi, cap_free, tau, t0_tab, T_tab, d0_tab, v0_tab, a0_tab,
                      c3_tab, c4_tab, c5_tab, fd_tab, fv_tab, fa_tab)
            P = profile_eval(M[1], time, t0_tab, T_tab, fd_tab, fv_tab, fa_tab, d0_tab, v0_tab, a0_tab, c3_tab,
                             c4_tab, c5_tab)
    R, lane_ref, member = reference_rows(group, tgt_lane, tb, anchors, M[0], P[0], P[1], P[2], v_form, period)
    return changed, gid_next, M, P, off, R, lane_ref, member


@nb.njit(cache=True)
def plan_pass(rows, group, tgt_behind, anchors, cx, speed, accel, vid, v_form, period, time, accel_lim, decel, jerk,
              t_min, grow, cap, band_lo, band_hi, cap_free, tau, t0_tab, T_tab, d0_tab, v0_tab, a0_tab, c3_tab,
              c4_tab, c5_tab, fd_tab, fv_tab, fa_tab):
    """``FormationManager._plan`` of members ``rows`` (non-empty) in one call
    (from stop 50; three kernels and NumPy's ``cbrt`` between them before):
    the plans' inputs (:func:`~icv_envs.sim._kernels.formation.plan_inputs_rows`,
    the acceleration clipped to ``[-decel, accel_lim]``), then
    :func:`~icv_envs.formation._kernels.plan_search_store` of ``vid[rows]``
    (the search's start, libm's ``cbrt``; the search within the speed band
    ``[band_lo, band_hi]`` relative to the formation and, for members that
    reach ``cap``, without it; the store into the tables, which must hold
    every id). Returns the durations."""
    d0, v0, a0 = plan_inputs_rows(rows, group, tgt_behind, anchors, cx, speed, accel, v_form, -decel, accel_lim,
                                  period)
    ids = np.empty(rows.shape[0], dtype=np.int64)
    for i in range(rows.shape[0]):
        ids[i] = vid[rows[i]]
    return plan_search_store(ids, time, d0, v0, a0, accel_lim, decel, jerk, t_min, grow, cap, band_lo, band_hi,
                             cap_free, tau, t0_tab, T_tab, d0_tab, v0_tab, a0_tab, c3_tab, c4_tab, c5_tab, fd_tab,
                             fv_tab, fa_tab)


@nb.njit(cache=True)
def _interp_lane(x, xp, fp):
    """``numpy.interp(x, xp, fp)`` of one value for ascending distinct
    ``xp`` (at least two) with ``xp[0] <= x <= xp[-1]``: NumPy's rule (the
    end value at ``x == xp[-1]``, ``fp[j]`` at ``x == xp[j]``, else
    ``slope * (x - xp[j]) + fp[j]`` with ``slope = (fp[j+1] - fp[j]) /
    (xp[j+1] - xp[j])`` over the interval holding ``x``)."""
    m = xp.shape[0]
    if x == xp[m - 1]:
        return fp[m - 1]
    j = 0
    while j + 1 < m and xp[j + 1] <= x:
        j += 1
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    return slope * (x - xp[j]) + fp[j]


@nb.njit(cache=True)
def reform_costs(rows, cx, cy, anchor, lane_width, lanes, tx, tl, w1, w2, length):
    """The members ``rows`` of a formation in its frame and their assignment
    costs (``FormationManager._reform``, paper Sec. 3.3, eq. (lp) with cost
    ``F_w``): metres behind the front target ``x_v =
    wrap(anchor - cx)`` and fractional formation lane ``y_v`` (``lanes``:
    the lane set as floats, ascending; ``numpy.interp`` over it inside, a
    straight extension by lane widths outside), and ``cost[i, j] = w1 *
    dx * dx + w2 * dy * dy`` with ``dx = tx[j] - x_v[i]``, ``dy = tl[j] -
    y_v[i]`` (the targets ``tx``, lane ids ``tl`` from 1). The arithmetic of
    the array code it replaced, element by element. Returns ``cost``."""
    n = rows.shape[0]
    nl = lanes.shape[0]
    ids = np.empty(nl)
    for k in range(nl):
        ids[k] = k + 1.0
    cost = np.empty((n, n))
    for i in range(n):
        r = rows[i]
        p = cy[r] / lane_width
        if nl > 1:
            if p < lanes[0]:
                yv = 1.0 - (lanes[0] - p)
            elif p > lanes[nl - 1]:
                yv = nl + (p - lanes[nl - 1])
            else:
                yv = _interp_lane(p, lanes, ids)
        else:
            yv = 1.0 + (p - lanes[0])
        xv = _wrap1(anchor - cx[r], length)
        for j in range(n):
            dx = tx[j] - xv
            dy = tl[j] - yv
            cost[i, j] = w1 * dx * dx + w2 * dy * dy
    return cost


@nb.njit(cache=True)
def reform_slots(rows, slot, tx, tl, lanes, gid, vid, tgt_behind, tgt_lane, slot_gid, slot_behind):
    """Write the assignment ``slot`` (member ``i`` -> target ``slot[i]``) of
    the members ``rows``: ``tgt_behind = tx[slot]``, ``tgt_lane =
    lanes[tl[slot] - 1]``; returns the rows whose slot differs from the one
    their join plan was made for (``slot_gid``, ``slot_behind`` by vehicle
    id), in order: they need a new plan."""
    n = rows.shape[0]
    out = np.empty(n, dtype=np.int64)
    k = 0
    for i in range(n):
        r = rows[i]
        tgt_behind[r] = tx[slot[i]]
        tgt_lane[r] = lanes[tl[slot[i]] - 1]
        v = vid[r]
        if slot_gid[v] != gid or slot_behind[v] != tgt_behind[r]:
            out[k] = r
            k += 1
    return out[:k]


@nb.njit(cache=True)
def reform_members(rows, cx, cy, anchor, lane_width, lanes_f, lanes_i, tx, tl, w1, w2, length, gid, vid, tgt_behind,
                   tgt_lane, plan, group, anchors, speed, accel, v_form, time, accel_lim, decel, jerk, t_min, grow,
                   cap, band_lo, band_hi, cap_free, tau, slot_gid, slot_behind, deadline, t0_tab, T_tab, d0_tab,
                   v0_tab, a0_tab, c3_tab, c4_tab, c5_tab, fd_tab, fv_tab, fa_tab):
    """``FormationManager._reform`` of one formation after its lane set
    and targets (paper Sec. 3.3) in one call (from stop 56; before, three
    kernels with SciPy's ``linear_sum_assignment`` and the plan between
    them): the costs (:func:`reform_costs`), the minimum-cost assignment
    (:func:`~icv_envs.formation._kernels.min_cost_assignment`, SciPy's
    answer), the slots written (:func:`reform_slots`) and, with ``plan``
    (the plan tables hold every vehicle id), a join plan for each member
    whose slot changed (:func:`plan_pass` with ``period = length``), its
    slot, place and deadline ``time + T`` stored by vehicle id. Returns the
    rows whose slot changed (without ``plan`` the caller plans them)."""
    cost = reform_costs(rows, cx, cy, anchor, lane_width, lanes_f, tx, tl, w1, w2, length)
    slot = min_cost_assignment(cost)
    if slot.shape[0] and slot[0] < 0:  # (finite costs always have one; SciPy raised ValueError)
        raise ValueError("re-forming: the assignment's cost matrix holds NaN or inf entries")
    r = reform_slots(rows, slot, tx, tl, lanes_i, gid, vid, tgt_behind, tgt_lane, slot_gid, slot_behind)
    if plan and r.shape[0]:
        T = plan_pass(r, group, tgt_behind, anchors, cx, speed, accel, vid, v_form, length, time, accel_lim, decel,
                      jerk, t_min, grow, cap, band_lo, band_hi, cap_free, tau, t0_tab, T_tab, d0_tab, v0_tab, a0_tab,
                      c3_tab, c4_tab, c5_tab, fd_tab, fv_tab, fa_tab)
        for k in range(r.shape[0]):
            v = vid[r[k]]
            slot_gid[v] = gid
            slot_behind[v] = tgt_behind[r[k]]
            deadline[v] = time + T[k]
    return r
