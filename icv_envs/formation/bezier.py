"""Cubic Bezier lane changes and preview (pure-pursuit) steering.

Paper Sec. 2.2 and Sec. 3.4 (Xu et al., IET ITS 2021): lane keeping and lane
changes follow a 3rd-order Bezier curve, tracked with a preview steering law
(docs/formation.md#lane-changes).  The paper does not give the control points; we use the
standard symmetric choice, in road coordinates (``x`` forward, ``y`` lateral)::

    P0 = (x0, y0),  P1 = (x0 + D/2, y0),  P2 = (x0 + D/2, y1),  P3 = (x0 + D, y1)

whose tangents are parallel to the road at both ends (zero slope, so the
manoeuvre starts and ends with zero curvature demand on the heading).  Then::

    x(t) = x0 + D (1.5 t (1 - t) + t^3),   dx/dt = D (3 (t - 1/2)^2 + 3/4) > 0
    y(t) = y0 + (y1 - y0) (3 t^2 - 2 t^3)

``x(t)`` is strictly increasing, so the path is a function ``y(x)``, and
``t(x)`` has the closed form ``t = 1/2 + sinh(asinh(4 s - 2) / 3)`` with
``s = (x - x0) / D`` (trigonometric/hyperbolic solution of the depressed cubic
``u^3 + 3/4 u + 1/2 - s = 0``, ``u = t - 1/2``).

The public functions are numpy and broadcast over vehicles;
:func:`_lane_change_lateral_rows` and :func:`_pure_pursuit_rows` are the
experts' per-step forms on vehicle rows (compiled arithmetic around numpy's
transcendental calls, the same numbers bit for bit).
"""

from __future__ import annotations

import numpy as np

from icv_envs.formation._kernels import lateral_rows, pursuit_rows
from icv_envs.formation._validate import finite

__all__ = [
    "DEFAULT_WHEELBASE",
    "DEFAULT_MAX_STEER",
    "cubic_bezier",
    "lane_change_control_points",
    "lane_change_lateral",
    "pure_pursuit_steering",
]

#: Wheelbase L of the bicycle model in metres (paper Table "vehicle parameters").
DEFAULT_WHEELBASE: float = 2.8
#: Steering limit in radians: |phi| <= 30 deg (paper Table "vehicle parameters").
DEFAULT_MAX_STEER: float = float(np.deg2rad(30.0))


_finite = finite


