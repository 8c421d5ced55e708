"""Longitudinal feedback law for target following.

Paper Sec. 2.2, eq. (law) (Xu et al., IET ITS 2021)::

    a_i = k_p (X_i - X_ref,i) + k_v (v_i - v_ref,i)

``X`` points forward, so both gains must be negative.  The paper gives no
values; ours (:data:`DEFAULT_KP`, :data:`DEFAULT_KV`) follow from a stated
design rule, below.  The law tracks a reference that moves smoothly from
where a vehicle is to its formation slot (:func:`join_profile`,
:func:`join_duration`), so the feedback only ever sees small errors.

Design rule for the gains (error dynamics ``e'' = k_v e' + k_p e`` with
``e = X - X_ref`` for a reference of constant speed):

* damping ratio ``zeta = 1`` (critically damped: a member never overshoots
  its slot towards the member ahead of it in the same lane);
* natural frequency from the largest error the feedback alone has to remove,
  ``e_max = L_s / 4 = 5 m`` (a quarter of the paper's sublayer spacing
  L_s = 20 m; larger errors are re-planned by the reference profile), taken
  at the comfort acceleration limit ``a_fb = 1.5 m/s^2`` of the formation
  expert: the initial command of the critically damped loop from rest is
  ``omega_n^2 e``, so ``omega_n = sqrt(a_fb / e_max) = 0.548 rad/s``;
* hence ``k_p = -omega_n^2 = -0.3 s^-2`` and ``k_v = -2 zeta omega_n =
  -1.095 s^-1``; the 2% settling time is ``5.83 / omega_n = 10.6 s``.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from icv_envs.formation._kernels import join_search_banded
from icv_envs.formation._validate import finite

__all__ = [
    "DEFAULT_KP", "DEFAULT_KV", "DEFAULT_A_MIN", "DEFAULT_A_MAX", "DAMPING_RATIO", "FEEDBACK_ERROR",
    "FEEDBACK_ACCEL", "PROFILE_ACCEL", "PROFILE_DECEL", "PROFILE_JERK", "PROFILE_MIN_DURATION",
    "longitudinal_feedback", "join_profile", "join_duration",
]

#: Damping ratio of the error dynamics (critically damped: no overshoot).
DAMPING_RATIO: float = 1.0
#: [m] largest position error the feedback handles alone: L_s / 4 (paper Table 1, L_s = 20 m).
FEEDBACK_ERROR: float = 5.0
#: [m/s^2] comfort acceleration of the formation expert that error may ask for.
FEEDBACK_ACCEL: float = 1.5
_OMEGA_N = math.sqrt(FEEDBACK_ACCEL / FEEDBACK_ERROR)
#: Position gain k_p = -omega_n^2 (1/s^2), omega_n = sqrt(FEEDBACK_ACCEL / FEEDBACK_ERROR) = 0.548 rad/s.
DEFAULT_KP: float = -(_OMEGA_N ** 2)
#: Speed gain k_v = -2 zeta omega_n (1/s) = -1.095.
DEFAULT_KV: float = -2.0 * DAMPING_RATIO * _OMEGA_N
#: [m/s^2] peak acceleration of a join/re-assignment reference profile: IDM's
#: desired acceleration on highways (Treiber, Hennecke & Helbing 2000, a = 1 m/s^2).
PROFILE_ACCEL: float = 1.0
#: [m/s^2] peak deceleration of a profile: IDM's comfortable deceleration (ibid., b = 1.5 m/s^2).
PROFILE_DECEL: float = 1.5
#: [m/s^3] peak jerk of a profile (design choice: the profile's acceleration
#: takes at least 1 s to reach PROFILE_ACCEL).
PROFILE_JERK: float = 1.0
#: [s] shortest profile (a re-plan from nearly on the slot).
PROFILE_MIN_DURATION: float = 2.0
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
    a_ref=0.0,
) -> np.ndarray:
    """Acceleration command of the longitudinal feedback law.

    Paper Sec. 2.2, eq. (law)::

        a = clip(k_p (x - x_ref) + k_v (v - v_ref), a_min, a_max)

    A vehicle behind its reference (``x < x_ref``) accelerates; one faster than
    its reference (``v > v_ref``) brakes.  With the default gains
    (``k_p = -0.3``, ``k_v = -1.095``, module docstring) the unsaturated
    error dynamics ``e'' + 1.095 e' + 0.3 e = 0`` have a double pole at
    -0.548 (``omega_n = 0.548 rad/s``, ``zeta = 1``).  The limits default to
    the paper's ``a in [-6, 3] m/s^2``.  ``a_ref`` (default 0) is the
    reference's own acceleration, fed forward (a reference profile from
    :func:`join_profile` is followed exactly by a vehicle that starts on it).

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
    ar = _finite("a_ref", a_ref)
    try:
        return _longitudinal_feedback(xa, xr, va, vr, kpa, kva, lo, hi, ar)
    except ValueError:
        shapes = ", ".join(
            f"{n}{np.shape(s)}" for n, s in
            (("x", xa), ("x_ref", xr), ("v", va), ("v_ref", vr), ("kp", kpa), ("kv", kva))
        )
        raise ValueError(f"arguments are not broadcastable to a common shape: {shapes}") from None


