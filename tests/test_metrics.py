"""Tests for the run metrics (icv_envs.sim.metrics) and their accumulation in
icv_envs.sim.world.World."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.sim.formations import FormationManager
from icv_envs.sim.metrics import (
    HEADWAY_BIN,
    MOTION_KEYS,
    STOPPED_SPEED,
    HeadwayStats,
    MotionStats,
    run_metrics,
)
from icv_envs.sim.road import RoadLayout
from icv_envs.sim.world import StepEvents, World

FEW = settings(max_examples=60, deadline=None, database=None)


def world_with(speeds, xs=None, v_max=30.0, lanes=None):
    road = RoadLayout(2, 2000.0, 4.0, np.full(2, np.inf), [], [], [], periodic=False)
    w = World(road, FormationManager(), dt=0.04, v_max=v_max)
    speeds = np.asarray(speeds, dtype=float)
    xs = np.arange(len(speeds)) * 50.0 + 100.0 if xs is None else np.asarray(xs, dtype=float)
    ys = np.zeros(len(speeds)) if lanes is None else np.asarray(lanes, dtype=float) * 4.0
    w.traffic.add(xs, ys, speeds)
    return w


def drive(w, accel, steps):
    ev = StepEvents()
    for _ in range(steps):
        w.substep(np.full(w.traffic.n, accel, dtype=float), np.zeros(w.traffic.n), ev)
        w.record_min_gap()


def test_vehicle_held_at_zero_with_braking_has_zero_realised_fluctuation():
    w = world_with([0.0])
    drive(w, -6.0, 100)
    m = run_metrics(w)
    assert m["speed_fluctuation"] == 0.0
    assert m["commanded_abs_accel"] == pytest.approx(6.0)
    assert m["stopped_share"] == 1.0
    assert m["mean_speed"] == 0.0
    assert m["speed_std"] == 0.0


def test_vehicle_at_v_max_commanded_to_accelerate_has_zero_realised_fluctuation():
    w = world_with([30.0], v_max=30.0)
    drive(w, 3.0, 50)
    m = run_metrics(w)
    assert m["speed_fluctuation"] == 0.0
    assert m["commanded_abs_accel"] == pytest.approx(3.0)
    assert m["stopped_share"] == 0.0


def test_braking_to_a_stop_counts_only_the_realised_deceleration():
    # 10 m/s, braking at 5 m/s^2 for 4 s (100 steps): stops after 2 s
    w = world_with([10.0])
    drive(w, -5.0, 100)
    m = run_metrics(w)
    # realised |dv/dt| sums to 10 m/s / dt over the 100 steps
    assert m["speed_fluctuation"] == pytest.approx(10.0 / 0.04 / 100)
    assert m["commanded_abs_accel"] == pytest.approx(5.0)
    assert m["stopped_share"] == pytest.approx(0.5, abs=0.02)


@FEW
@given(st.floats(0.0, 30.0), st.floats(-6.0, 3.0), st.integers(1, 60))
def test_realised_fluctuation_never_exceeds_commanded(v0, a, steps):
    w = world_with([v0])
    drive(w, a, steps)
    m = run_metrics(w)
    assert m["speed_fluctuation"] <= m["commanded_abs_accel"] + 1e-9
    assert 0.0 <= m["stopped_share"] <= 1.0
    # a constant command drives the speed monotonically: |dv| sums to |v_end - v0|
    assert m["speed_fluctuation"] * steps * 0.04 == pytest.approx(abs(w.traffic.speed[0] - v0), abs=1e-9)


def test_per_vehicle_speed_std():
    ms = MotionStats()
    # vehicle 0 alternates 10/20 m/s (std 5), vehicle 3 constant (std 0)
    for k in range(10):
        v = 10.0 if k % 2 == 0 else 20.0
        ms.record([0, 3], [v, 7.0], [v, 7.0], [0.0, 0.0], 0.04)
    assert ms.per_vehicle_std() == pytest.approx([5.0, 0.0])
    assert ms.summary()["speed_std"] == pytest.approx(2.5)
    assert set(MOTION_KEYS) <= set(ms.summary())


def test_motion_stats_bad_input():
    ms = MotionStats()
    with pytest.raises(ValueError, match="dt must be > 0"):
        ms.record([0], [1.0], [1.0], [0.0], 0.0)
    with pytest.raises(ValueError, match="ids must be >= 0"):
        ms.record([-1], [1.0], [1.0], [0.0], 0.04)


def test_headways_hand_built_platoon():
    # three vehicles in one lane, 5 m bodies, centres 20 m apart: gaps 15 m;
    # the follower's speeds 10 and 15 m/s -> time headways 1.5 and 1.0 s
    w = world_with([15.0, 10.0, 20.0], xs=[100.0, 120.0, 140.0])
    w.record_min_gap()
    m = run_metrics(w)
    assert m["min_gap"] == pytest.approx(15.0)
    assert m["min_time_headway"] == pytest.approx(1.0)
    assert m["time_headway_p05"] == pytest.approx(1.0, abs=HEADWAY_BIN)


def test_headway_of_standing_vehicles_is_excluded_but_gap_counts():
    h = HeadwayStats()
    h.record([3.0, np.inf], [0.0, 20.0])
    s = h.summary()
    assert s["min_gap"] == 3.0
    assert s["min_time_headway"] is None and s["time_headway_p05"] is None
    h.record([20.0], [STOPPED_SPEED * 200])
    assert h.summary()["min_time_headway"] == pytest.approx(1.0)


@FEW
@given(st.lists(st.floats(0.05, 15.0), min_size=1, max_size=200))
def test_headway_percentile_matches_numpy_within_a_bin(ths):
    h = HeadwayStats()
    th = np.asarray(ths)
    h.record(th * 10.0, np.full(len(th), 10.0))
    for q in (5.0, 50.0, 100.0):
        exact = np.percentile(th, q, method="inverted_cdf")
        assert exact - HEADWAY_BIN - 1e-9 <= h.percentile(q) <= exact + 1e-9
    assert h.summary()["min_time_headway"] == pytest.approx(th.min())
    with pytest.raises(ValueError, match="percentile"):
        h.percentile(101)


def test_env_metrics_report_the_shared_keys():
    from icv_envs.envs.highway_ramps_v0 import parallel_env

    env = parallel_env(method="formation", vgr=0.3, duration=20.0)
    env.reset(seed=0)
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    m = env.metrics()
    for k in MOTION_KEYS + ("min_gap", "min_time_headway", "time_headway_p05"):
        assert k in m, k
    assert 0 <= m["speed_fluctuation"] <= m["commanded_abs_accel"] + 1e-9
    assert math.isfinite(m["speed_std"])


class _PlainHeadways(HeadwayStats):
    """A HeadwayStats the one-call path of World.record_min_gap does not
    take (it takes the class itself only): the separate calls."""


@FEW
@given(n=st.integers(2, 40), periodic=st.booleans(), lanes=st.integers(1, 4), seed=st.integers(0, 2**31))
def test_record_min_gap_one_call_equals_the_separate_calls(n, periodic, lanes, seed):
    """Stop 43: ``record_min_gap`` builds the lane index, the own-lane gaps
    and the headway record in one compiled call (``lane_gap_pass``) when
    nothing was built for the state yet and nobody holds a lane. Against
    the separate calls on the same states: the same index, gaps, leaders,
    headway statistics and histogram, over several steps (vehicles dense
    enough to overlap lanes, touch, stand)."""
    rng = np.random.default_rng(seed)
    length = 600.0
    road = RoadLayout(lanes, length, 4.0, np.full(lanes, np.inf), [], [], [], periodic=periodic)
    worlds = []
    for plain in (False, True):
        w = World(road, FormationManager(), dt=0.04, v_max=30.0)
        if plain:
            w.headways = _PlainHeadways()
        r = np.random.default_rng(seed)
        w.traffic.add(r.uniform(0.0, length - 50.0, n), r.integers(0, lanes, n) * 4.0 + r.normal(0, 0.8, n),
                      np.where(r.random(n) < 0.3, 0.0, r.uniform(0.0, 30.0, n)), heading=r.normal(0, 0.05, n))
        worlds.append(w)
    fused, plain = worlds
    accel = rng.uniform(-3.0, 2.0, n)
    for _ in range(3):
        for w in worlds:
            w.substep(accel, np.zeros(n), StepEvents())
            w.record_min_gap()
        a, b = fused.lane_index(reserved=False), plain.lane_index(reserved=False)
        for f in ("keys", "rows", "lanes", "x"):
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
        assert a.offset == b.offset
        assert fused.lane_index(reserved=True) is a  # (nobody holds a lane: one index for both views)
        for g, p in zip(fused.own_lane_gaps(), plain.own_lane_gaps()):
            np.testing.assert_array_equal(g, p)
        hf, hp = fused.headways, plain.headways
        assert (hf.min_gap, hf.min_time_headway, hf.samples) == (hp.min_gap, hp.min_time_headway, hp.samples)
        np.testing.assert_array_equal(hf._hist, hp._hist)


def test_record_min_gap_takes_the_one_call_path(monkeypatch):
    """The one-call path is the one taken on a state nothing was built for
    (and not when the index exists already, or someone holds a lane)."""
    import icv_envs.sim.world as world_mod

    calls = []
    real = world_mod.lane_gap_pass
    monkeypatch.setattr(world_mod, "lane_gap_pass", lambda *a: calls.append(1) or real(*a))
    w = world_with([15.0, 10.0, 20.0], xs=[100.0, 120.0, 140.0])
    w.record_min_gap()
    assert calls == [1]
    w.record_min_gap()  # the index of this state exists: the separate path (the kept gaps)
    assert calls == [1]
    assert run_metrics(w)["min_gap"] == pytest.approx(15.0)
    w.invalidate()
    w.traffic.lc_lane = np.array([1, -1, -1])  # a lane change under way holds lane 1
    held = []
    real_held = world_mod.World._held_lanes
    monkeypatch.setattr(world_mod.World, "_held_lanes", lambda self: held.append(1) or real_held(self))
    w.record_min_gap()
    assert calls == [1]
    assert held == [1]  # (the reservations asked once: the index is built from them, from stop 44)
    assert w.lane_index(reserved=True) is not w.lane_index(reserved=False)  # (the held view and the body's)
