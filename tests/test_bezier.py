"""Tests for icv_envs.formation.bezier (paper Sec. 2.2 / 3.4)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.formation import (
    DEFAULT_MAX_STEER,
    cubic_bezier,
    lane_change_control_points,
    lane_change_lateral,
    pure_pursuit_steering,
)

SETTINGS = settings(max_examples=60, deadline=None, database=None)
finite = dict(allow_nan=False, allow_infinity=False)
x0_st = st.floats(min_value=-1000.0, max_value=1000.0, **finite)
y_st = st.floats(min_value=-20.0, max_value=20.0, **finite)
len_st = st.floats(min_value=1.0, max_value=300.0, **finite)


# ---------------------------------------------------------------------------
# cubic_bezier
# ---------------------------------------------------------------------------
def test_cubic_bezier_endpoints_and_shape():
    p = [np.array([0.0, 0.0]), np.array([1.0, 2.0]), np.array([3.0, 2.0]), np.array([4.0, 0.0])]
    pts = cubic_bezier(*p, np.array([0.0, 0.5, 1.0]))
    assert pts.shape == (3, 2)
    np.testing.assert_allclose(pts[0], p[0])
    np.testing.assert_allclose(pts[-1], p[3])
    np.testing.assert_allclose(pts[1], [2.0, 1.5])  # (p0 + 3p1 + 3p2 + p3)/8
    assert cubic_bezier(*p, 0.25).shape == (2,)


def test_cubic_bezier_batched_control_points():
    p0, p1, p2, p3 = lane_change_control_points([0.0, 10.0], [0.0, 4.0], [4.0, 0.0], 50.0)
    assert p0.shape == (2, 2)
    pts = cubic_bezier(p0, p1, p2, p3, np.array([[0.0], [1.0]]))
    assert pts.shape == (2, 2, 2)
    np.testing.assert_allclose(pts[0], p0)
    np.testing.assert_allclose(pts[1], p3)


def test_cubic_bezier_bad_input():
    p = np.zeros(2)
    with pytest.raises(ValueError, match=r"t must lie in \[0, 1\].*1\.5"):
        cubic_bezier(p, p, p, p, np.array([0.0, 1.5]))
    with pytest.raises(ValueError, match=r"p2 must have shape \(\.\.\., 2\)"):
        cubic_bezier(p, p, np.zeros(3), p, 0.5)
    with pytest.raises(ValueError, match=r"p0 must be finite.*nan"):
        cubic_bezier(np.array([np.nan, 0.0]), p, p, p, 0.5)
    with pytest.raises(ValueError, match="broadcast"):
        cubic_bezier(np.zeros((3, 2)), np.zeros((4, 2)), p, p, 0.5)


# ---------------------------------------------------------------------------
# lane_change_lateral
# ---------------------------------------------------------------------------
def test_lane_change_endpoints_and_clamping():
    x = np.array([-100.0, 0.0, 1e-12, 60.0, 60.0 + 1e-9, 500.0])
    y, slope = lane_change_lateral(x, 0.0, 2.0, 6.0, 60.0)
    np.testing.assert_allclose(y[[0, 1]], 2.0, atol=0)
    np.testing.assert_allclose(y[[3, 4, 5]], 6.0, atol=0)
    np.testing.assert_allclose(slope[[0, 1, 3, 4, 5]], 0.0, atol=0)
    assert y[2] == pytest.approx(2.0, abs=1e-9) and slope[2] == pytest.approx(0.0, abs=1e-9)


def test_lane_change_shape_midpoint_and_max_slope():
    x0, y0, y1, d = 5.0, -1.0, 3.0, 40.0
    x = np.linspace(x0 - 10, x0 + d + 10, 20001)
    y, slope = lane_change_lateral(x, x0, y0, y1, d)
    assert y.shape == slope.shape == x.shape
    # y between y0 and y1, monotone, symmetric about the midpoint
    assert np.all((y >= y0) & (y <= y1))
    assert np.all(np.diff(y) >= 0.0)
    ym, sm = lane_change_lateral(x0 + d / 2, x0, y0, y1, d)
    assert ym == pytest.approx(0.5 * (y0 + y1), abs=1e-12)
    assert sm == pytest.approx(2.0 * (y1 - y0) / d, rel=1e-12)
    assert slope.max() == pytest.approx(2.0 * (y1 - y0) / d, rel=1e-6)
    # slope is continuous (no jumps anywhere, including at both ends)
    assert np.max(np.abs(np.diff(slope))) < 1e-3
    # slope is the derivative of y
    mid = 0.5 * (x[1:] + x[:-1])
    _, s_mid = lane_change_lateral(mid, x0, y0, y1, d)
    np.testing.assert_allclose(np.diff(y) / np.diff(x), s_mid, atol=1e-5)
    # the path's x(t) is strictly increasing, so it is a function y(x)
    t = np.linspace(0.0, 1.0, 10001)
    pts = cubic_bezier(*lane_change_control_points(x0, y0, y1, d), t)
    assert np.all(np.diff(pts[:, 0]) > 0.0)


def test_lane_change_vectorised_over_vehicles():
    n = 400
    rng = np.random.default_rng(1)
    x0 = rng.uniform(0, 1000, n)
    y0 = rng.integers(0, 4, n) * 4.0
    y1 = y0 + rng.choice([-4.0, 4.0], n)
    d = rng.uniform(30, 120, n)
    x = x0 + rng.uniform(-0.2, 1.2, n) * d
    y, slope = lane_change_lateral(x, x0, y0, y1, d)
    assert y.shape == slope.shape == (n,)
    for i in range(0, n, 37):
        yi, si = lane_change_lateral(x[i], x0[i], y0[i], y1[i], d[i])
        assert y[i] == yi and slope[i] == si


@SETTINGS
@given(x0=x0_st, y0=y_st, y1=y_st, d=len_st,
       t=st.lists(st.floats(min_value=0.0, max_value=1.0), min_size=1, max_size=20))
def test_lane_change_matches_bezier(x0, y0, y1, d, t):
    t = np.array(t)
    pts = cubic_bezier(*lane_change_control_points(x0, y0, y1, d), t)
    # the path's x(t) is strictly increasing: x = x0 + D (1.5 t (1-t) + t^3)
    np.testing.assert_allclose(pts[:, 0], x0 + d * (1.5 * t * (1 - t) + t**3),
                               rtol=0, atol=1e-9)
    y, slope = lane_change_lateral(pts[:, 0], x0, y0, y1, d)
    # the round trip through x loses only the rounding of x itself
    tol = 1e-9 + 1e-13 * abs(x0) * abs(y1 - y0) / d * 10
    np.testing.assert_allclose(y, pts[:, 1], rtol=0, atol=tol)
    # slope = (dy/dt) / (dx/dt) at the same t (up to the recovered t)
    dydt = (y1 - y0) * 6 * t * (1 - t)
    dxdt = d * (1.5 - 3 * t + 3 * t**2)
    np.testing.assert_allclose(slope, dydt / dxdt, rtol=1e-6, atol=1e-9)


@SETTINGS
@given(x0=x0_st, y0=y_st, y1=y_st, d=len_st, s=st.floats(min_value=-0.5, max_value=1.5))
def test_lane_change_bounds(x0, y0, y1, d, s):
    x = x0 + s * d
    y, slope = lane_change_lateral(x, x0, y0, y1, d)
    assert min(y0, y1) - 1e-12 <= y <= max(y0, y1) + 1e-12
    assert abs(slope) <= 2.0 * abs(y1 - y0) / d * (1 + 1e-9) + 1e-15
    # clamping is exact, decided by comparing x with x0 and x0 + D
    if x <= x0:
        assert y == y0 and slope == 0.0
    if x >= x0 + d:
        assert y == y1 and slope == 0.0


def test_lane_change_bad_input():
    with pytest.raises(ValueError, match=r"length must be > 0.*0\.0"):
        lane_change_lateral(1.0, 0.0, 0.0, 4.0, 0.0)
    with pytest.raises(ValueError, match=r"length must be > 0.*-3\.0"):
        lane_change_lateral(1.0, 0.0, 0.0, 4.0, [10.0, -3.0])
    with pytest.raises(ValueError, match=r"x must be finite.*nan"):
        lane_change_lateral(np.nan, 0.0, 0.0, 4.0, 10.0)
    with pytest.raises(ValueError, match=r"y1 must be finite.*inf"):
        lane_change_lateral(1.0, 0.0, 0.0, np.inf, 10.0)
    with pytest.raises(ValueError, match=r"not broadcastable.*x\(3,\).*x0\(2,\)"):
        lane_change_lateral(np.zeros(3), np.zeros(2), 0.0, 4.0, 10.0)


# ---------------------------------------------------------------------------
# pure_pursuit_steering
# ---------------------------------------------------------------------------
def test_pure_pursuit_sign_convention():
    # straight ahead -> 0
    assert pure_pursuit_steering(0.0, 0.0, 0.0, 20.0, 0.0) == pytest.approx(0.0)
    # target at larger y (to the left with +y left) -> positive steering
    assert pure_pursuit_steering(0.0, 0.0, 0.0, 20.0, 1.0) > 0.0
    assert pure_pursuit_steering(0.0, 0.0, 0.0, 20.0, -1.0) < 0.0
    # heading +y: the vehicle's left is -x
    assert pure_pursuit_steering(0.0, 0.0, np.pi / 2, -1.0, 20.0) > 0.0
    assert pure_pursuit_steering(0.0, 0.0, np.pi / 2, 1.0, 20.0) < 0.0
    # heading wraps
    a = pure_pursuit_steering(3.0, 4.0, 0.3, 20.0, 9.0)
    b = pure_pursuit_steering(3.0, 4.0, 0.3 + 4 * np.pi, 20.0, 9.0)
    assert a == pytest.approx(b, abs=1e-12)
    # coincident target -> 0
    assert pure_pursuit_steering(1.0, 1.0, 0.7, 1.0, 1.0) == 0.0


def test_pure_pursuit_formula_and_clipping():
    L = 2.8
    phi = pure_pursuit_steering(0.0, 0.0, 0.0, 10.0, 1.0, wheelbase=L)
    alpha, ld = np.arctan2(1.0, 10.0), np.hypot(10.0, 1.0)
    assert phi == pytest.approx(np.arctan(2 * L * np.sin(alpha) / ld), rel=1e-12)
    # sharp target -> clipped to +-30 deg
    assert pure_pursuit_steering(0.0, 0.0, 0.0, 1.0, 3.0) == pytest.approx(DEFAULT_MAX_STEER)
    assert pure_pursuit_steering(0.0, 0.0, 0.0, 1.0, -3.0) == pytest.approx(-DEFAULT_MAX_STEER)
    assert pure_pursuit_steering(0.0, 0.0, 0.0, 1.0, 3.0, max_steer=0.1) == pytest.approx(0.1)


@SETTINGS
@given(
    rx=st.floats(-100, 100), ry=st.floats(-100, 100), th=st.floats(-10, 10),
    dist=st.floats(5.0, 50.0), ang=st.floats(-1.2, 1.2),
)
def test_pure_pursuit_arc_passes_through_target(rx, ry, th, dist, ang):
    """Unclipped, the steering's circular arc goes through the preview point."""
    L = 2.8
    tx, ty = rx + dist * np.cos(th + ang), ry + dist * np.sin(th + ang)
    phi = float(pure_pursuit_steering(rx, ry, th, tx, ty, wheelbase=L, max_steer=1.5))
    assert np.sign(phi) == np.sign(np.round(ang, 12)) or abs(ang) < 1e-12
    kappa = np.tan(phi) / L
    # target in vehicle frame
    lx = np.cos(th) * (tx - rx) + np.sin(th) * (ty - ry)
    ly = -np.sin(th) * (tx - rx) + np.cos(th) * (ty - ry)
    # circle through origin tangent to +x with curvature kappa: x^2 + y^2 = 2 y / kappa
    assert kappa * (lx**2 + ly**2) == pytest.approx(2 * ly, abs=1e-9 * dist)


