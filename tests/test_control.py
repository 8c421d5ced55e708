"""Tests for icv_envs.formation.control (paper Sec. 2.2, eq. (law))."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.formation import DEFAULT_KP, DEFAULT_KV, longitudinal_feedback

SETTINGS = settings(max_examples=25, deadline=None, database=None)
DT = 0.04  # paper Table 1 time step


def test_default_gains_are_well_damped():
    assert DEFAULT_KP < 0 and DEFAULT_KV < 0
    # characteristic polynomial s^2 - kv s - kp
    poles = np.roots([1.0, -DEFAULT_KV, -DEFAULT_KP])
    assert np.all(np.isreal(poles)) and np.all(poles.real < 0)
    np.testing.assert_allclose(np.sort(poles.real), [-0.6, -0.5])
    zeta = -DEFAULT_KV / (2 * np.sqrt(-DEFAULT_KP))
    assert zeta >= 1.0


def test_signs():
    # behind its reference -> accelerates
    assert longitudinal_feedback(0.0, 5.0, 20.0, 20.0) > 0
    # ahead of its reference -> decelerates
    assert longitudinal_feedback(5.0, 0.0, 20.0, 20.0) < 0
    # faster than the reference -> brakes; slower -> accelerates
    assert longitudinal_feedback(0.0, 0.0, 22.0, 20.0) < 0
    assert longitudinal_feedback(0.0, 0.0, 18.0, 20.0) > 0
    # on reference -> zero
    assert longitudinal_feedback(3.0, 3.0, 20.0, 20.0) == 0.0
    # exact value in the linear range
    a = longitudinal_feedback(0.0, 2.0, 21.0, 20.0)
    assert a == pytest.approx(-0.3 * -2.0 + -1.1 * 1.0)


def test_clipping_and_vectorisation():
    x = np.array([0.0, 0.0, 0.0, 0.0])
    x_ref = np.array([1000.0, -1000.0, 1.0, 0.0])
    v = np.full(4, 20.0)
    a = longitudinal_feedback(x, x_ref, v, 20.0)
    assert a.shape == (4,)
    np.testing.assert_allclose(a, [3.0, -6.0, 0.3, 0.0])
    a = longitudinal_feedback(x, x_ref, v, 20.0, a_min=-2.0, a_max=1.0)
    np.testing.assert_allclose(a, [1.0, -2.0, 0.3, 0.0])
    # per-vehicle gains broadcast
    a = longitudinal_feedback(x, 1.0, 20.0, 20.0, kp=np.array([-0.1, -0.2, -0.3, -0.4]))
    np.testing.assert_allclose(a, [0.1, 0.2, 0.3, 0.4])


@SETTINGS
@given(
    x=st.floats(-1e4, 1e4), xr=st.floats(-1e4, 1e4),
    v=st.floats(0, 40), vr=st.floats(0, 40),
)
def test_always_within_limits(x, xr, v, vr):
    a = longitudinal_feedback(x, xr, v, vr)
    assert -6.0 <= a <= 3.0


def _simulate(e0, de0, t_end: float = 60.0, v_ref: float = 25.0, clip_error=None):
    """Batch of point masses x'' = a tracking x_ref(t) = 100 + v_ref t.

    ``clip_error=E`` applies the documented recipe
    ``x_ref_eff = x + clip(x_ref - x, -E, E)``.  Returns the error history
    (steps, n) and the final speed errors.
    """
    e0, de0 = np.asarray(e0, dtype=float), np.asarray(de0, dtype=float)
    x_ref0 = 100.0
    x = x_ref0 + e0
    v = v_ref + de0
    errors = []
    for k in range(int(round(t_end / DT))):
        x_ref = x_ref0 + v_ref * k * DT
        if clip_error is not None:
            x_ref = x + np.clip(x_ref - x, -clip_error, clip_error)
        a = longitudinal_feedback(x, x_ref, v, v_ref)
        # semi-implicit Euler
        v = v + a * DT
        x = x + v * DT
        errors.append(x - (x_ref0 + v_ref * (k + 1) * DT))
    return np.array(errors), v - v_ref


def _overshoot(e0, err):
    """Largest excursion past zero, on the side opposite to the initial error."""
    return np.max(-np.sign(e0) * err, axis=0)


def test_closed_loop_converges_without_overshoot():
    # position errors up to 100 m (5 sublayer gaps) either way, equal speeds
    e0 = np.array([-100.0, -60.0, -20.0, -5.0, -0.5, 0.5, 5.0, 20.0, 60.0, 100.0])
    err, dv = _simulate(e0, np.zeros_like(e0))
    assert np.all(np.abs(err[-1]) < 1e-3)
    assert np.all(np.abs(dv) < 1e-3)
    # no overshoot: the error never changes sign beyond a small tolerance
    overshoot = _overshoot(e0, err)
    assert np.all(overshoot < 1e-3 * np.abs(e0) + 1e-3), overshoot
    # monotone approach
    assert np.all(np.diff(np.abs(err), axis=0) <= 1e-9)


pairs_st = st.lists(
    st.tuples(st.floats(-90.0, 90.0).filter(lambda e: abs(e) > 1e-3), st.floats(0.0, 3.0)),
    min_size=1, max_size=20,
)


@SETTINGS
@given(pairs=pairs_st)
def test_closed_loop_moving_away_no_overshoot(pairs):
    """Errors up to 90 m, initially growing at up to 3 m/s: no overshoot."""
    e0 = np.array([p[0] for p in pairs])
    de0 = np.sign(e0) * np.array([p[1] for p in pairs])
    err, dv = _simulate(e0, de0, t_end=60.0)
    assert np.all(np.abs(err[-1]) < 1e-2) and np.all(np.abs(dv) < 1e-2)
    assert np.all(_overshoot(e0, err) < 1e-3 * np.abs(e0) + 1e-3)


def test_large_lead_overshoots_unless_error_is_bounded():
    """Documented saturation caveat: 150 m ahead overshoots; the E = 50 m recipe fixes it."""
    e0 = np.array([150.0])
    err, _ = _simulate(e0, np.zeros(1), t_end=80.0)
    assert _overshoot(e0, err)[0] > 1.0
    err, dv = _simulate(e0, np.zeros(1), t_end=80.0, clip_error=50.0)
    assert _overshoot(e0, err)[0] < 1e-3
    assert abs(err[-1, 0]) < 1e-3 and abs(dv[0]) < 1e-3


@settings(max_examples=10, deadline=None, database=None)
@given(pairs=st.lists(
    st.tuples(st.floats(-1000.0, 1000.0).filter(lambda e: abs(e) > 1e-3), st.floats(0.0, 10.0)),
    min_size=1, max_size=20,
))
def test_bounded_error_recipe_never_overshoots(pairs):
    e0 = np.array([p[0] for p in pairs])
    de0 = np.sign(e0) * np.array([p[1] for p in pairs])
    err, dv = _simulate(e0, de0, t_end=110.0, clip_error=50.0)
    assert np.all(_overshoot(e0, err) < 1e-3 * np.abs(e0) + 1e-3)
    assert np.all(np.abs(err[-1]) < 1e-2) and np.all(np.abs(dv) < 1e-2)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(kp=0.3), r"kp must be < 0.*0\.3"),
        (dict(kp=0.0), r"kp must be < 0"),
        (dict(kv=1.1), r"kv must be < 0.*1\.1"),
        (dict(kv=np.array([-1.0, 0.5])), r"kv must be < 0"),
        (dict(kp=float("nan")), r"kp must be finite.*nan"),
        (dict(a_min=1.0), r"a_min must be < 0.*1\.0"),
        (dict(a_max=-1.0), r"a_max must be > 0.*-1\.0"),
        (dict(a_max=0.0), r"a_max must be > 0"),
        (dict(a_min=float("-inf")), r"a_min must be a finite.*-inf"),
    ],
)
def test_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        longitudinal_feedback(0.0, 1.0, 20.0, 20.0, **kwargs)


def test_bad_inputs():
    with pytest.raises(ValueError, match=r"x_ref must be finite.*inf"):
        longitudinal_feedback(0.0, np.inf, 20.0, 20.0)
    with pytest.raises(ValueError, match=r"not broadcastable.*x\(3,\).*x_ref\(2,\)"):
        longitudinal_feedback(np.zeros(3), np.zeros(2), 20.0, 20.0)