def _broadcast(**arrays: np.ndarray) -> list[np.ndarray]:
    try:
        return list(np.broadcast_arrays(*arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{k}{np.shape(v)}" for k, v in arrays.items())
        raise ValueError(f"arguments are not broadcastable to a common shape: {shapes}") from None


def cubic_bezier(p0, p1, p2, p3, t) -> np.ndarray:
    """Points of the cubic Bezier curve with control points ``p0..p3``.

    Paper Sec. 3.4 ("3-order Bezier curve")::

        B(t) = (1-t)^3 p0 + 3 (1-t)^2 t p1 + 3 (1-t) t^2 p2 + t^3 p3,  t in [0, 1]

    Args:
        p0, p1, p2, p3: control points, arrays of shape (..., 2) (broadcastable
            against each other, e.g. one curve per vehicle).
        t: curve parameters in ``[0, 1]``, any shape ``T``.

    Returns:
        float64 array of shape ``broadcast(T, P) + (2,)`` where ``P`` is the
        broadcast leading shape of the control points; e.g. (2,) control
        points and t of shape (K,) give (K, 2).

    Raises:
        ValueError: non-finite input, control points whose last axis is not 2
            or that do not broadcast, or ``t`` outside ``[0, 1]``.
    """
    pts = [_finite(f"p{i}", p) for i, p in enumerate((p0, p1, p2, p3))]
    for i, p in enumerate(pts):
        if p.ndim == 0 or p.shape[-1] != 2:
            raise ValueError(f"p{i} must have shape (..., 2), got {p.shape}")
    tt = _finite("t", t)
    if np.any((tt < 0.0) | (tt > 1.0)):
        bad = np.atleast_1d(tt)[(np.atleast_1d(tt) < 0.0) | (np.atleast_1d(tt) > 1.0)]
        raise ValueError(f"t must lie in [0, 1], got {bad.tolist()}")
    tt = tt[..., None]
    s = 1.0 - tt
    b0, b1, b2, b3 = s * s * s, 3.0 * s * s * tt, 3.0 * s * tt * tt, tt * tt * tt
    try:
        return b0 * pts[0] + b1 * pts[1] + b2 * pts[2] + b3 * pts[3]
    except ValueError:
        raise ValueError(
            "control points and t do not broadcast: "
            + ", ".join(f"p{i}{p.shape}" for i, p in enumerate(pts))
            + f", t{np.shape(t)}"
        ) from None


def lane_change_control_points(x0, y0, y1, length) -> tuple[np.ndarray, ...]:
    """Control points ``(P0, P1, P2, P3)`` of the lane-change Bezier curve.

    Paper Sec. 3.4 (control points are our choice, see module docstring):
    ``P0=(x0,y0), P1=(x0+D/2,y0), P2=(x0+D/2,y1), P3=(x0+D,y1)``.  Each returned
    point has shape ``broadcast(x0, y0, y1, length) + (2,)``.

    Raises:
        ValueError: non-finite input, ``length <= 0`` or shapes that do not
            broadcast.
    """
    x0a, y0a, y1a, d = _broadcast(
        x0=_finite("x0", x0), y0=_finite("y0", y0), y1=_finite("y1", y1),
        length=_finite("length", length),
    )
    _check_length(d)
    xm = x0a + 0.5 * d
    return (
        np.stack([x0a, y0a], axis=-1),
        np.stack([xm, y0a], axis=-1),
        np.stack([xm, y1a], axis=-1),
        np.stack([x0a + d, y1a], axis=-1),
    )


def _check_length(d: np.ndarray) -> None:
    if np.any(d <= 0.0):
        bad = np.atleast_1d(d)[np.atleast_1d(d) <= 0.0]
        raise ValueError(f"length must be > 0 (metres), got {bad.tolist()}")


def lane_change_lateral(x, x0, y0, y1, length) -> tuple[np.ndarray, np.ndarray]:
    """Lateral position and slope of the Bezier lane-change path at ``x``.

    Paper Sec. 3.4: the cubic Bezier lane change with control points
    ``(x0,y0), (x0+D/2,y0), (x0+D/2,y1), (x0+D,y1)`` (``D = length``) seen as a
    function ``y(x)``.  ``t`` is recovered from ``x`` in closed form,
    ``t = 1/2 + sinh(asinh(4 s - 2) / 3)`` with ``s = (x - x0)/D``, followed by
    one vectorised Newton step (error far below 1e-9 m), then::

        y     = y0 + (y1 - y0) (3 t^2 - 2 t^3)
        dy/dx = (y1 - y0) 6 t (1 - t) / (D (3 t^2 - 3 t + 3/2))

    Outside the manoeuvre the path is the straight lane: for ``x <= x0`` the
    result is ``(y0, 0)``, for ``x >= x0 + D`` it is ``(y1, 0)``.  The slope is
    continuous everywhere and its largest magnitude, ``2 |y1 - y0| / D``, is at
    the midpoint.

    Args:
        x: longitudinal positions (m).
        x0: start of the manoeuvre (m).
        y0, y1: lateral positions before / after (m, or any lateral unit).
        length: longitudinal length ``D`` of the manoeuvre, > 0.
        All arguments are broadcastable arrays (e.g. one entry per vehicle).

    Returns:
        ``(y, dy_dx)``: float64 arrays of the broadcast shape.

    Raises:
        ValueError: non-finite input, ``length <= 0`` or non-broadcastable
            shapes.
    """
    xa, x0a, y0a, y1a, d = _broadcast(
        x=_finite("x", x), x0=_finite("x0", x0), y0=_finite("y0", y0),
        y1=_finite("y1", y1), length=_finite("length", length),
    )
    _check_length(d)
    return _lane_change_lateral(xa, x0a, y0a, y1a, d)


def _lane_change_lateral(xa, x0a, y0a, y1a, d) -> tuple[np.ndarray, np.ndarray]:
    """:func:`lane_change_lateral` without its input checks, for callers
    whose arguments are already finite float64 arrays (or floats) that
    broadcast, with ``d > 0`` (the experts, once per step)."""
    s = np.clip((xa - x0a) / d, 0.0, 1.0)
    t = 0.5 + np.sinh(np.arcsinh(4.0 * s - 2.0) / 3.0)
    # One Newton step on f(t) = t^3 - 1.5 t^2 + 1.5 t - s (f' >= 3/4).
    t = t - (((t - 1.5) * t + 1.5) * t - s) / ((3.0 * t - 3.0) * t + 1.5)
    t = np.clip(t, 0.0, 1.0)
    dy = y1a - y0a
    y = y0a + dy * (t * t * (3.0 - 2.0 * t))
    slope = dy * (6.0 * t * (1.0 - t)) / (d * ((3.0 * t - 3.0) * t + 1.5))
    before, after = xa <= x0a, xa >= x0a + d
    y = np.where(before, y0a, np.where(after, y1a, y))
    slope = np.where(before | after, 0.0, slope)
    return y, slope


def _lane_change_lateral_rows(rows, x, x0, y0, y1, d) -> tuple[np.ndarray, np.ndarray]:
    """``_lane_change_lateral(x[rows], x0[rows], y0[rows], y1[rows],
    d[rows])`` for 1-D float64 arrays ``x, x0, y0, y1, d`` (finite, ``d >
    0`` at ``rows``) and int64 ``rows``, in one compiled pass
    (:func:`icv_envs.formation._kernels.lateral_rows`): the same operations,
    ``arcsinh`` and ``sinh`` libm's (from stop 49; numpy's between two
    kernels before), which numpy's are at ``X86_V3`` (the rule of
    :mod:`icv_envs.sim._kernels`)."""
    if x.flags.writeable:  # one specialisation of the kernel: x is a read-only state array at most call sites
        x = x.view()
        x.flags.writeable = False
    return lateral_rows(rows, x, x0, y0, y1, d)


def _pure_pursuit_rows(rx, ry, th, tx, ty, wb: float, ms: float, cos_sin=None) -> np.ndarray:
    """:func:`_pure_pursuit_steering` for 1-D float64 arrays of one length
    (finite; ``wb > 0``, ``0 < ms < pi/2``) in one compiled pass
    (:func:`icv_envs.formation._kernels.pursuit_rows`): the same operations,
    ``hypot`` and ``arctan`` libm's (from stop 49; numpy's between two
    kernels before), which numpy's are at ``X86_V3`` (the rule of
    :mod:`icv_envs.sim._kernels`). ``cos_sin``: ``(np.cos(th),
    np.sin(th))`` when the caller has them (numpy's ``cos`` and ``sin``
    are libm's on every SIMD level checked)."""
    c, s = (np.cos(th), np.sin(th)) if cos_sin is None else cos_sin
    return pursuit_rows(rx, ry, c, s, tx, ty, float(wb), float(ms))


def pure_pursuit_steering(
    rear_x,
    rear_y,
    heading,
    target_x,
    target_y,
    wheelbase: float = DEFAULT_WHEELBASE,
    max_steer: float = DEFAULT_MAX_STEER,
) -> np.ndarray:
    """Preview (pure-pursuit) steering angle for the rear-axle bicycle model.

    Paper Sec. 2.2 ("the preview method is chosen to guide vehicle to follow
    the trajectory"; docs/formation.md#preview-steering).  With the preview point at angle ``alpha``
    in the vehicle frame and distance ``l_d`` from the rear axle, the circle
    through the rear axle tangent to the heading and through the preview point
    has curvature ``2 sin(alpha) / l_d``; the bicycle model
    ``heading' = v tan(phi) / L`` follows it with::

        phi = atan(2 L sin(alpha) / l_d),  clipped to [-max_steer, max_steer]

    Sign convention: ``heading`` is measured from +x towards +y, positive
    ``phi`` increases ``heading``; a target at positive lateral offset (to the
    left when +y is left) gives positive steering.  A preview point that
    coincides with the rear axle (``l_d = 0``) gives ``phi = 0``.  A target
    behind the vehicle (``|alpha| > 90 deg``) is pursued with the same formula
    (standard pure pursuit); callers should preview ahead.

    Args:
        rear_x, rear_y: rear-axle position (m).
        heading: yaw angle (rad), any real value (wrapped internally).
        target_x, target_y: preview point (m).
        wheelbase: ``L`` > 0 (m), default 2.8 m.
        max_steer: steering limit in (0, pi/2) rad, default 30 deg.
        Position/heading arguments broadcast (one entry per vehicle).

    Returns:
        float64 array of steering angles (rad), the broadcast shape.

    Raises:
        ValueError: non-finite input, ``wheelbase <= 0``, ``max_steer`` not in
            (0, pi/2), or non-broadcastable shapes.
    """
    wb = float(_finite("wheelbase", wheelbase))
    if np.ndim(wheelbase) != 0 or wb <= 0.0:
        raise ValueError(f"wheelbase must be a finite scalar > 0 (metres), got {wheelbase!r}")
    ms = float(_finite("max_steer", max_steer))
    if np.ndim(max_steer) != 0 or not 0.0 < ms < 0.5 * np.pi:
        raise ValueError(f"max_steer must be a finite scalar in (0, pi/2) rad, got {max_steer!r}")
    rx, ry, th, tx, ty = _broadcast(
        rear_x=_finite("rear_x", rear_x), rear_y=_finite("rear_y", rear_y),
        heading=_finite("heading", heading), target_x=_finite("target_x", target_x),
        target_y=_finite("target_y", target_y),
    )
    return _pure_pursuit_steering(rx, ry, th, tx, ty, wb, ms)


def _pure_pursuit_steering(rx, ry, th, tx, ty, wb: float, ms: float) -> np.ndarray:
    """:func:`pure_pursuit_steering` without its input checks, for callers
    whose arguments are already finite float64 arrays that broadcast, with
    ``wb > 0`` and ``0 < ms < pi/2`` floats (the experts, once per step)."""
    dx, dy = tx - rx, ty - ry
    ld = np.hypot(dx, dy)
    # sin(alpha) with alpha = atan2(dy, dx) - heading, without the atan2:
    # sin(alpha) * l_d = cross(heading unit vector, d) = lateral offset in vehicle frame.
    lateral = np.cos(th) * dy - np.sin(th) * dx
    safe_ld = np.where(ld > 0.0, ld, 1.0)
    curvature = np.where(ld > 0.0, 2.0 * lateral / (safe_ld * safe_ld), 0.0)
    phi = np.arctan(wb * curvature)
    return np.clip(phi, -ms, ms)
