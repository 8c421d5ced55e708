"""Tests for icv_envs.platoon.conflicts (paper Sec. 4.2, docs/intersection.md#conflicts)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.platoon import (
    CONFLICT_KINDS,
    LANE_USE_PRESETS,
    OPPOSING_LEFT_PAIRS,
    conflict_model,
    conflicts_report,
    format_matrix,
    lane_path,
    movement_id,
    polyline_intersections,
    required_layer_gap,
)

SETTINGS = settings(max_examples=25, deadline=None, database=None)


def mid(leg, turn):
    return movement_id(leg, turn)


@pytest.fixture(scope="module")
def paper():
    return conflict_model("paper")


@pytest.fixture(scope="module")
def exclusive():
    return conflict_model("exclusive")


lanes_st = st.lists(st.integers(0, 2), min_size=1, max_size=3, unique=True)
table_st = st.fixed_dictionaries({"left": lanes_st, "straight": lanes_st, "right": lanes_st})


@pytest.mark.parametrize("name", list(LANE_USE_PRESETS))
@pytest.mark.parametrize("switch", [False, True])
def test_structure(name, switch):
    m = conflict_model(name, switch)
    assert m.matrix.shape == (12, 12) and m.matrix.dtype == bool
    assert np.array_equal(m.matrix, m.matrix.T)
    assert m.matrix.diagonal().all()
    for i in range(12):
        assert m.kinds[i, i] == {"self"}
        for j in range(12):
            assert m.kinds[i, j] == m.kinds[j, i]
            assert m.matrix[i, j] == bool(m.kinds[i, j])
            assert m.kinds[i, j] <= set(CONFLICT_KINDS)


@given(table=table_st, switch=st.booleans())
@SETTINGS
def test_structure_random_tables(table, switch):
    m = conflict_model(table, switch)
    assert np.array_equal(m.matrix, m.matrix.T) and m.matrix.diagonal().all()
    # rotational symmetry: the same table on every leg gives a matrix invariant under leg + 1
    perm = (np.arange(12) + 3) % 12
    assert np.array_equal(m.matrix[np.ix_(perm, perm)], m.matrix)
    for i, j in OPPOSING_LEFT_PAIRS:
        if not switch:
            assert not m.matrix[i, j]
            assert ((i, j) in m.crossings) == ((i, j) in m.waived)
        else:
            assert not m.waived
            assert m.matrix[i, j] == ((i, j) in m.crossings)
    # diverging iff same leg and shared lane; converging iff same exit and shared departure lane
    for i in range(12):
        for j in range(12):
            if i == j or (not switch and {i, j} in [set(p) for p in OPPOSING_LEFT_PAIRS]):
                continue
            shared = set(m.lane_use[i]) & set(m.lane_use[j])
            assert ("diverging" in m.kinds[i, j]) == (i // 3 == j // 3 and bool(shared))


def test_opposing_left_turns(paper):
    for i, j in OPPOSING_LEFT_PAIRS:
        assert not paper.matrix[i, j]
    # with the presets the two wide arcs never meet: the switch changes nothing
    for name in LANE_USE_PRESETS:
        on = conflict_model(name, opposing_left_conflict=True)
        off = conflict_model(name)
        assert np.array_equal(on.matrix, off.matrix)
        assert not on.matrix[0, 6] and not on.matrix[3, 9]
        assert off.waived == {}
    # left turns allowed from lane 1 too: the lane-1 arcs cross, and only the switch keeps it
    table = {"left": (0, 1), "straight": (1,), "right": (2,)}
    on = conflict_model(table, opposing_left_conflict=True)
    off = conflict_model(table)
    for i, j in OPPOSING_LEFT_PAIRS:
        assert on.matrix[i, j] and on.kinds[i, j] == {"crossing"}
        assert not off.matrix[i, j] and off.kinds[i, j] == frozenset()
        assert off.waived[(i, j)] == {"crossing"}
    diff = on.matrix != off.matrix
    assert {tuple(sorted(p)) for p in zip(*np.nonzero(diff))} == set(OPPOSING_LEFT_PAIRS)


def test_same_leg_paper(paper):
    for leg in "NESW":
        L, S, R = mid(leg, "left"), mid(leg, "straight"), mid(leg, "right")
        assert not paper.matrix[L, S]  # different lanes, paths do not cross
        assert not paper.matrix[L, R]
        assert paper.matrix[S, R] and "diverging" in paper.kinds[S, R]  # shared middle lane


def test_same_leg_exclusive(exclusive):
    for leg in "NESW":
        ids = [mid(leg, t) for t in ("left", "straight", "right")]
        for a in ids:
            for b in ids:
                if a != b:
                    assert "diverging" not in exclusive.kinds[a, b]
                    assert not exclusive.matrix[a, b]


def test_converging(paper, exclusive):
    # N-right from lane 1 and E-straight (lane 1) both end in W departure lane 1
    nr, es = mid("N", "right"), mid("E", "straight")
    assert paper.kinds[nr, es] == {"converging"}
    # exclusive: N-right only from lane 2 -> W departure lane 2, E-straight -> lane 1: no conflict
    assert not exclusive.matrix[nr, es]
    # under the kerb rule right turns all end in lane 2: no longer converging with straight
    assert not conflict_model("paper", rule="kerb").matrix[nr, es]
    # left turns (lane 0 -> departure 0) and straight (lane 1 -> 1) into the same leg do not converge
    assert "converging" not in paper.kinds[mid("W", "left"), mid("S", "straight")]


@pytest.mark.parametrize("a,b,expected", [
    (("N", "straight"), ("E", "straight"), True),
    (("N", "straight"), ("W", "straight"), True),
    (("N", "straight"), ("S", "straight"), False),
    (("N", "right"), ("S", "right"), False),
    (("N", "right"), ("E", "right"), False),
    (("N", "left"), ("E", "straight"), True),
    (("N", "left"), ("S", "straight"), True),
    (("N", "left"), ("W", "straight"), False),
    (("N", "left"), ("E", "left"), True),
    (("N", "left"), ("W", "left"), True),
    (("N", "straight"), ("E", "left"), False),
    (("N", "straight"), ("S", "left"), True),
    (("N", "right"), ("E", "straight"), False),
])
def test_crossing_entries(paper, a, b, expected):
    i, j = mid(*a), mid(*b)
    assert ("crossing" in paper.kinds[i, j]) == expected
    if expected:
        pts = paper.crossings[(min(i, j), max(i, j))]
        assert np.all(np.abs(pts[:, :2]) < 12.0)


def test_crossing_point_location(paper):
    pts = paper.crossings[(mid("N", "straight"), mid("E", "straight"))]
    assert np.allclose(pts[:, :2], [-6.0, 6.0])
    assert np.allclose(pts[:, 2:4], [6.0, 18.0])  # arc lengths along N-straight and E-straight


def test_exclusive_differs_from_paper(paper, exclusive):
    diff = paper.matrix != exclusive.matrix
    pairs = {tuple(sorted(p)) for p in zip(*np.nonzero(diff))}
    assert pairs  # they differ ...
    # ... exactly where the right turn's extra lane 1 matters: diverging with the same leg's
    # straight and converging with the straight movement into the same exit
    for i, j in pairs:
        assert 2 in (i % 3, j % 3)
        assert paper.matrix[i, j] and not exclusive.matrix[i, j]
        assert paper.kinds[i, j] <= {"diverging", "converging"}
    assert (mid("N", "straight"), mid("N", "right")) in pairs


def test_polyline_intersections_basic():
    p = np.array([[0.0, 0.0], [2.0, 2.0]])
    q = np.array([[0.0, 2.0], [2.0, 0.0]])
    x = polyline_intersections(p, q)
    assert np.allclose(x, [[1.0, 1.0, np.sqrt(2), np.sqrt(2)]])
    assert polyline_intersections(p, p + [0.0, 1.0]).shape == (0, 4)
    ov = polyline_intersections(np.array([[0.0, 0.0], [2.0, 0.0]]), np.array([[1.0, 0.0], [3.0, 0.0]]))
    assert ov.shape == (1, 4) and np.allclose(ov[0, :2], [1.5, 0.0])


def test_shared_start_is_not_crossing(paper):
    # N-straight and N-right share the stop-line point of lane 1 only
    x = polyline_intersections(lane_path(mid("N", "straight"), 1), lane_path(mid("N", "right"), 1))
    assert len(x) and np.allclose(x[:, :2], [-6.0, 12.0])
    assert "crossing" not in paper.kinds[mid("N", "straight"), mid("N", "right")]


def test_report_json(paper):
    rep = conflicts_report("paper")
    json.dumps(rep)
    assert rep["lane_use"] == "paper"
    assert [mv["id"] for mv in rep["movements"]] == list(range(12))
    assert rep["movements"][2] == {"id": 2, "leg": "N", "turn": "right", "name": "N-right",
                                   "exit_leg": "W", "lanes": [1, 2], "departure_lanes": [1, 2]}
    assert np.array_equal(np.array(rep["matrix"], dtype=bool), paper.matrix)
    assert rep["kinds"][0][0] == ["self"]
    assert rep["kinds"][1][2] == ["diverging"]
    rep2 = conflicts_report({"left": 0, "straight": 1, "right": 2}, opposing_left_conflict=True)
    assert rep2["lane_use"] == "custom" and rep2["opposing_left_conflict"] is True
    assert rep2["matrix"] == conflicts_report("exclusive")["matrix"]


def test_format_and_gap(paper):
    s = format_matrix(paper)
    assert len(s.splitlines()) == 13 and "NL" in s and "WR" in s
    gap = required_layer_gap(paper, vehicle_length=5.0, margin=2.0)
    assert gap == pytest.approx(19.0)
    from icv_envs.platoon import DEFAULT_D_T
    for name in LANE_USE_PRESETS:
        assert required_layer_gap(conflict_model(name)) <= DEFAULT_D_T


def test_bad_arguments():
    with pytest.raises(ValueError, match="'nope'"):
        conflict_model("nope")
    with pytest.raises(ValueError, match="opposing_left_conflict"):
        conflict_model("paper", opposing_left_conflict="yes")
    with pytest.raises(ValueError, match="'odd'"):
        conflict_model("paper", rule="odd")
    with pytest.raises(ValueError, match="margin"):
        required_layer_gap(conflict_model("paper"), margin=-1.0)
