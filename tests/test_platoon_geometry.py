"""Tests for icv_envs.platoon.geometry (paper Sec. 4, docs/intersection.md#geometry)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.platoon import (
    LANE_USE_PRESETS,
    LEGS,
    MOVEMENTS,
    TURNS,
    approach_centerline,
    approach_heading,
    departure_centerline,
    departure_lane,
    exit_heading,
    exit_leg,
    lane_path,
    lane_use_table,
    movement_id,
    path_headings,
    path_length,
)

SETTINGS = settings(max_examples=60, deadline=None, database=None)
W, B = 4.0, 12.0


def _ang(a, b):
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def test_numbering():
    assert len(MOVEMENTS) == 12
    for m, (leg, turn) in enumerate(MOVEMENTS):
        assert movement_id(leg, turn) == m == 3 * LEGS.index(leg) + TURNS.index(turn)
        assert movement_id(LEGS.index(leg), TURNS.index(turn)) == m
    assert MOVEMENTS[0] == ("N", "left") and MOVEMENTS[11] == ("W", "right")
    assert [exit_leg("N", t) for t in TURNS] == ["E", "S", "W"]
    assert [exit_leg("E", t) for t in TURNS] == ["S", "W", "N"]
    assert [exit_leg("S", t) for t in TURNS] == ["W", "N", "E"]
    assert [exit_leg("W", t) for t in TURNS] == ["N", "E", "S"]


def test_headings():
    assert math.isclose(approach_heading("N"), -math.pi / 2)
    assert math.isclose(approach_heading("W"), 0.0)
    assert math.isclose(exit_heading("E"), 0.0)
    assert math.isclose(exit_heading("S"), -math.pi / 2)


def test_right_hand_traffic_lane_positions():
    # N approach lanes west of the centre line, lane 0 next to it
    p = approach_centerline("N", [0, 1, 2][0], 0.0)
    assert np.allclose(p, [-2.0, 12.0])
    assert np.allclose(approach_centerline("N", 2, 0.0), [-10.0, 12.0])
    assert np.allclose(approach_centerline("N", 1, [0.0, 10.0]), [[-6.0, 12.0], [-6.0, 22.0]])
    assert np.allclose(approach_centerline("E", 0, 5.0), [17.0, 2.0])
    assert np.allclose(approach_centerline("S", 2, 0.0), [10.0, -12.0])
    assert np.allclose(approach_centerline("W", 1, 0.0), [-12.0, -6.0])
    assert np.allclose(departure_centerline("N", 0, 3.0), [2.0, 15.0])
    assert np.allclose(departure_centerline("W", 2, 0.0), [-12.0, 10.0])


@given(m=st.integers(0, 11), lane=st.integers(0, 2), rule=st.sampled_from(["same", "kerb"]),
       w=st.floats(2.5, 5.0), extra=st.floats(0.0, 6.0))
@SETTINGS
def test_paths_start_end_and_headings(m, lane, rule, w, extra):
    b = 3 * w + extra
    leg, turn = MOVEMENTS[m]
    p = lane_path(m, lane, w, b, rule=rule)
    assert p.ndim == 2 and p.shape[1] == 2
    # start on the stop line of the approach lane, end on the exit edge of the departure lane
    assert np.allclose(p[0], approach_centerline(leg, lane, 0.0, w, b))
    j = departure_lane(m, lane, rule)
    assert np.allclose(p[-1], departure_centerline(exit_leg(leg, turn), j, 0.0, w, b))
    assert np.isclose(np.max(np.abs(p[0])), b) and np.isclose(np.max(np.abs(p[-1])), b)
    # stays inside the box
    assert np.all(np.abs(p) <= b + 1e-9)
    # tangent headings at both ends (chords of the arc: within half a chord angle)
    h = path_headings(p)
    assert _ang(h[0], approach_heading(leg)) < 0.05
    assert _ang(h[-1], exit_heading(exit_leg(leg, turn))) < 0.05
    # turns by -90 (right), 0 (straight), +90 (left) degrees overall (minus one chord angle)
    total = np.sum(np.angle(np.exp(1j * np.diff(h))))
    assert math.isclose(total, {"left": math.pi / 2, "straight": 0.0, "right": -math.pi / 2}[turn], abs_tol=0.05)
    # length between chord and the two legs of the corner
    L = path_length(p)
    chord = np.linalg.norm(p[-1] - p[0])
    assert chord - 1e-9 <= L
    if turn == "straight":
        assert math.isclose(L, 2 * b)
    else:
        corner_len = abs(np.dot(p[-1] - p[0], [math.cos(h[0]), math.sin(h[0])])) + \
            abs(np.dot(p[-1] - p[0], [-math.sin(h[0]), math.cos(h[0])]))
        assert L <= corner_len + 1e-6


def test_quarter_circle_lengths_default_rule():
    for lane in range(3):
        r_right = B - (lane + 0.5) * W
        r_left = B + (lane + 0.5) * W
        assert math.isclose(path_length(lane_path(("N", "right"), lane)), math.pi / 2 * r_right, rel_tol=1e-3)
        assert math.isclose(path_length(lane_path(("S", "left"), lane)), math.pi / 2 * r_left, rel_tol=1e-3)
        assert math.isclose(path_length(lane_path(("E", "straight"), lane)), 2 * B)
    # right turns tight, left turns wide
    assert path_length(lane_path(2, 2)) < path_length(lane_path(2, 1)) < path_length(lane_path(0, 0))
    # arc points equidistant from the box corner (exact quarter circle)
    p = lane_path(("N", "right"), 1)
    assert np.allclose(np.linalg.norm(p - [-B, B], axis=1), B - 1.5 * W)


def test_departure_lane_rules():
    assert [departure_lane(0, a) for a in range(3)] == [0, 1, 2]
    assert [departure_lane(2, a, "kerb") for a in range(3)] == [2, 2, 2]
    assert [departure_lane(0, a, "kerb") for a in range(3)] == [0, 0, 0]
    assert [departure_lane(1, a, "kerb") for a in range(3)] == [0, 1, 2]
    with pytest.raises(ValueError, match="'zigzag'"):
        departure_lane(0, 0, "zigzag")


def test_lane_use_presets():
    t = lane_use_table("paper")
    assert set(t) == set(range(12))
    for leg in LEGS:
        assert t[movement_id(leg, "left")] == (0,)
        assert t[movement_id(leg, "straight")] == (1,)
        assert t[movement_id(leg, "right")] == (1, 2)
    e = lane_use_table("exclusive")
    assert all(e[m] == (m % 3,) for m in range(12))
    assert set(LANE_USE_PRESETS) == {"paper", "exclusive"}


def test_lane_use_custom_keys():
    t = lane_use_table({"left": 0, "straight": [1, 0], "right": (2,), ("N", "right"): (1, 2), 7: [2]})
    assert t[0] == (0,) and t[1] == (0, 1) and t[2] == (1, 2) and t[5] == (2,) and t[7] == (2,)


def test_lane_use_errors():
    with pytest.raises(ValueError, match="'fancy'.*paper, exclusive"):
        lane_use_table("fancy")
    with pytest.raises(ValueError, match=r"movement 4 \(E-straight\)"):
        lane_use_table({"left": 0, "right": 2, ("N", "straight"): 1, ("S", "straight"): 1, ("W", "straight"): 1})
    with pytest.raises(ValueError, match=r"movement 1 \(N-straight\)"):
        lane_use_table({"left": 0, "straight": 1, "right": 2, 1: ()})
    with pytest.raises(ValueError, match="got 3"):
        lane_use_table({"left": 0, "straight": 1, "right": 3})
    with pytest.raises(ValueError, match="got -1"):
        lane_use_table({"left": -1, "straight": 1, "right": 2})
    with pytest.raises(ValueError, match="'sideways'"):
        lane_use_table({"left": 0, "straight": 1, "right": 2, "sideways": 1})
    with pytest.raises(ValueError, match="12"):
        lane_use_table({"left": 0, "straight": 1, "right": 2, 12: 1})


def test_bad_inputs():
    with pytest.raises(ValueError, match="'Q'"):
        movement_id("Q", "left")
    with pytest.raises(ValueError, match="'u-turn'"):
        exit_leg("N", "u-turn")
    with pytest.raises(ValueError, match="got 3"):
        lane_path(0, 3)
    with pytest.raises(ValueError, match="box_half"):
        lane_path(0, 0, lane_width=4.0, box_half=10.0)
    with pytest.raises(ValueError, match="n_points"):
        lane_path(0, 0, n_points=1)
    with pytest.raises(ValueError, match="lane_width"):
        approach_centerline("N", 0, 1.0, lane_width=-4.0)
    with pytest.raises(ValueError, match="distance"):
        approach_centerline("N", 0, float("nan"))
