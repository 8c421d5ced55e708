"""Tests for icv_envs.formation.assignment (paper Sec. 3.3)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.formation import (
    assign_targets,
    assignment_cost,
    interlaced_targets,
    total_cost,
)

SETTINGS = settings(max_examples=60, deadline=None, database=None)


def _brute_force_min(cost: np.ndarray) -> float:
    n = cost.shape[0]
    if n == 0:
        return 0.0
    perms = np.array(list(itertools.permutations(range(n))), dtype=np.int64)
    return float(cost[np.arange(n)[None, :], perms].sum(axis=1).min())


@st.composite
def scenario(draw, max_n=7):
    n = draw(st.integers(min_value=1, max_value=max_n))
    n_l = draw(st.integers(min_value=1, max_value=5))
    ls = draw(st.floats(min_value=5.0, max_value=40.0))
    xs = st.floats(min_value=-50.0, max_value=300.0, allow_nan=False, allow_infinity=False)
    veh_x = np.array(draw(st.lists(xs, min_size=n, max_size=n)))
    veh_lane = np.array(draw(st.lists(st.integers(1, n_l), min_size=n, max_size=n)))
    tgt_x, tgt_lane = interlaced_targets(n, n_l, ls)
    return veh_x, veh_lane, tgt_x, tgt_lane


def test_cost_matrix_formula():
    vx, vy = np.array([0.0, 10.0]), np.array([1, 3])
    gx, gy = np.array([0.0, 20.0, 20.0]), np.array([1, 2, 4])
    c = assignment_cost(vx, vy, gx, gy, w1=1.0, w2=10.0)
    assert c.shape == (2, 3)
    expected = np.array(
        [[0.0, 400.0 + 10.0, 400.0 + 90.0],
         [100.0 + 40.0, 100.0 + 10.0, 100.0 + 10.0]]
    )
    np.testing.assert_allclose(c, expected)
    np.testing.assert_allclose(assignment_cost(vx, vy, gx, gy, w1=2.0, w2=0.0),
                               2.0 * (gx[None] - vx[:, None]) ** 2)


@SETTINGS
@given(sc=scenario(), w1=st.floats(0.0, 5.0), w2=st.floats(0.0, 50.0))
def test_matches_brute_force(sc, w1, w2):
    veh_x, veh_lane, tgt_x, tgt_lane = sc
    a = assign_targets(veh_x, veh_lane, tgt_x, tgt_lane, w1, w2)
    n = len(veh_x)
    assert a.dtype == np.int64 and a.shape == (n,)
    assert sorted(a.tolist()) == list(range(n))  # a permutation
    cost = assignment_cost(veh_x, veh_lane, tgt_x, tgt_lane, w1, w2)
    best = _brute_force_min(cost)
    assert total_cost(cost, a) == pytest.approx(best, rel=1e-9, abs=1e-9)


@SETTINGS
@given(sc=scenario())
def test_deterministic(sc):
    a1 = assign_targets(*sc)
    a2 = assign_targets(*(np.array(v, copy=True) for v in sc))
    np.testing.assert_array_equal(a1, a2)


@SETTINGS
@given(sc=scenario())
def test_huge_lane_weight_minimises_lane_changes(sc):
    veh_x, veh_lane, tgt_x, tgt_lane = sc
    # With x spread <= 350 m and N <= 7 the longitudinal part is < 1e6 in total,
    # and the lateral part takes integer values, so w2 = 1e7 makes it dominant.
    a = assign_targets(veh_x, veh_lane, tgt_x, tgt_lane, w1=1.0, w2=1e7)
    lateral = assignment_cost(veh_x, veh_lane, tgt_x, tgt_lane, w1=0.0, w2=1.0)
    assert total_cost(lateral, a) == pytest.approx(_brute_force_min(lateral), abs=1e-9)


def test_lane_weight_changes_preference():
    # Two vehicles side by side; targets: one in each lane, but staggered.
    veh_x, veh_lane = np.array([0.0, 20.0]), np.array([2, 1])
    tgt_x, tgt_lane = np.array([0.0, 20.0]), np.array([1, 2])
    # lanes dominate -> keep lanes (vehicle 0 -> target 1 in lane 2)
    np.testing.assert_array_equal(
        assign_targets(veh_x, veh_lane, tgt_x, tgt_lane, w1=0.0, w2=1.0), [1, 0])
    # distance dominates -> keep longitudinal positions
    np.testing.assert_array_equal(
        assign_targets(veh_x, veh_lane, tgt_x, tgt_lane, w1=1.0, w2=0.0), [0, 1])


def test_empty():
    a = assign_targets([], [], [], [])
    assert a.shape == (0,) and a.dtype == np.int64
    assert total_cost(np.zeros((0, 0)), a) == 0.0


def test_identity_when_vehicles_on_targets():
    tx, tl = interlaced_targets(20, 4, 20.0)
    rng = np.random.default_rng(0)
    perm = rng.permutation(20)
    a = assign_targets(tx[perm], tl[perm], tx, tl)
    np.testing.assert_array_equal(a, perm)


def test_total_cost():
    c = np.array([[1.0, 2.0], [3.0, 4.0]])
    assert total_cost(c, np.array([1, 0])) == 5.0
    with pytest.raises(ValueError, match="shape"):
        total_cost(c, np.array([0]))
    with pytest.raises(ValueError, match="0..1"):
        total_cost(c, np.array([0, 2]))
    with pytest.raises(ValueError, match="integer"):
        total_cost(c, np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match="2-D"):
        total_cost(np.ones(3), np.array([0, 1, 2]))


@pytest.mark.parametrize(
    "args, match",
    [
        (([0.0, 1.0], [1, 2], [0.0], [1]), r"2 vehicles and 1 targets"),
        (([0.0, 1.0], [1], [0.0, 1.0], [1, 2]), r"veh_x and veh_lane.*\(2,\).*\(1,\)"),
        (([0.0, 1.0], [1, 2], [0.0, 1.0], [1]), r"tgt_x and tgt_lane"),
        (([[0.0, 1.0]], [[1, 2]], [0.0, 1.0], [1, 2]), r"veh_x must be 1-D"),
        (([0.0, np.nan], [1, 2], [0.0, 1.0], [1, 2]), r"veh_x must be finite.*nan"),
        (([0.0, 1.0], [1, 2], [0.0, np.inf], [1, 2]), r"tgt_x must be finite.*inf"),
        ((["a", "b"], [1, 2], [0.0, 1.0], [1, 2]), r"veh_x"),
    ],
)
def test_bad_shapes_and_values(args, match):
    with pytest.raises(ValueError, match=match):
        assign_targets(*args)


@pytest.mark.parametrize(
    "w1, w2, match",
    [(-1.0, 10.0, r"w1.*-1\.0"), (1.0, -0.5, r"w2.*-0\.5"),
     (float("nan"), 1.0, r"w1.*nan"), (1.0, float("inf"), r"w2.*inf"),
     ("1", 1.0, r"w1.*'1'")],
)
def test_bad_weights(w1, w2, match):
    with pytest.raises(ValueError, match=match):
        assignment_cost([0.0], [1], [0.0], [1], w1=w1, w2=w2)
    with pytest.raises(ValueError, match=match):
        assign_targets([0.0], [1], [0.0], [1], w1=w1, w2=w2)
