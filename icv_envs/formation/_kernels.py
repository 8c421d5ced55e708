"""Compiled inner loops of the formation algorithms (numba, ``@njit(cache=True)``).

:func:`join_search` is the duration search of
:func:`icv_envs.formation.control.join_duration`, per member: test the
starting duration, double it until the profile is feasible, then bisect (in
log T) to a ratio ``grow``. Its feasibility test evaluates the quintic join
profile (``control._quintic``) on the same sample points with the same
IEEE-754 operations as the numpy expression it replaced, and stops at the
first sample that breaks a limit instead of materialising every sample of
every candidate. The comparisons carry a 1e-9 tolerance, so the answer
cannot depend on the last bit of a power (numpy may take ``pow`` from a SIMD
library where numba calls libm's; the sample powers ``t^3``, ``t^4`` are
products, a few times faster than ``pow`` and within 2 ulp of it, far inside
the slack); the search's own arithmetic (doubling,
``sqrt(lo * hi)``) is exactly rounded everywhere, so the durations are the
numpy code's, bit for bit (``tests/test_trajectory_hash.py``).

:func:`join_search_banded` is the formation layer's plan search in one call
(its start, the search within the speed band, the fallback without it);
:func:`profile_eval` evaluates join profiles from the coefficients stored
with the plan, and :func:`plan_rows` stores new plans (coefficients and end
values; until stop 49 also stamps) in one pass. The search's start
(``cbrt``) is libm's inside :func:`plan_search_store`, which every plan
goes through from stop 50 (numpy's before; the same numbers at ``X86_V3``,
as the powers below).
The quintic's powers ``t^3``, ``t^4``, ``t^5`` are libm's ``pow``, taken
inside the kernels (from stop 49; numpy's ``power`` between two kernels
before): at ``X86_V3``, the level the reference fingerprints are pinned at,
numpy's float64 ``power`` is libm's, bit for bit (0 of 1,200,000 probes
differ, ``results/bench/stop49/libm_vs_numpy.py``), so the values are the
same there; NumPy's AVX-512 ``power`` rounds 5% of them differently in the
last bit, where the kernels now give the pinned level's numbers instead of
that machine's NumPy's (the rule of :mod:`icv_envs.sim._kernels`). The
rest is exactly rounded arithmetic in the numpy code's order
(``tests/test_kernels.py``).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["clip1", "join_search", "join_search_banded", "lateral_rows", "min_cost_assignment", "plan_rows",
           "plan_search_store", "profile_eval", "pursuit_rows"]


@nb.njit(cache=True)
def _feasible1(Ti, d, v, a, hi_a, lo_a, v_hi, v_lo, jerk, max_duration, tau):
    """The quintic from ``(d, v, a)`` to rest at ``Ti`` keeps, on the samples
    ``tau * Ti``, its acceleration within ``[lo_a, hi_a]``, its jerk within
    ``+-jerk`` and its speed within ``[v_lo, v_hi]`` (1e-9 slack each), or
    ``Ti >= max_duration``."""
    if Ti >= max_duration:
        return True
    c3 = -(20.0 * d + 12.0 * v * Ti + 3.0 * a * Ti ** 2) / (2.0 * Ti ** 3.0)
    c4 = (30.0 * d + 16.0 * v * Ti + 3.0 * a * Ti ** 2) / (2.0 * Ti ** 4.0)
    c5 = -(12.0 * d + 6.0 * v * Ti + a * Ti ** 2) / (2.0 * Ti ** 5.0)
    a_hi = hi_a + 1e-9
    a_lo = lo_a - 1e-9
    s_hi = v_hi + 1e-9
    s_lo = v_lo - 1e-9
    j_hi = jerk + 1e-9
    for k in range(tau.shape[0]):
        t = min(max(tau[k] * Ti, 0.0), Ti)
        t2 = t * t
        t3 = t2 * t
        vk = v + a * t + 3.0 * c3 * t2 + 4.0 * c4 * t3 + 5.0 * c5 * (t2 * t2)
        ak = a + 6.0 * c3 * t + 12.0 * c4 * t2 + 20.0 * c5 * t3
        jk = 6.0 * c3 + 24.0 * c4 * t + 60.0 * c5 * t2
        if not (ak <= a_hi and ak >= a_lo and abs(jk) <= j_hi and vk <= s_hi and vk >= s_lo):
            return False
    return True


@nb.njit(cache=True)
def join_search(lo, d0, v0, a0, hi_a, lo_a, v_hi, v_lo, jerk, max_duration, grow, tau):
    """Per member ``i``: ``lo[i]`` if feasible; else double from it until
    feasible (capped at ``max_duration``, which counts as feasible) and
    bisect in log T between the last infeasible and the first feasible
    duration until they are within a factor ``grow``; the feasible end."""
    m = lo.shape[0]
    T = np.empty(m, dtype=np.float64)
    for i in range(m):
        lo_i = lo[i]
        args = (d0[i], v0[i], a0[i], hi_a[i], lo_a[i], v_hi[i], v_lo[i], jerk, max_duration, tau)
        if _feasible1(lo_i, *args):
            T[i] = lo_i
            continue
        hi_i = min(2.0 * lo_i, max_duration)
        while not _feasible1(hi_i, *args):
            lo_i = hi_i
            hi_i = min(2.0 * hi_i, max_duration)
        while hi_i > lo_i * grow:
            mid = np.sqrt(lo_i * hi_i)
            if _feasible1(mid, *args):
                hi_i = mid
            else:
                lo_i = mid
        T[i] = hi_i
    return T


@nb.njit(cache=True)
def join_search_banded(cb, d0, v0, a0, accel, decel, jerk, t_min, grow, cap, v_lo, v_hi, fallback, cap_free, tau):
    """``control._join_duration_banded`` after its cube roots (``cb =
    cbrt(60 |d0| / jerk)``, libm's from :func:`plan_search_store`; numpy's,
    whose SIMD ``cbrt`` may round differently, until stop 50): the start of
    the search (the rest-to-rest
    estimate of the minimum-jerk move, the limits widened to the member's
    own state: element-wise max/min, ``sqrt`` and the divisions, exactly
    rounded everywhere), :func:`join_search` within the per-member speed
    band ``[v_lo, v_hi]`` capped at ``cap``, and with ``fallback``, for
    members that reach the cap, the search again without the band, capped
    at ``cap_free``. The durations of the numpy search start this replaced
    (``tests/test_kernels.py``), bit for bit."""
    m = d0.shape[0]
    amax = max(accel, decel)
    lo = np.empty(m)
    hi_a = np.empty(m)
    lo_a = np.empty(m)
    vhi = np.empty(m)
    vlo = np.empty(m)
    for i in range(m):
        # np.maximum(a, b) is ``a if a >= b else b`` (np.minimum: ``<=``)
        e1 = math.sqrt(5.7735 * abs(d0[i]) / amax)
        e2 = cb[i]
        e3 = abs(v0[i]) / amax
        est = e1 if e1 >= e2 else e2
        est = est if est >= e3 else e3
        x = 0.7 * est
        lo[i] = t_min if t_min >= x else x
        hi_a[i] = accel if accel >= a0[i] else a0[i]
        lo_a[i] = -decel if -decel <= a0[i] else a0[i]
        vhi[i] = v_hi[i] if v_hi[i] >= v0[i] else v0[i]
        vlo[i] = v_lo[i] if v_lo[i] <= v0[i] else v0[i]
    T = join_search(lo, d0, v0, a0, hi_a, lo_a, vhi, vlo, jerk, cap, grow, tau)
    if not fallback:
        return T
    stuck = np.flatnonzero(T >= cap)
    if stuck.shape[0]:
        free_hi = np.full(stuck.shape[0], np.inf)
        T[stuck] = join_search(lo[stuck], d0[stuck], v0[stuck], a0[stuck], hi_a[stuck], lo_a[stuck], free_hi,
                               -free_hi, jerk, cap_free, grow, tau)
    return T


@nb.njit(cache=True, inline="always")
def _quintic_at(ti, t3, t4, t5, d, v, a, p3, p4, p5):
    """The quintic's ``(d, d', d'')`` (``control._quintic`` with ``jerk``
    off) at time ``ti`` with its powers ``t3 = ti**3``, ``t4``, ``t5``, from
    the plan's start ``(d, v, a)`` and coefficients ``p3, p4, p5``: term by
    term the products and sums of ``_quintic`` in its order (``t**2`` is
    numpy's exact square ``t * t``)."""
    t2 = ti * ti
    return (d + v * ti + 0.5 * a * t2 + p3 * t3 + p4 * t4 + p5 * t5,
            v + a * ti + 3.0 * p3 * t2 + 4.0 * p4 * t3 + 5.0 * p5 * t4,
            a + 6.0 * p3 * ti + 12.0 * p4 * t2 + 20.0 * p5 * t3)


@nb.njit(cache=True)
def plan_rows(vid, time, T, d0, v0, a0, t0_tab, T_tab, d0_tab, v0_tab, a0_tab, c3_tab, c4_tab, c5_tab, fd_tab,
              fv_tab, fa_tab):
    """Store new join plans (:meth:`icv_envs.sim.join_plans.JoinPlans.plan`
    after its duration search) in the tables indexed by vehicle id: start
    ``time``, duration ``T``, initial state ``(d0, v0, a0)``, the quintic's
    coefficients (``control._quintic_coeffs``: its products, sums and
    divisions in its order, from the powers ``T**3``, ``T**4``, ``T**5``,
    libm's ``pow`` (from stop 49; numpy's before: the module docstring);
    ``T**2`` is numpy's exact square ``T * T``), the profile's values at
    ``T`` (:func:`_quintic_at`; until stop 49 also a stamp, the count of
    plans once these were made, read by the patched re-evaluation that
    stop 49 dropped). With a repeated id the last plan wins, as with
    numpy's fancy assignment. Bit for bit the numpy code's
    values where numpy's ``power`` is libm's (``tests/test_kernels.py``,
    pinned at ``X86_V3``)."""
    for i in range(vid.shape[0]):
        k = vid[i]
        Ti, d, v, a = T[i], d0[i], v0[i], a0[i]
        t2, t3, t4, t5 = Ti * Ti, Ti ** 3.0, Ti ** 4.0, Ti ** 5.0
        p3 = -(20.0 * d + 12.0 * v * Ti + 3.0 * a * t2) / (2.0 * t3)
        p4 = (30.0 * d + 16.0 * v * Ti + 3.0 * a * t2) / (2.0 * t4)
        p5 = -(12.0 * d + 6.0 * v * Ti + a * t2) / (2.0 * t5)
        t0_tab[k], T_tab[k] = time, Ti
        d0_tab[k], v0_tab[k], a0_tab[k] = d, v, a
        c3_tab[k], c4_tab[k], c5_tab[k] = p3, p4, p5
        fd_tab[k], fv_tab[k], fa_tab[k] = _quintic_at(Ti, t3, t4, t5, d, v, a, p3, p4, p5)


@nb.njit(cache=True)
def plan_search_store(ids, time, d0, v0, a0, accel, decel, jerk, t_min, grow, cap, band_lo, band_hi, cap_free, tau,
                      t0_tab, T_tab, d0_tab, v0_tab, a0_tab, c3_tab, c4_tab, c5_tab, fd_tab, fv_tab, fa_tab):
    """New join plans for vehicles ``ids`` at ``time`` from their offsets
    ``d0``, relative speeds ``v0`` and accelerations ``a0`` (finite), in one
    pass (from stop 50; ``JoinPlans.plan`` and the formation layer's
    re-plans share it): the search's start ``cbrt(60 |d0| / jerk)`` (libm's
    ``cbrt``, NumPy's at ``X86_V3``; NumPy's before, between the kernels),
    :func:`join_search_banded` within the speed band ``[band_lo, band_hi]``
    with its fallback, and :func:`plan_rows` into the tables (which must
    hold every id). Returns the durations."""
    m = d0.shape[0]
    cb = np.empty(m)
    for i in range(m):
        cb[i] = np.cbrt(60.0 * abs(d0[i]) / jerk)
    T = join_search_banded(cb, d0, v0, a0, accel, decel, jerk, t_min, grow, cap, np.full(m, band_lo),
                           np.full(m, band_hi), True, cap_free, tau)
    plan_rows(ids, time, T, d0, v0, a0, t0_tab, T_tab, d0_tab, v0_tab, a0_tab, c3_tab, c4_tab, c5_tab, fd_tab,
              fv_tab, fa_tab)
    return T


@nb.njit(cache=True)
def profile_eval(vid, time, t0_tab, T_tab, fd_tab, fv_tab, fa_tab, d0_tab, v0_tab, a0_tab, c3_tab, c4_tab, c5_tab):
    """``JoinPlans._eval`` in one pass (from stop 49; before, a gather, numpy's
    powers and a second kernel): per vehicle ``vid[i]`` the join profile
    ``(d, v, a)`` at ``time``, as the rows of one ``(3, n)`` array (numba
    boxes each returned array for about 0.35 us, a view of a row costs
    0.1): the end values stored with the plan where it has ended (``time -
    t0 >= T``), else the quintic (:func:`_quintic_at`) at ``time - t0``
    clamped to ``[0, T]`` (numpy's ``minimum(maximum(t, 0), T)``; the times
    are finite) with its powers from libm's ``pow`` (the module docstring)."""
    n = vid.shape[0]
    P = np.empty((3, n))
    for i in range(n):
        k = vid[i]
        t = time - t0_tab[k]
        T = T_tab[k]
        if t < T:
            x = t if t > 0.0 else 0.0
            ti = x if x < T else T
            P[0, i], P[1, i], P[2, i] = _quintic_at(ti, ti ** 3.0, ti ** 4.0, ti ** 5.0, d0_tab[k], v0_tab[k],
                                                    a0_tab[k], c3_tab[k], c4_tab[k], c5_tab[k])
        else:
            P[0, i] = fd_tab[k]
            P[1, i] = fv_tab[k]
            P[2, i] = fa_tab[k]
    return P


# ------------------------------------------------- lane change and steering
# bezier._lane_change_lateral and _pure_pursuit_steering on vehicle rows,
# each in one pass: the experts evaluate them on a few to a few hundred rows
# per step, where the two dozen numpy calls of the array code cost more than
# the arithmetic. Until stop 49 the transcendental steps (arcsinh, sinh,
# hypot, arctan) stayed numpy's, between two kernels each; they are libm's
# now, which numpy's are at X86_V3, the reference fingerprints' level (the
# module docstring); the rest is exactly rounded, in the array code's order
# (tests/test_expert_kernels.py). numpy's clip: :func:`clip1`.


@nb.njit(cache=True)
def clip1(v, lo, hi):
    """``numpy.clip(v, lo, hi)`` of one finite float: ``lo`` below it,
    ``hi`` above, ``v`` itself on a tie (a -0.0 above a 0.0 bound stays
    -0.0), as numpy's clip loop compares."""
    if v < lo:
        v = lo
    if v > hi:
        v = hi
    return v


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def lateral_rows(rows, x, x0, y0, y1, d):
    """``_lane_change_lateral`` of entries ``rows`` in one pass (from stop 49;
    before, a kernel, NumPy's ``arcsinh`` and ``sinh``, a second kernel):
    the parameter ``s = clip((x - x0) / d, 0, 1)``, ``t = 0.5 + sinh(asinh(4
    s - 2) / 3)``, one Newton step on ``t`` and its clip to ``[0, 1]``, the
    lateral position and slope, and the straight lanes before and after the
    curve; ``asinh`` and ``sinh`` libm's (the module docstring). Returns
    ``(y, slope)`` aligned with ``rows``."""
    n = rows.shape[0]
    y = np.empty(n)
    slope = np.empty(n)
    for k in range(n):
        i = rows[k]
        sv = clip1((x[i] - x0[i]) / d[i], 0.0, 1.0)
        t = 0.5 + math.sinh(math.asinh(4.0 * sv - 2.0) / 3.0)
        t = clip1(t - (((t - 1.5) * t + 1.5) * t - sv) / ((3.0 * t - 3.0) * t + 1.5), 0.0, 1.0)
        dy = y1[i] - y0[i]
        if x[i] <= x0[i]:
            y[k] = y0[i]
            slope[k] = 0.0
        elif x[i] >= x0[i] + d[i]:
            y[k] = y1[i]
            slope[k] = 0.0
        else:
            y[k] = y0[i] + dy * (t * t * (3.0 - 2.0 * t))
            slope[k] = dy * (6.0 * t * (1.0 - t)) / (d[i] * ((3.0 * t - 3.0) * t + 1.5))
    return y, slope


@nb.njit(cache=True, error_model="numpy")  # IEEE division (inf, nan) as numpy's, no ZeroDivisionError
def pursuit_rows(rx, ry, c, sn, tx, ty, wb, ms):
    """``_pure_pursuit_steering`` in one pass (from stop 49; before, a
    kernel, NumPy's ``hypot``, a second kernel, NumPy's ``arctan`` and
    ``clip``): the preview point relative to the rear axle,
    its distance ``ld`` (``hypot``), ``wb`` times the pursuit circle's
    curvature ``2 (c dy - sn dx) / ld^2`` (0 where ``ld == 0``), its
    ``arctan`` clipped to ``[-ms, ms]`` as numpy's clip; ``c, sn`` the
    cosine and sine of the heading; ``hypot`` and ``atan`` libm's (the
    module docstring)."""
    n = rx.shape[0]
    phi = np.empty(n)
    for i in range(n):
        dx = tx[i] - rx[i]
        dy = ty[i] - ry[i]
        ld = math.hypot(dx, dy)
        lateral = c[i] * dy - sn[i] * dx
        if ld > 0.0:
            q = wb * (2.0 * lateral / (ld * ld))
        else:
            q = wb * 0.0
        phi[i] = clip1(math.atan(q), -ms, ms)
    return phi


@nb.njit(cache=True)
def min_cost_assignment(cost):
    """Minimum-total-cost assignment of a square cost matrix (paper Sec.
    3.3, eq. (lp); the Hungarian step of the formation layer's re-forming),
    compiled so that the re-forming runs in one call (from stop 56;
    :func:`icv_envs.formation.assignment._solve`, SciPy's
    ``linear_sum_assignment``, before).

    The shortest augmenting path algorithm of D. F. Crouse, "On
    implementing 2D rectangular assignment algorithms", IEEE Trans.
    Aerospace and Electronic Systems 52(4), 2016, pp. 1685-1686 (the
    algorithm SciPy implements), with SciPy's choices wherever the
    pseudocode leaves one open, so that the answer is SciPy's (1.17),
    ties included: the costs as given (SciPy 1.17 does not shift them by
    their minimum); the columns scanned from the last to the first, a
    column taken out of the scan by moving the scan's last one into its
    place; among columns of equal
    reduced cost the first found, unless a later one is unassigned (it
    ends the path). Returns ``out`` with ``out[i]`` the column of row
    ``i`` (``tests/test_kernels.py`` compares it with SciPy's on random,
    integer-valued and constant matrices), or all -1 for a matrix SciPy
    refuses (a NaN or -inf entry, or no assignment of finite cost)."""
    n = cost.shape[0]
    out = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return out
    for i in range(n):
        for j in range(n):
            if np.isnan(cost[i, j]) or cost[i, j] == -np.inf:
                return out
    u = np.zeros(n)
    v = np.zeros(n)
    dist = np.empty(n)
    pred = np.full(n, -1, dtype=np.int64)
    row_of = np.full(n, -1, dtype=np.int64)
    in_rows = np.zeros(n, dtype=np.bool_)
    in_cols = np.zeros(n, dtype=np.bool_)
    todo = np.empty(n, dtype=np.int64)
    for start in range(n):
        # the shortest augmenting path from row ``start``
        for k in range(n):
            todo[k] = n - 1 - k
            in_rows[k] = False
            in_cols[k] = False
            dist[k] = np.inf
        left = n
        i = start
        reached = 0.0
        sink = -1
        while sink < 0:
            in_rows[i] = True
            best = -1
            best_d = np.inf
            for k in range(left):
                j = todo[k]
                r = reached + cost[i, j] - u[i] - v[j]
                if r < dist[j]:
                    pred[j] = i
                    dist[j] = r
                if dist[j] < best_d or (dist[j] == best_d and row_of[j] < 0):
                    best_d = dist[j]
                    best = k
            reached = best_d
            j = todo[best]
            if reached == np.inf:  # (finite costs never get here)
                return np.full(n, -1, dtype=np.int64)
            if row_of[j] < 0:
                sink = j
            else:
                i = row_of[j]
            in_cols[j] = True
            left -= 1
            todo[best] = todo[left]
        # the dual variables
        u[start] += reached
        for k in range(n):
            if in_rows[k] and k != start:
                u[k] += reached - dist[out[k]]
        for k in range(n):
            if in_cols[k]:
                v[k] -= reached - dist[k]
        # the path's columns passed one row back
        j = sink
        while True:
            i = pred[j]
            row_of[j] = i
            prev = out[i]
            out[i] = j
            j = prev
            if i == start:
                break
    return out