def _longitudinal_feedback(x, x_ref, v, v_ref, kp, kv, a_min: float, a_max: float, a_ref) -> np.ndarray:
    """:func:`longitudinal_feedback` without its input checks, for callers
    whose arguments are already finite float64 arrays (or floats) that
    broadcast, with gains < 0 and ``a_min < 0 < a_max`` (the experts)."""
    return np.clip(a_ref + kp * (x - x_ref) + kv * (v - v_ref), a_min, a_max)


# ------------------------------------------------------------ join profile
def _quintic(t, T, d0, v0, a0, jerk: bool = True):
    """Offset, speed and acceleration (and with ``jerk`` the jerk) of the
    quintic from ``(d0, v0, a0)`` at ``t = 0`` to ``(0, 0, 0)`` at ``t = T``
    (clamped to 0 after ``T``). Each power is computed once (the same
    values as writing it out in every term)."""
    t = np.minimum(np.maximum(t, 0.0), T)
    c3, c4, c5 = _quintic_coeffs(T, d0, v0, a0)
    t2, t3, t4 = t ** 2, t ** 3, t ** 4
    d = d0 + v0 * t + 0.5 * a0 * t2 + c3 * t3 + c4 * t4 + c5 * t ** 5
    v = v0 + a0 * t + 3.0 * c3 * t2 + 4.0 * c4 * t3 + 5.0 * c5 * t4
    a = a0 + 6.0 * c3 * t + 12.0 * c4 * t2 + 20.0 * c5 * t3
    if not jerk:
        return d, v, a, None
    j = 6.0 * c3 + 24.0 * c4 * t + 60.0 * c5 * t2
    return d, v, a, j


def _quintic_coeffs(T, d0, v0, a0):
    """The coefficients ``(c3, c4, c5)`` of :func:`_quintic`'s polynomial
    (fixed per plan: a caller evaluating one plan many times keeps them)."""
    T2, T3, T4, T5 = T ** 2, T ** 3, T ** 4, T ** 5
    c3 = -(20.0 * d0 + 12.0 * v0 * T + 3.0 * a0 * T2) / (2.0 * T3)
    c4 = (30.0 * d0 + 16.0 * v0 * T + 3.0 * a0 * T2) / (2.0 * T4)
    c5 = -(12.0 * d0 + 6.0 * v0 * T + a0 * T2) / (2.0 * T5)
    return c3, c4, c5


def join_profile(t, T, d0, v0, a0):
    """Reference offset from a formation slot during a join (or after a
    re-assignment): ``(d, d', d'')`` at time ``t`` since the plan started.

    A member that joins at position error ``d0 = X - X_slot``, relative
    speed ``v0 = v - v_slot`` and acceleration ``a0`` tracks
    ``X_ref = X_slot + d(t)``, ``v_ref = v_slot + d'(t)``, with ``d''(t)``
    fed forward: a quintic (the minimum-jerk motion between the two states,
    Flash & Hogan 1985) that starts at the member's state and reaches the
    slot at rest relative to it after ``T`` seconds (:func:`join_duration`),
    instead of a step error. Arrays broadcast; after ``T`` the offset is 0."""
    T = np.asarray(T, dtype=np.float64)
    if np.any(~(T > 0)):
        raise ValueError(f"profile duration T must be > 0, got {T!r}")
    d, v, a, _ = _quintic(np.asarray(t, dtype=np.float64), T, np.asarray(d0, dtype=np.float64),
                          np.asarray(v0, dtype=np.float64), np.asarray(a0, dtype=np.float64), jerk=False)
    return d, v, a


