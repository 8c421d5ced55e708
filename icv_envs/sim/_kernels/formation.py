"""The formation layer's front-target pass and drivable-lane windows,
compiled (the rules every kernel here follows:
:mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.formation._kernels import clip1
from icv_envs.sim._kernels.physics import lane_of1, npy_mod

__all__ = ["drivable_lane_bits", "drivable_lane_bits1", "eligible_free_rows", "hold_targets", "leaving_rows",
           "reference_rows", "room_ahead", "plan_inputs_rows"]


@nb.njit(cache=True)
def _window_bits(npc, p0s, p1s, lane_ends, ob_lane, ob_lo, ob_hi, allowed):
    """Bit set of the lanes in ``allowed`` that do not end within and are
    not blocked by an obstacle over any of the ``npc`` pieces
    ``[p0s[p], p1s[p]]`` of a window (``drivable_main_lanes``' test)."""
    bits = 0
    for lane in range(lane_ends.shape[0]):
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
    return bits


@nb.njit(cache=True)
def drivable_lane_bits1(x0, x1, periodic, length, lane_ends, ob_lane, ob_lo, ob_hi, allowed):
    """:meth:`icv_envs.sim.road.RoadLayout.drivable_main_lanes` of one
    window ``[x0, x1]``, as a bit set of the lanes also in ``allowed``: its
    window pieces (on a ring the start folded with NumPy's ``mod``, the
    span clipped to the road; on a straight road clipped at 0), then
    :func:`_window_bits`."""
    p0s = np.empty(2)
    p1s = np.empty(2)
    if periodic:
        span = min(max(x1 - x0, 0.0), length)
        a = npy_mod(x0, length)
        if a + span <= length:
            npc = 1
            p0s[0] = a
            p1s[0] = a + span
        else:
            npc = 2
            p0s[0] = a
            p1s[0] = length
            p0s[1] = 0.0
            p1s[1] = a + span - length
    else:
        npc = 1
        lo = max(x0, 0.0)
        p0s[0] = lo
        p1s[0] = max(x1, lo)
    return _window_bits(npc, p0s, p1s, lane_ends, ob_lane, ob_lo, ob_hi, allowed)


@nb.njit(cache=True)
def drivable_lane_bits(a, span, x0, x1, periodic, length, lane_ends, ob_lane, ob_lo, ob_hi, allowed):
    """Vectorised :meth:`icv_envs.sim.road.RoadLayout.drivable_main_lanes`
    over many windows, as bit sets (bit ``l`` set = lane ``l`` drivable
    over the whole window and in ``allowed``). On a ring, ``a`` is the
    window start folded onto the road and ``span`` its clipped length (both
    computed by the caller with numpy, as the scalar code does); on a
    straight road ``x0``/``x1`` are the window ends."""
    G = a.shape[0]
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
        bits = _window_bits(npc, p0s, p1s, lane_ends, ob_lane, ob_lo, ob_hi, allowed)
        out[g] = bits
    return out


@nb.njit(cache=True)
def _wrap1(d, length):
    """``RoadLayout.wrap`` of one float (``length < 0``: a straight road)."""
    if length < 0.0:
        return d
    half = 0.5 * length
    x = d + half
    if 0.0 <= x < length:  # fmod is exact and the identity there (a zero's sign does not survive "- half")
        return x - half
    return npy_mod(x, length) - half


@nb.njit(cache=True)
def hold_targets(grp, slot_of_gid, A, chg, room, tb, cx, d_members, vid, deadline, time, max_lead, brake_step,
                 stall_error, length):
    """The array part of ``FormationManager.update``'s front-target hold in one pass per
    quantity, over formations ``k`` (``slot_of_gid[gid] = k``, -1 for ids not
    asked about) with front targets ``A`` (updated in place), re-forming
    flags ``chg`` and room to the formation ahead ``room`` (nan: none):

    * ``implied[k]``: the largest ``wrap(cx + tb - A[k]) - d`` over the
      members (``d``: each member's join-profile offset, ``d_members`` in
      ascending row order of the members ``grp >= 0``), ``-inf`` for none;
    * the front target falls back by ``max(back, brake_step)`` (``brake_step
      = -anchor_brake * dt``) where ``back`` (the lead beyond ``max_lead``
      unless re-forming, capped by a negative room) is negative;
    * ``late[k]``: some member is farther than ``stall_error`` from its slot
      after its plan's deadline.

    Rows are visited in ascending order, as the segment reductions over a
    stable sort by formation id did; the arithmetic is theirs element by
    element. Returns ``(has, brake, late)``; ``length``: the ring's length,
    or -1 on a straight road."""
    G = A.shape[0]
    n = grp.shape[0]
    implied = np.full(G, -np.inf)
    has = np.zeros(G, dtype=np.bool_)
    kk = np.full(n, -1, dtype=np.int64)
    j = 0
    for r in range(n):
        g = grp[r]
        if g < 0:
            continue
        dref = d_members[j]
        j += 1
        k = slot_of_gid[g] if g < slot_of_gid.shape[0] else -1
        if k < 0:
            continue
        kk[r] = k
        has[k] = True
        val = _wrap1(cx[r] + tb[r] - A[k], length) - dref
        if val > implied[k]:
            implied[k] = val
    brake = np.zeros(G, dtype=np.bool_)
    for k in range(G):
        back = implied[k] + max_lead if (not chg[k]) and implied[k] < -max_lead else 0.0
        if room[k] < 0:
            back = min(back, room[k])
        if has[k] and back < 0:
            brake[k] = True
            step = back if back > brake_step else brake_step
            x = A[k] + step
            A[k] = npy_mod(x, length) if length >= 0.0 else x
    late = np.zeros(G, dtype=np.bool_)
    for r in range(n):
        k = kk[r]
        if k < 0:
            continue
        if abs(_wrap1(cx[r] - (A[k] - tb[r]), length)) > stall_error and time > deadline[vid[r]]:
            late[k] = True
    return has, brake, late


@nb.njit(cache=True)
def room_ahead(A, Lf, length):
    """Per formation ``i``: the distance from its front target ``A[i]`` to the
    rear ``A[j] - Lf[j]`` of the nearest other formation ahead (``wrap`` of
    the difference, ``length < 0``: a straight road), over the formations
    whose rear is not more than ``Lf[i]`` behind that front (``inf`` if
    none): ``FormationManager.update``'s pairwise matrix, one row at a time."""
    G = A.shape[0]
    out = np.full(G, np.inf)
    for i in range(G):
        best = np.inf
        for j in range(G):
            if j == i:
                continue
            r = _wrap1(A[j] - Lf[j] - A[i], length)
            if r > -Lf[i] and r < best:
                best = r
        out[i] = best
    return out


@nb.njit(cache=True)
def reference_rows(group, tgt_lane, tgt_behind, anchor_of, m, d, dv, dd, speed, period):
    """``FormationManager._references`` compiled: for the members ``m``
    (rows with ``group >= 0``, ascending) with join profiles ``(d, dv, dd)``,
    ``x_ref = (anchor_of[group] - tgt_behind) + d`` (``mod period`` on a ring,
    ``period < 0``: none), ``v_ref = speed + dv``, ``a_ref = dd``; ``nan``
    for free vehicles, whose ``lane_ref`` is -1 (members: ``tgt_lane``).
    Returns ``(R, lane_ref, member)``, ``R`` the rows ``x_ref, v_ref,
    a_ref`` of one ``(3, n)`` array (numba boxes each returned array for
    about 0.35 us, a view of a row costs 0.1)."""
    n = group.shape[0]
    R = np.full((3, n), np.nan)
    x_ref = R[0]
    v_ref = R[1]
    a_ref = R[2]
    lane_ref = np.empty(n, dtype=np.int64)
    member = np.empty(n, dtype=np.bool_)
    for i in range(n):
        member[i] = group[i] >= 0
        lane_ref[i] = tgt_lane[i] if member[i] else -1
    for q in range(m.shape[0]):
        r = m[q]
        x = (anchor_of[group[r]] - tgt_behind[r]) + d[q]
        if period > 0.0:
            x = npy_mod(x, period)
        x_ref[r] = x
        v_ref[r] = speed + dv[q]
        a_ref[r] = dd[q]
    return R, lane_ref, member


@nb.njit(cache=True, inline="always")
def _exit_ahead1(e, x, diverge_iv, period):
    """``RoadLayout.exit_ahead`` of one vehicle (``period < 0``: a straight road)."""
    ds = diverge_iv[e, 0]
    de = diverge_iv[e, 1]
    if period < 0.0:
        return ds - x
    return npy_mod(de - x, period) - (de - ds)


@nb.njit(cache=True, inline="always")
def _exit_lookahead1(lane, ramp_lane, base, per_lane):
    """``RoadLayout.exit_lookahead`` of one vehicle."""
    extra = ramp_lane - lane - 1
    return base + per_lane * (extra if extra > 0 else 0)


@nb.njit(cache=True)
def eligible_free_rows(group, crashed, cx, cy, lc_lane, exit_id, lane_width, total_lanes, n_lanes, has_ramp, n_exits,
                       diverge_iv, period, exit_lookahead, per_lane):
    """The free vehicles that may join or found a formation
    (``FormationManager.update``, through :func:`membership_pass`), in one
    pass: rows (ascending) of free vehicles (``group < 0``) not crashed;
    with a ramp lane, on a main lane and not changing lanes into the ramp
    lane (vehicles still on a ramp merge first, as free vehicles, and join
    from the main road: a formation cannot help them merge; so do vehicles
    changing into the ramp lane, an exit taken late); with exits, not
    within their exit lookahead ``+ 100 m`` of the diverge start unless
    past the diverge end (on a straight road: never once past it). The
    operations of ``RoadLayout.lane_of``/``exit_ahead``/``exit_lookahead``,
    in order."""
    n = cx.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if group[i] >= 0 or crashed[i]:
            continue
        if has_ramp:
            if not (lane_of1(cy[i], lane_width, total_lanes) < n_lanes and lc_lane[i] != n_lanes):
                continue
        if n_exits and exit_id[i] >= 0:
            e = exit_id[i]
            d = _exit_ahead1(e, cx[i], diverge_iv, period)
            dlen = diverge_iv[e, 1] - diverge_iv[e, 0]
            la = _exit_lookahead1(lane_of1(cy[i], lane_width, total_lanes), n_lanes, exit_lookahead, per_lane)
            soon = d < la + 100.0 and d >= -dlen
            if period < 0.0:
                soon = soon or d < -dlen
            if soon:
                continue
        out[m] = i
        m += 1
    return out[:m]


@nb.njit(cache=True)
def leaving_rows(group, exit_id, cx, cy, lc_lane, lane_width, total_lanes, n_lanes, has_ramp, diverge_iv, period,
                 exit_lookahead, per_lane):
    """Members that leave their formation for their exit
    (``FormationManager.update``), rows ascending: a member with an exit
    whose diverge start is nearer than its exit lookahead, or, with a ramp
    lane, one on or changing into the ramp lane."""
    n = cx.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if exit_id[i] < 0 or group[i] < 0:
            continue
        ln = lane_of1(cy[i], lane_width, total_lanes)
        leave = _exit_ahead1(exit_id[i], cx[i], diverge_iv, period) < _exit_lookahead1(ln, n_lanes, exit_lookahead,
                                                                                        per_lane)
        if has_ramp and (ln == n_lanes or lc_lane[i] == n_lanes):
            leave = True
        if leave:
            out[m] = i
            m += 1
    return out[:m]


@nb.njit(cache=True)
def plan_inputs_rows(rows, group, tgt_behind, anchors, cx, speed, accel, v_form, a_lo, a_hi, period):
    """The join plans' inputs of members ``rows``
    (:meth:`icv_envs.sim.formations.FormationManager._plan`): the offset
    from the slot ``wrap(cx - (anchors[group] - tgt_behind))`` (``period <
    0``: a straight road), the speed relative to the formation's ``v_form``
    and the acceleration clipped to ``[a_lo, a_hi]`` (finite state), the
    array code's operations element by element. Returns ``(d0, v0, a0)``."""
    m = rows.shape[0]
    d0 = np.empty(m)
    v0 = np.empty(m)
    a0 = np.empty(m)
    for q in range(m):
        r = rows[q]
        d0[q] = _wrap1(cx[r] - (anchors[group[r]] - tgt_behind[r]), period)
        v0[q] = speed[r] - v_form
        a0[q] = clip1(accel[r], a_lo, a_hi)
    return d0, v0, a0
