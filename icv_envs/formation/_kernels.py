"""Compiled inner loop of the formation algorithms (numba, ``@njit(cache=True)``).

:func:`quintic_feasible` is the feasibility test of
:func:`icv_envs.formation.control.join_duration`'s duration search: for each
candidate duration it evaluates the quintic join profile on the same sample
points, with the same IEEE-754 operations in the same order, as the numpy
expression it replaces (``_quintic``), and stops at the first sample that
breaks a limit instead of materialising every sample of every candidate.
The result is a boolean per candidate; the comparisons carry a 1e-9
tolerance, so the answer cannot depend on the last bit of a power (numpy may
take ``pow`` from a SIMD library where numba calls libm's).
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["quintic_feasible"]


@nb.njit(cache=True)
def quintic_feasible(T, d0, v0, a0, hi_a, lo_a, v_hi, v_lo, jerk, max_duration, tau):
    """``ok[i]``: the quintic from ``(d0, v0, a0)[i]`` to rest at ``T[i]``
    keeps, on the samples ``tau * T[i]``, its acceleration within
    ``[lo_a, hi_a]``, its jerk within ``+-jerk`` and its speed within
    ``[v_lo, v_hi]`` (each with 1e-9 slack), or ``T[i] >= max_duration``."""
    m = T.shape[0]
    out = np.empty(m, dtype=np.bool_)
    for i in range(m):
        Ti = T[i]
        if Ti >= max_duration:
            out[i] = True
            continue
        d = d0[i]
        v = v0[i]
        a = a0[i]
        c3 = -(20.0 * d + 12.0 * v * Ti + 3.0 * a * Ti ** 2) / (2.0 * Ti ** 3.0)
        c4 = (30.0 * d + 16.0 * v * Ti + 3.0 * a * Ti ** 2) / (2.0 * Ti ** 4.0)
        c5 = -(12.0 * d + 6.0 * v * Ti + a * Ti ** 2) / (2.0 * Ti ** 5.0)
        a_hi = hi_a[i] + 1e-9
        a_lo = lo_a[i] - 1e-9
        s_hi = v_hi[i] + 1e-9
        s_lo = v_lo[i] - 1e-9
        j_hi = jerk + 1e-9
        ok = True
        for k in range(tau.shape[0]):
            t = min(max(tau[k] * Ti, 0.0), Ti)
            t2 = t ** 2
            t3 = t ** 3.0
            vk = v + a * t + 3.0 * c3 * t2 + 4.0 * c4 * t3 + 5.0 * c5 * t ** 4.0
            ak = a + 6.0 * c3 * t + 12.0 * c4 * t2 + 20.0 * c5 * t3
            jk = 6.0 * c3 + 24.0 * c4 * t + 60.0 * c5 * t2
            if not (ak <= a_hi and ak >= a_lo and abs(jk) <= j_hi and vk <= s_hi and vk >= s_lo):
                ok = False
                break
        out[i] = ok
    return out