_PROFILE_SAMPLES = np.linspace(0.0, 1.0, 201)  # where join_duration checks a profile (fractions of T)
_PROFILE_SAMPLES.flags.writeable = False


JOIN_GROW = 1.05  # join_duration's default ratio between the last infeasible and the returned duration
JOIN_SEARCH_CAP = 600.0  # join_duration's default max_duration [s]


def join_duration(d0, v0, a0, accel: float = PROFILE_ACCEL, decel: float = PROFILE_DECEL,
                  jerk: float = PROFILE_JERK, t_min: float = PROFILE_MIN_DURATION, grow: float = JOIN_GROW,
                  max_duration: float = JOIN_SEARCH_CAP, v_lo=-np.inf, v_hi=np.inf) -> np.ndarray:
    """Shortest duration ``T >= t_min`` (to within a factor ``grow``) for which the profile of :func:`join_profile` keeps its
    acceleration within ``[-decel, accel]`` (widened to the initial
    acceleration ``a0`` if that lies outside), its jerk within ``+-jerk``
    and its relative speed within ``[v_lo, v_hi]`` (widened to ``v0``;
    the caller passes the road's speed limits minus the slot's speed),
    checked on 201 points per profile. Vectorised."""
    for name, val in (("accel", accel), ("decel", decel), ("jerk", jerk), ("t_min", t_min)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {val!r}")
    if not grow > 1.0:
        raise ValueError(f"grow must be > 1, got {grow!r}")
    for name, val in (("v_lo", v_lo), ("v_hi", v_hi)):
        if np.any(np.isnan(np.asarray(val, dtype=np.float64))):
            raise ValueError(f"{name} must be numbers (+-inf for no bound), got {val!r}")
    d0, v0, a0 = np.broadcast_arrays(*(np.atleast_1d(_finite(n, x)) for n, x in
                                       (("d0", d0), ("v0", v0), ("a0", a0))))
    shape = d0.shape
    d0, v0, a0 = (np.ascontiguousarray(x, dtype=np.float64).reshape(-1) for x in (d0, v0, a0))
    band = (np.broadcast_to(np.asarray(b, dtype=np.float64), shape).reshape(-1) for b in (v_lo, v_hi))
    T = _join_duration_banded(d0, v0, a0, accel, decel, jerk, t_min, *band, max_duration, grow, cap_free=None)
    return T.reshape(shape)


def _join_duration_banded(d0, v0, a0, accel, decel, jerk, t_min, v_lo, v_hi, cap, grow=JOIN_GROW,
                          cap_free=JOIN_SEARCH_CAP) -> np.ndarray:
    """:func:`join_duration` without its input checks, for 1-D float64
    arrays ``d0, v0, a0`` whose values and limits are valid; the speed band
    ``v_lo, v_hi``: numbers or arrays of ``d0``'s length. With ``cap_free``
    (the formation layer's plans), members whose banded search reaches
    ``cap`` (no duration keeps the quintic inside the band) get
    ``join_duration(..., max_duration=cap_free)`` without the band.

    The search starts from 0.7 x the rest-to-rest estimate of the
    minimum-jerk move (peak acceleration 5.77 d / T^2, jerk 60 d / T^3,
    closing speed), doubles until feasible, then bisects (in log T) between
    the last infeasible and the first feasible duration to a ratio of
    ``grow``, the limits checked on every sample of ``_quintic(tau * T, T,
    ...)``: one compiled call after numpy's cube roots
    (:func:`icv_envs.formation._kernels.join_search_banded`)."""
    n = d0.shape[0]
    cb = np.cbrt(60.0 * np.abs(d0) / jerk)
    # always fresh writable copies: a read-only broadcast view (one member: already contiguous, so
    # ascontiguousarray kept it) made numba compile or load a second, read-only specialisation
    lo_v, hi_v = (np.array(np.broadcast_to(np.asarray(b, dtype=np.float64), (n,)), dtype=np.float64) for b in (v_lo, v_hi))
    return join_search_banded(cb, d0, v0, a0, float(accel), float(decel), float(jerk), float(t_min), float(grow),
                              float(cap), lo_v, hi_v, cap_free is not None,
                              float(JOIN_SEARCH_CAP if cap_free is None else cap_free), _PROFILE_SAMPLES)