def test_pure_pursuit_vectorised_and_bad_input():
    n = 500
    rng = np.random.default_rng(2)
    out = pure_pursuit_steering(np.zeros(n), np.zeros(n), rng.uniform(-3, 3, n),
                                rng.uniform(-50, 50, n), rng.uniform(-50, 50, n))
    assert out.shape == (n,)
    assert np.all(np.abs(out) <= DEFAULT_MAX_STEER)
    with pytest.raises(ValueError, match=r"wheelbase.*-1\.0"):
        pure_pursuit_steering(0.0, 0.0, 0.0, 1.0, 1.0, wheelbase=-1.0)
    with pytest.raises(ValueError, match=r"max_steer.*2\.0"):
        pure_pursuit_steering(0.0, 0.0, 0.0, 1.0, 1.0, max_steer=2.0)
    with pytest.raises(ValueError, match=r"max_steer.*0\.0"):
        pure_pursuit_steering(0.0, 0.0, 0.0, 1.0, 1.0, max_steer=0.0)
    with pytest.raises(ValueError, match=r"heading must be finite.*nan"):
        pure_pursuit_steering(0.0, 0.0, np.nan, 1.0, 1.0)
    with pytest.raises(ValueError, match="not broadcastable"):
        pure_pursuit_steering(np.zeros(2), np.zeros(3), 0.0, 1.0, 1.0)
