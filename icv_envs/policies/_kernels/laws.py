"""The control laws both experts share, one vehicle at a time (numba,
``@njit(cache=True)``): :func:`normalised_actions` turns controls into
normalised actions in one pass (five numpy calls and their temporaries
before; the highway expert and the intersection experts), :func:`idm_free_pow`
the IDM's free-road term of every vehicle for one desired speed (from stop
50, its power libm's; the intersection experts), :func:`_idm_free1` the IDM without a leader and
:func:`_feedback1` the clipped longitudinal feedback law
(``formation.control._longitudinal_feedback``, paper Sec. 2.2, eq. (law)), called by the
highway and the intersection kernels. Rules: :mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.formation._kernels import clip1

__all__ = ["idm_free_pow", "normalised_actions"]


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


@nb.njit(cache=True, error_model="numpy")
def _idm_free1(v, free_pow, a_max, T, s0, root):
    """``traffic.idm_acceleration`` of one vehicle without a leader (gap
    ``inf``, ``dv = 0``): ``a_max (1 - free_pow - (s*/inf)^2)`` with ``s* =
    s0 + max(0, v T + v 0 / root)``, ``root = 2 sqrt(a_max b)`` and
    ``free_pow`` the free term's power (from stop 50 libm's ``pow``,
    :func:`idm_free_pow` and ``free_speed_pow``; NumPy's before)."""
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
def idm_free_pow(v, v0):
    """The IDM's free-road term ``(v / v0)^4`` of every vehicle for one
    desired speed ``v0`` (the caller's ``max(v0, 0.1)``): NumPy's ``(v /
    v0) ** 4.0``, the division exactly rounded, the power libm's ``pow``
    (from stop 50; NumPy's before, the same numbers at ``X86_V3``: the rule
    of :mod:`icv_envs.sim._kernels`)."""
    out = np.empty(v.shape[0])
    for i in range(v.shape[0]):
        out[i] = (v[i] / v0) ** 4.0
    return out
