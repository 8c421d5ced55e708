"""Tests for icv_envs.formation.control (paper Sec. 2.2, eq. (law))."""

from __future__ import annotations

import math

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
    np.testing.assert_allclose(poles.real, [-math.sqrt(0.3)] * 2, atol=1e-6)  # critically damped double pole
    np.testing.assert_allclose(poles.imag, 0.0, atol=1e-6)
    zeta = -DEFAULT_KV / (2 * np.sqrt(-DEFAULT_KP))
    assert zeta == pytest.approx(1.0)


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
    assert a == pytest.approx(-0.3 * -2.0 + -2.0 * math.sqrt(0.3) * 1.0)


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


# ------------------------------------------------------------ join profile
def test_gains_follow_the_stated_design_rule():
    from icv_envs.formation.control import DAMPING_RATIO, DEFAULT_KP, DEFAULT_KV, FEEDBACK_ACCEL, FEEDBACK_ERROR

    wn = math.sqrt(-DEFAULT_KP)
    assert -DEFAULT_KV / (2 * wn) == pytest.approx(DAMPING_RATIO) == pytest.approx(1.0)
    assert wn ** 2 * FEEDBACK_ERROR == pytest.approx(FEEDBACK_ACCEL)


profile_st = st.tuples(st.floats(-200.0, 200.0), st.floats(-15.0, 15.0), st.floats(-1.5, 1.0))


@settings(max_examples=60, deadline=None, database=None)
@given(profile_st)
def test_join_profile_starts_at_the_member_and_ends_on_the_slot_within_limits(state):
    from icv_envs.formation.control import PROFILE_ACCEL, PROFILE_DECEL, PROFILE_JERK, join_duration, join_profile

    d0, v0, a0 = state
    T = float(join_duration(d0, v0, a0)[0])
    t = np.linspace(0.0, T, 2001)
    d, v, a = join_profile(t, T, d0, v0, a0)
    assert d[0] == pytest.approx(d0) and v[0] == pytest.approx(v0) and a[0] == pytest.approx(a0)
    assert abs(d[-1]) < 1e-6 and abs(v[-1]) < 1e-6 and abs(a[-1]) < 1e-6
    # after T the reference stays on the slot
    d2, v2, a2 = join_profile(T + 5.0, T, d0, v0, a0)
    assert abs(d2) < 1e-6 and abs(v2) < 1e-6 and abs(a2) < 1e-6
    # bounded acceleration and jerk (checked on a 10x finer grid than the planner's)
    assert a.max() <= PROFILE_ACCEL + 1e-2 and a.min() >= -PROFILE_DECEL - 1e-2
    jerk = np.diff(a) / np.diff(t)
    assert np.abs(jerk).max() <= PROFILE_JERK + 1e-2
    # consistency: v = d', a = v'
    np.testing.assert_allclose(np.diff(d) / np.diff(t), 0.5 * (v[1:] + v[:-1]), atol=1e-3 * (1 + abs(v0)))


def test_join_profile_of_a_60_m_join():
    from icv_envs.formation.control import join_duration, join_profile

    T = float(join_duration(60.0, 0.0, 0.0)[0])
    # rest-to-rest minimum-jerk move: peak acceleration 5.77 d / T^2 <= 1 m/s^2
    assert T == pytest.approx(math.sqrt(5.7735 * 60.0), rel=0.06)
    d, v, a = join_profile(np.array([0.0, T / 2, T]), T, 60.0, 0.0, 0.0)
    np.testing.assert_allclose(d, [60.0, 30.0, 0.0], atol=1e-9)


def test_a_vehicle_on_its_profile_tracks_it_exactly():
    # point mass driven by the law with the profile's acceleration fed forward
    from icv_envs.formation.control import join_duration, join_profile

    d0, v0 = -40.0, -5.0
    T = float(join_duration(d0, v0, 0.0)[0])
    x, v = 100.0 + d0, 25.0 + v0
    worst = 0.0
    for k in range(int(T / DT) + 200):
        t = k * DT
        dr, vr, ar = join_profile(t, T, d0, v0, 0.0)
        a = float(longitudinal_feedback(x, 100.0 + 25.0 * t + dr, v, 25.0 + vr, a_ref=ar, a_min=-2.0, a_max=1.5))
        worst = max(worst, abs(x - (100.0 + 25.0 * t + dr)))
        v += a * DT
        x += v * DT
    assert worst < 0.2  # forward-Euler discretisation at dt = 0.04 s
    assert abs(x - (100.0 + 25.0 * (k + 1) * DT)) < 0.05


def test_join_duration_bad_input():
    from icv_envs.formation.control import join_duration, join_profile

    with pytest.raises(ValueError, match="jerk must be"):
        join_duration(1.0, 0.0, 0.0, jerk=0.0)
    with pytest.raises(ValueError, match="d0"):
        join_duration(float("nan"), 0.0, 0.0)
    with pytest.raises(ValueError, match="duration T must be > 0"):
        join_profile(0.0, 0.0, 1.0, 0.0, 0.0)


def test_join_duration_refuses_a_nan_speed_band():
    """The band may be +-inf (no bound) or arrays of the members' shape; NaN is refused, naming it."""
    from icv_envs.formation.control import join_duration

    with pytest.raises(ValueError, match="v_hi must be numbers"):
        join_duration(10.0, 0.0, 0.0, v_hi=float("nan"))
    with pytest.raises(ValueError, match="v_lo must be numbers"):
        join_duration(np.array([10.0, 5.0]), 0.0, 0.0, v_lo=np.array([-1.0, np.nan]))
    T = join_duration(np.array([10.0, 5.0]), 0.0, 0.0, v_lo=np.array([-1.0, -np.inf]), v_hi=np.inf)
    assert T.shape == (2,) and np.all(np.isfinite(T))
