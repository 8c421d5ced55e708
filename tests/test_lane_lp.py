"""Tests for the LP lane assignment (icv_envs.policies.lane_lp, Dao et al. 2007)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.policies.lane_lp import lane_changes_needed, optimal_lane_shares

TABLE1 = [25.0, 25.0, 25.0, 20.0]  # paper Table 1: left three lanes 25 m/s, fourth 20 m/s


def test_hand_solved_instance_capacity_binds():
    # Two lanes: fast (25 m/s, holds 10 vehicles) and slow (20 m/s, 100).
    # Group A: 6 vehicles going 2000 m, group B: 8 vehicles going 4000 m.
    # On the fast lane a vehicle saves D (1/20 - 1/25) = D / 100 s: 20 s for
    # A, 40 s for B. Capacity 10 binds: B (8) goes fast entirely, the
    # remaining 2 fast places go to A (share 1/3), A's other 4 drive slow.
    # Travel time = 8*4000/25 + 2*2000/25 + 4*2000/20 = 1280 + 160 + 400 s.
    p, info = optimal_lane_shares([6, 8], [2000.0, 4000.0], [25.0, 20.0], [10.0, 100.0], 0.0, return_info=True)
    np.testing.assert_allclose(p, [[1 / 3, 2 / 3], [1.0, 0.0]], atol=1e-9)
    np.testing.assert_allclose(info["load"], [10.0, 4.0], atol=1e-6)
    assert info["travel_time"] == pytest.approx(1840.0)
    np.testing.assert_allclose(info["excess"], 0.0, atol=1e-9)


def test_light_traffic_is_spread_over_the_equal_lanes_not_put_on_one():
    # light load (far below capacity) on the paper's four lanes: the three
    # 25 m/s lanes are equally good; each group is split evenly over them
    # (to the tie-break's resolution 1/K) and the slower fourth lane is empty
    counts, dist = [3, 2, 4, 1, 5], [1500.0, 3500.0, 5500.0, 7500.0, 9500.0]
    p = optimal_lane_shares(counts, dist, TABLE1, [60.0] * 4, 100.0)
    np.testing.assert_allclose(p[:, :3], 1 / 3, atol=1 / 50 + 1e-9)
    np.testing.assert_allclose(p[:, 3], 0.0, atol=1e-9)
    load = np.asarray(counts) @ p
    assert load.max() - load[:3].min() <= 15 * (1 / 50) + 1e-9


def test_full_fast_lanes_overflow_to_the_slow_lane_shortest_trips_first():
    # 3 fast lanes of capacity 10 and 40 vehicles: 10 must use the slow lane,
    # and they are the ones with the shortest trip
    p, info = optimal_lane_shares([10, 30], [1500.0, 8000.0], TABLE1, [10.0] * 4, 0.0, return_info=True)
    np.testing.assert_allclose(p[0], [0, 0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(p[1, :3], 1 / 3, atol=1e-9)
    np.testing.assert_allclose(info["load"], [10, 10, 10, 10], atol=1e-6)


def test_demand_over_total_capacity_uses_the_elastic_slack():
    p, info = optimal_lane_shares([50], [3000.0], TABLE1, [10.0] * 4, 0.0, return_info=True)
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    assert info["excess"].sum() == pytest.approx(10.0)


def test_reachability_depends_on_distance_and_lane_changes():
    # 4 lanes: from lane l a ramp vehicle makes (3 - l) + (4 - l) lane changes
    np.testing.assert_array_equal(lane_changes_needed(4), [7, 5, 3, 1])
    # 400 m with 100 m per lane change: lanes needing <= 4 changes -> lanes 2, 3
    p = optimal_lane_shares([5, 5], [400.0, 5000.0], TABLE1, [60.0] * 4, 100.0)
    np.testing.assert_allclose(p[0, :2], 0.0, atol=1e-12)
    assert p[0, 2] == pytest.approx(1.0)  # lane 2 is fast and reachable
    np.testing.assert_allclose(p[1, :3], 1 / 3, atol=1 / 50 + 1e-9)
    # nothing reachable but the rightmost lane
    p = optimal_lane_shares([1], [50.0], TABLE1, [60.0] * 4, 100.0)
    np.testing.assert_allclose(p, [[0, 0, 0, 1]], atol=1e-12)


@settings(max_examples=40, deadline=None, database=None)
@given(st.lists(st.tuples(st.integers(0, 40), st.floats(0.0, 10000.0)), min_size=1, max_size=6),
       st.lists(st.floats(5.0, 80.0), min_size=4, max_size=4))
def test_shares_are_distributions_within_capacity_when_it_suffices(groups, caps):
    counts = [g[0] for g in groups]
    dist = [g[1] for g in groups]
    p, info = optimal_lane_shares(counts, dist, TABLE1, caps, 100.0, return_info=True)
    assert p.shape == (len(groups), 4)
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    assert (p >= -1e-12).all()
    if sum(counts) <= sum(caps) and all(d >= 700.0 for d in dist):
        assert info["excess"].sum() == pytest.approx(0.0, abs=1e-6)


def test_deterministic():
    args = ([3, 7, 2], [2000.0, 4000.0, 6000.0], TABLE1, [30.0] * 4)
    np.testing.assert_array_equal(optimal_lane_shares(*args), optimal_lane_shares(*args))


def test_bad_input():
    with pytest.raises(ValueError, match="counts must be >= 0"):
        optimal_lane_shares([-1], [100.0], [25.0], [10.0])
    with pytest.raises(ValueError, match="same shape"):
        optimal_lane_shares([1, 2], [100.0], [25.0], [10.0])
    with pytest.raises(ValueError, match="distances must be >= 0"):
        optimal_lane_shares([1], [-5.0], [25.0], [10.0])
    with pytest.raises(ValueError, match="pieces must be an integer"):
        optimal_lane_shares([1], [5.0], [25.0], [10.0], pieces=0)
    with pytest.raises(ValueError, match="excess_cost must be"):
        optimal_lane_shares([1], [5.0], [25.0], [10.0], excess_cost=0.0)
    with pytest.raises(ValueError, match="lane_change_distance must be"):
        optimal_lane_shares([1], [5.0], [25.0], [10.0], lane_change_distance=float("nan"))


def test_lane_lp_policy_spreads_light_traffic_over_the_lanes():
    # light load on the paper's ring: the vehicles the LP assigns at the ramps
    # are spread over the three 25 m/s lanes, none carries most of them
    from icv_envs.envs.highway_ramps_v0 import parallel_env

    env = parallel_env(method="lane-lp", vgr=0.1, duration=150.0)
    env.reset(seed=3)
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    lanes = np.bincount(list(env.core.expert.assigned.values()), minlength=4)
    assert lanes.sum() >= 20
    assert lanes.max() <= 0.6 * lanes.sum(), lanes
    assert (lanes[:3] > 0).all(), lanes
    assert env.metrics()["collisions"] == 0
