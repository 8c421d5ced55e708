"""The intersection experts' control (paper Sec. 4.3 and Sec. 5's controller,
:class:`icv_envs.policies.platoon_control.PlatoonControl`):
:func:`box_steering` is the pure-pursuit steering through the box (about
forty numpy calls before; its ``sin``, ``cos``, ``arctan``, ``sinh``,
``arcsinh`` and ``hypot`` are libm's, as NumPy's float64 loops up to AVX2,
the level the reference fingerprints are pinned at, see
:mod:`icv_envs.sim._kernels`), :func:`envelope_pairs` the safety envelope
towards the leader in every corridor (and :func:`box_obstacle_rows` the
vehicles stopped across the paths), :func:`platoon_accelerations` the
longitudinal law. Rules: :mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.formation._kernels import clip1
from icv_envs.policies._kernels.corridors import corridor_add_signals
from icv_envs.policies._kernels.laws import _feedback1, _idm_free1, normalised_actions
from icv_envs.sim._kernels.physics import npy_maximum, npy_minimum

__all__ = ["box_obstacle_rows", "box_steering", "envelope_pairs", "platoon_accelerations", "stop_line_caps",
           "platoon_actions_rows"]


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
        g = gap if (gap > 0.1 or gap != gap) else 0.1  # numpy's maximum(gap, 0.1): NaN kept
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


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def stop_line_caps(stop, u, length, speed, stop_margin, a_max, sqrt_ab, T, s0, cap, cap_other, phase, acc_ref):
    """The end of :meth:`icv_envs.policies.platoon_control.PlatoonControl._envelope`:
    every vehicle with ``stop`` gets the IDM interaction cap towards its stop
    line (``idm_acceleration(v, ., gap, v, a_max, ., T, s0,
    free_term=False)`` at the bumper gap ``-u - length / 2 - stop_margin``,
    ``sqrt_ab = sqrt(a_max b)`` as numpy takes it), in place, the smaller of
    it and ``cap`` (numpy's ``minimum``: the cap on a tie); then the in-box
    vehicles whose cap binds (below ``acc_ref - 0.5``) are counted: those
    bound towards a leader of another group too (``cap_other``) and the
    others. Returns the two counts."""
    n = u.shape[0]
    for i in range(n):
        if not stop[i]:
            continue
        gap = -u[i] - 0.5 * length[i] - stop_margin
        v = speed[i]
        z = v * T + v * v / (2.0 * sqrt_ab)
        s_star = s0 + npy_maximum(0.0, z)
        q = s_star / npy_maximum(gap, 0.1)
        a = a_max * (1.0 - q * q)
        cap[i] = npy_minimum(cap[i], a)
    n_other = 0
    n_member = 0
    for i in range(n):
        if phase[i] == 1 and cap[i] < acc_ref[i] - 0.5:
            if cap_other[i] < acc_ref[i] - 0.5:
                n_other += 1
            else:
                n_member += 1
    return n_other, n_member


@nb.njit(cache=True)
def box_obstacle_rows(phase, s, L, speed, v_stopped):
    """The candidate obstacles of
    :meth:`icv_envs.policies.platoon_control.PlatoonControl._path_obstacles`
    (from stop 42; the array expression it replaced is frozen in
    ``tests/test_box_steering.py``): vehicles slower than ``v_stopped`` in
    the box (``phase`` 1) or within 10 m past its exit (``phase`` 2, ``s -
    L < 10``), in row order."""
    n = phase.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if (phase[i] == 1 or (phase[i] == 2 and s[i] - L[i] < 10.0)) and speed[i] < v_stopped:
            out[m] = i
            m += 1
    return out[:m]


@nb.njit(cache=True, error_model="numpy")  # (its kernels' own error models: IEEE division as numpy's)
def platoon_actions_rows(x, y, heading, speed, klane, mv, pid, phase, s, u, lc_lane, lc_u0, lc_lat0, lc_lat1, lc_len,
                         leg, L, P0, D0, P1, D1, arc, TH0, SGN, R, C, box_half, out, app_dir, app_right, lane_width,
                         preview_min, preview_time, wheelbase, steer_max,
                         acc_given, l_v, free_pow, a_free, l_b, l_T, l_s0, mode, mode_follow, mode_tree, l_u, X, xref,
                         vref, tight, vcap, clip_err, kp, kv, comfort_lo, comfort_hi, a_min, a_max,
                         b_rows, b_corr, b_coord, b_keys, signal_lane, big,
                         e_length, e_speed, grp, co, e_phase, member_T, e_T, member_s0, e_s0, e_a_max, e_b, sqrt_ab2,
                         gipps_b, gipps_tau, gipps_bt2, in_box,
                         route_L, v_stopped,
                         stop, s_u, s_length, s_speed, stop_margin, s_a_max, sqrt_ab, s_T, s_s0):
    """:meth:`icv_envs.policies.platoon_control.PlatoonControl.compute` in
    one call (from stop 47), each kernel with the arguments of its separate
    call, in their order: :func:`box_steering` (``x`` .. ``steer_max``);
    :func:`platoon_accelerations` (``l_v`` .. ``a_max``), unless
    ``acc_given`` holds one acceleration per vehicle (an expert whose
    longitudinal law is its own, FCFS's);
    :func:`~icv_envs.policies._kernels.corridors.corridor_add_signals` of
    the index without signals (``b_rows`` .. ``b_keys``, with ``phase``,
    ``leg``, ``s``, ``signal_lane``, ``big``); :func:`envelope_pairs`
    (``e_length`` .. ``in_box``) on the caps ``inf``; then, when
    :func:`box_obstacle_rows` finds no vehicle stopped in or just past the
    box (``phase``, ``s``, ``route_L``, ``speed``, ``v_stopped``: nothing on
    anybody's path, most steps), :func:`stop_line_caps` (``stop`` ..
    ``s_s0``, then the caps, ``phase`` and the accelerations) and the
    actions ``normalised_actions(clip(minimum(acc, cap), a_min, a_max),
    phi, ...)`` with numpy's ``minimum`` and ``clip`` (NaN kept; ``b`` on a
    tie).

    Returns ``(done, actions, W, binding, passed, n_other, n_member)``:
    ``done`` False when there are stopped vehicles (the caller then adds
    their caps and ends the envelope as ``_envelope`` does, from ``W``'s
    rows ``phi, acc, cap, cap_other``; ``actions`` empty and ``n_other``,
    ``n_member`` 0); the counts are the statistics the separate calls
    return (``binding`` of :func:`platoon_accelerations`, 0 with
    ``acc_given``)."""
    n = x.shape[0]
    W = np.empty((4, n))
    W[0] = box_steering(x, y, heading, speed, klane, mv, pid, phase, s, u, lc_lane, lc_u0, lc_lat0, lc_lat1, lc_len,
                        leg, L, P0, D0, P1, D1, arc, TH0, SGN, R, C, box_half, out, app_dir, app_right, lane_width,
                        preview_min, preview_time, wheelbase, steer_max)
    binding = 0
    if acc_given.shape[0] == n:
        W[1] = acc_given
    else:
        acc, binding = platoon_accelerations(l_v, free_pow, a_free, l_b, l_T, l_s0, mode, mode_follow, mode_tree, l_u,
                                             X, xref, vref, tight, vcap, clip_err, kp, kv, comfort_lo, comfort_hi,
                                             a_min, a_max)
        W[1] = acc
    rows, corr, coord, keys, signal_only, lead = corridor_add_signals(b_rows, b_corr, b_coord, b_keys, phase, leg, s,
                                                                      signal_lane, big)
    cap = W[2]
    cap_other = W[3]
    cap[:] = np.inf
    cap_other[:] = np.inf
    passed = envelope_pairs(lead, coord, rows, signal_only, e_length, e_speed, grp, co, e_phase, member_T, e_T,
                            member_s0, e_s0, e_a_max, e_b, sqrt_ab2, gipps_b, gipps_tau, gipps_bt2, in_box, cap,
                            cap_other)
    if box_obstacle_rows(phase, s, route_L, speed, v_stopped).shape[0]:
        return False, np.empty((0, 2)), W, binding, passed, 0, 0
    acc = W[1]
    n_other, n_member = stop_line_caps(stop, s_u, s_length, s_speed, stop_margin, s_a_max, sqrt_ab, s_T, s_s0, cap,
                                       cap_other, phase, acc)
    a = np.empty(n)
    for i in range(n):
        a[i] = npy_minimum(npy_maximum(npy_minimum(acc[i], cap[i]), a_min), a_max)
    return True, normalised_actions(a, W[0], a_max, a_min, steer_max), W, binding, passed, n_other, n_member
