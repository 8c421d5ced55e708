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
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["join_search"]


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
