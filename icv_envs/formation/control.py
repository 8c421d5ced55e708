"""Longitudinal feedback law for target following.

Paper Sec. 2.2, eq. (law) (Xu et al., IET ITS 2021)::

    a_i = k_p (X_i - X_ref,i) + k_v (v_i - v_ref,i)

``X`` points forward, so both gains must be negative (docs/formation.md#feedback-law).  The
paper gives no values; ours are :data:`DEFAULT_KP` and :data:`DEFAULT_KV`.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from icv_envs.formation._validate import finite

__all__ = ["DEFAULT_KP", "DEFAULT_KV", "DEFAULT_A_MIN", "DEFAULT_A_MAX", "longitudinal_feedback"]

#: Position gain k_p (1/s^2).  With e = X - X_ref and a reference moving at
#: constant speed, the closed loop is e'' = k_v e' + k_p e, i.e. the
#: characteristic polynomial s^2 - k_v s - k_p = s^2 + 1.1 s + 0.3 with real
#: poles -0.5 and -0.6 (time constants 2.0 s and 1.67 s): natural frequency
#: omega_n = sqrt(0.3) = 0.548 rad/s and damping ratio
#: zeta = 1.1 / (2 sqrt(0.3)) = 1.004, i.e. (just) over-damped, so a position
#: error closes without overshoot.
DEFAULT_KP: float = -0.3
#: Speed gain k_v (1/s); see :data:`DEFAULT_KP` for the closed-loop poles.
DEFAULT_KV: float = -1.1
#: Acceleration limits (m/s^2) from the paper's vehicle parameter table.
DEFAULT_A_MIN: float = -6.0
DEFAULT_A_MAX: float = 3.0


_finite = finite


def _scalar(name: str, value) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    f = float(value)
    if not math.isfinite(f):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    return f


def longitudinal_feedback(
    x,
    x_ref,
    v,
    v_ref,
    kp=DEFAULT_KP,
    kv=DEFAULT_KV,
    a_min: float = DEFAULT_A_MIN,
    a_max: float = DEFAULT_A_MAX,
) -> np.ndarray:
    """Acceleration command of the longitudinal feedback law.

    Paper Sec. 2.2, eq. (law)::

        a = clip(k_p (x - x_ref) + k_v (v - v_ref), a_min, a_max)

    A vehicle behind its reference (``x < x_ref``) accelerates; one faster than
    its reference (``v > v_ref``) brakes.  With the default gains
    (``k_p = -0.3``, ``k_v = -1.1``) the unsaturated error dynamics
    ``e'' + 1.1 e' + 0.3 e = 0`` have poles -0.5 and -0.6
    (``omega_n = 0.548 rad/s``, ``zeta = 1.004``, over-damped).  The limits
    default to the paper's ``a in [-6, 3] m/s^2``.

    Saturation caveat (measured with a point mass ``x'' = a``, dt = 0.04 s,
    zero initial speed error): the linear loop cannot overshoot, but the
    clipped one can when the error is large, because the saturated phase
    builds up a closing speed that the opposite limit cannot cancel in time.
    With the default gains and limits there is no overshoot for a vehicle up
    to about 100 m ahead of (or about 450 m behind) its reference; a vehicle
    150 m ahead overshoots by about 17 m.  Callers that need no overshoot for
    large errors can bound the position error they pass in, without changing
    the law near the reference::

        x_ref_eff = x + np.clip(x_ref - x, -E, E)    # E = 50 m works

    which caps the closing speed at ``-k_p E / k_v`` (about 13.6 m/s for
    ``E = 50 m``); ``tests/test_control.py`` checks both statements.

    Args:
        x, x_ref: positions and reference positions along the road (m).
        v, v_ref: speeds and reference speeds (m/s).
        kp, kv: gains, scalars or per-vehicle arrays; all must be finite and
            strictly negative.
        a_min, a_max: acceleration limits, ``a_min < 0 < a_max``.
        All array arguments broadcast (one entry per vehicle).

    Returns:
        float64 array of accelerations (m/s^2), the broadcast shape.

    Raises:
        ValueError: non-finite input, a gain >= 0, limits not satisfying
            ``a_min < 0 < a_max``, or non-broadcastable shapes.
    """
    kpa, kva = _finite("kp", kp), _finite("kv", kv)
    if np.any(kpa >= 0.0):
        raise ValueError(
            f"kp must be < 0 (X points forward, a positive gain is unstable), got {kp!r}"
        )
    if np.any(kva >= 0.0):
        raise ValueError(
            f"kv must be < 0 (X points forward, a positive gain is unstable), got {kv!r}"
        )
    lo, hi = _scalar("a_min", a_min), _scalar("a_max", a_max)
    if not lo < 0.0:
        raise ValueError(f"a_min must be < 0 (m/s^2), got {a_min!r}")
    if not hi > 0.0:
        raise ValueError(f"a_max must be > 0 (m/s^2), got {a_max!r}")
    xa, xr = _finite("x", x), _finite("x_ref", x_ref)
    va, vr = _finite("v", v), _finite("v_ref", v_ref)
    try:
        a = kpa * (xa - xr) + kva * (va - vr)
    except ValueError:
        shapes = ", ".join(
            f"{n}{np.shape(s)}" for n, s in
            (("x", xa), ("x_ref", xr), ("v", va), ("v_ref", vr), ("kp", kpa), ("kv", kva))
        )
        raise ValueError(f"arguments are not broadcastable to a common shape: {shapes}") from None
    return np.clip(a, lo, hi)
