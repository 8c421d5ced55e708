"""The highway formation expert's compiled loops
(:class:`icv_envs.policies.formation_expert.FormationExpert`, paper Sec. 2.2
and 3.4):
:func:`safety_cap` is its safety envelope (about thirty numpy calls
before), :func:`exit_lanes` and :func:`lane_end_escape` the lanes it
heads for (about thirty); then the arithmetic of ``compute``'s preview
points and longitudinal law around the numpy calls that stay
(:func:`preview_points`, :func:`lane_speed_rows`, :func:`expert_lane_speeds`,
:func:`free_speed_ratio`, :func:`free_speed_pow`, :func:`expert_accelerations`), and the runs of
these kernels ``compute`` makes in one call (:func:`desired_lane_rows`,
:func:`free_speed_pow_rows`, :func:`expert_control_rows`). Its
lane-change decisions are :mod:`.lane_changes`. Rules:
:mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.policies._kernels.laws import _feedback1, _idm_free1, normalised_actions
from icv_envs.sim._kernels.formation import _exit_ahead1, _exit_lookahead1, _wrap1
from icv_envs.sim._kernels.neighbours import leader_rows
from icv_envs.sim._kernels.physics import interval_ends_at

__all__ = ["desired_lane_rows", "exit_lanes", "expert_accelerations", "expert_control_rows", "expert_lane_speeds",
           "free_speed_pow", "free_speed_pow_rows", "free_speed_ratio", "lane_end_escape", "lane_speed_rows", "preview_points",
           "safety_cap"]


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


@nb.njit(cache=True, error_model="numpy")  # (free_speed_ratio's division, as there)
def free_speed_pow(rows, v, v0):
    """:func:`free_speed_ratio` to the fourth power, the IDM's free-road
    term ``(v / v0)^4``, the power libm's ``pow`` (from stop 50; NumPy's
    ``** 4.0`` between the kernels before, the same numbers at ``X86_V3``:
    the rule of :mod:`icv_envs.sim._kernels`)."""
    r = free_speed_ratio(rows, v, v0)
    for k in range(r.shape[0]):
        r[k] = r[k] ** 4.0
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


@nb.njit(cache=True)
def lane_speed_rows(use_table, table, lane, n_lanes, has_ramp, ramp_speed, desired_speed):
    """``FormationExpert._lane_speeds``: the desired speed of a free vehicle
    in each ``lane``, ``table`` at the lane clipped to the table's range
    with ``use_table``, else ``ramp_speed`` in the ramp lane (``n_lanes``)
    of a road that has one and ``desired_speed`` elsewhere (values copied,
    never computed)."""
    n = lane.shape[0]
    out = np.empty(n)
    top = table.shape[0] - 1
    for i in range(n):
        if use_table:
            j = lane[i]
            if j < 0:
                j = 0
            elif j > top:
                j = top
            out[i] = table[j]
        else:
            out[i] = ramp_speed if (lane[i] == n_lanes and has_ramp) else desired_speed
    return out


# ---------------------------------------------------------------------------
# ``FormationExpert.compute``'s runs of kernels with no numpy call between
# them, each run in one call, the arguments of each kernel's separate call
# in its order (FormationExpert builds them with the same methods for both
# paths; used while the expert's hooks are its own: icv_envs._hooks.own_hooks)


@nb.njit(cache=True)
def desired_lane_rows(member, lane_ref, lane, exit_id, cx, has_ramp, n_exits, n_lanes, diverge_iv, exit_x, period,
                      exit_lookahead, per_lane, e_cx, e_period, e_n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv,
                      lc_max_length):
    """:func:`exit_lanes` (``member`` .. ``per_lane``) then
    :func:`lane_end_escape` on its answer (``e_cx`` .. ``lc_max_length``;
    the expert's ``_desired_lanes`` hook between them being the identity).
    Returns ``(desired, exiting)``."""
    desired, exiting = exit_lanes(member, lane_ref, lane, exit_id, cx, has_ramp, n_exits, n_lanes, diverge_iv, exit_x,
                                  period, exit_lookahead, per_lane)
    desired = lane_end_escape(desired, lane, member, exiting, e_cx, e_period, e_n_lanes, lane_ends, ob_lane, ob_lo,
                              ob_hi, ramp_iv, lc_max_length)
    return desired, exiting


@nb.njit(cache=True, error_model="numpy")  # (free_speed_ratio's division, as there)
def free_speed_pow_rows(use_table, table, lane, n_lanes, has_ramp, ramp_speed, desired_speed, exiting, blocked, member,
                        t_n_lanes, exit_speed, slowdown, v_min, free_rows, v):
    """:func:`lane_speed_rows` (``use_table`` .. ``desired_speed``), then
    :func:`expert_lane_speeds` (``exiting`` .. ``v_min``) and
    :func:`free_speed_pow` of ``free_rows`` (the IDM's free term; until
    stop 50 ``free_speed_ratio_rows``, the base, whose power the caller
    took with NumPy)."""
    ls = lane_speed_rows(use_table, table, lane, n_lanes, has_ramp, ramp_speed, desired_speed)
    lane_speed = expert_lane_speeds(ls, lane, exiting, blocked, member, t_n_lanes, exit_speed, slowdown, v_min)
    return free_speed_pow(free_rows, v, lane_speed)


@nb.njit(cache=True)
def expert_control_rows(n, free_rows, free_pow, v, a_max, b, T, s0, m_rows, cx, x_ref, v_ref, a_ref, period, kp, kv,
                        lo, hi, v_min, keys, i_rows, i_lanes, i_x, offset, s_cx, s_v, length, lc_lane, lane, desired,
                        member, exiting, s_period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, lc_min_length,
                        member_time_gap, idm_T, s_a_max, idm_s0, idm_denom, clip_lo, clip_hi, phi, n_a_max, n_a_min,
                        steer_max):
    """:func:`expert_accelerations` (``n`` .. ``v_min``), the safety
    envelope on them (:func:`safety_cap`: ``keys`` .. ``exiting``, the
    accelerations, ``s_period`` .. ``clip_hi``), and the normalised actions
    (:func:`~icv_envs.policies._kernels.laws.normalised_actions` of
    ``phi`` with ``n_a_max``, ``n_a_min``, ``steer_max``). Returns
    ``(n, 2)`` float64."""
    acc = expert_accelerations(n, free_rows, free_pow, v, a_max, b, T, s0, m_rows, cx, x_ref, v_ref, a_ref, period,
                               kp, kv, lo, hi, v_min)
    acc = safety_cap(keys, i_rows, i_lanes, i_x, offset, s_cx, s_v, length, lc_lane, lane, desired, member, exiting,
                     acc, s_period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, lc_min_length, member_time_gap,
                     idm_T, s_a_max, idm_s0, idm_denom, clip_lo, clip_hi)
    return normalised_actions(acc, phi, n_a_max, n_a_min, steer_max)
