"""Intersection geometry: analytic paths, highway-env road network, lane use, radii."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from highway_env.road.lane import CircularLane, StraightLane

from icv_envs.platoon import conflict_model, lane_path, path_length, required_layer_gap
from icv_envs.platoon.geometry import LEGS, lane_use_table
from icv_envs.sim.intersection_world import DEFAULT_BOX_HALF, IntersectionLayout, validate_radii


@pytest.mark.parametrize("lane_use", ["paper", "exclusive"])
def test_paths_match_platoon_geometry(lane_use):
    lay = IntersectionLayout(lane_use)
    for m in range(12):
        for a in range(3):
            p = lane_path(m, a, box_half=lay.box_half, n_points=101)
            pid = 3 * m + a
            assert lay.L[pid] == pytest.approx(path_length(p), abs=1e-2)
            seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
            s = np.concatenate([[0.0], np.cumsum(seg)])
            x, y, h = lay.route_points(np.full(len(s), pid), s)
            np.testing.assert_allclose(np.c_[x, y], p, atol=1e-3)
            s2, lat = lay.project(np.full(len(s), pid), x, y, np.ones(len(s), dtype=int))
            np.testing.assert_allclose(s2, s, atol=1e-3)
            np.testing.assert_allclose(lat, 0.0, atol=1e-3)
            # headings are tangent to the path
            d = np.diff(p, axis=0)
            mid = 0.5 * (s[1:] + s[:-1])
            _, _, hm = lay.route_points(np.full(len(mid), pid), mid)
            dd = np.arctan2(d[:, 1], d[:, 0]) - hm
            assert np.max(np.abs((dd + np.pi) % (2 * np.pi) - np.pi)) < 0.05


def test_route_extends_straight_before_and_after_the_box():
    lay = IntersectionLayout()
    pid = 3 * 0 + 0  # N-left, lane 0
    x, y, h = lay.route_points(np.array([pid, pid]), np.array([-100.0, lay.L[pid] + 50.0]))
    # N approach: heading south at x = -2; departure to E (right-hand traffic: south side), heading east at y = -2
    assert x[0] == pytest.approx(-2.0) and y[0] == pytest.approx(lay.box_half + 100.0)
    assert h[0] == pytest.approx(-math.pi / 2)
    assert x[1] == pytest.approx(lay.box_half + 50.0) and y[1] == pytest.approx(-2.0)
    assert h[1] == pytest.approx(0.0)


def test_kerb_right_turn_is_drivable_with_the_default_box():
    lay = IntersectionLayout("exclusive")
    r_min = 2.8 / math.tan(math.radians(30.0))  # 4.85 m at the rear axle
    radii = [lay.R[3 * m + a] for m in range(12) for a in lay.lane_use[m] if lay.arc[3 * m + a]]
    assert min(radii) == pytest.approx(DEFAULT_BOX_HALF - 2.5 * 4.0) and min(radii) > r_min
    # the 12 m box of three lanes would make it a 2 m radius
    assert 12.0 - 2.5 * 4.0 < r_min


@pytest.mark.parametrize("lane_use", ["paper", "exclusive"])
def test_conflict_matrix_same_for_12_and_16_m_box(lane_use):
    a = conflict_model(lane_use, box_half=12.0)
    b = IntersectionLayout(lane_use).model
    np.testing.assert_array_equal(a.matrix, b.matrix)
    assert required_layer_gap(b) == pytest.approx(19.0)


@pytest.mark.parametrize("lane_use", ["paper", "exclusive"])
def test_road_network_turns_only_from_allowed_lanes(lane_use):
    lay = IntersectionLayout(lane_use)
    net = lay.to_network()
    table = lane_use_table(lane_use)
    turn_edges = set()
    for frm, tos in net.graph.items():
        for to, lanes in tos.items():
            assert len(lanes) == 1  # one lane per edge: each lane has its own nodes
            if ":stop" in frm:
                leg, a = frm.split(":stop")
                exit_leg, j = to.split(":exit")
                turn_edges.add((leg, int(a), exit_leg, int(j)))
    expected = set()
    for m, lanes in table.items():
        leg, turn = divmod(m, 3)
        for a in lanes:
            expected.add((LEGS[leg], a, LEGS[(leg + 1 + turn) % 4], a))
    assert turn_edges == expected
    # every approach lane reaches exactly the exits its movements allow
    for leg in LEGS:
        for a in range(3):
            allowed = {e for (lg, aa, e, _) in expected if lg == leg and aa == a}
            got = set(to.split(":")[0] for to in net.graph.get(f"{leg}:stop{a}", {}))
            assert got == allowed
    # departure lanes have their own nodes
    for leg in LEGS:
        for j in range(3):
            assert f"{leg}:out{j}" in net.graph[f"{leg}:exit{j}"]


def test_road_network_positions_match_the_paths_in_screen_frame():
    lay = IntersectionLayout("paper")
    net = lay.to_network()
    for m, lanes in lay.lane_use.items():
        leg, turn = divmod(m, 3)
        for a in lanes:
            pid = 3 * m + a
            lane = net.get_lane((f"{LEGS[leg]}:stop{a}", f"{LEGS[(leg + 1 + turn) % 4]}:exit{a}", 0))
            assert isinstance(lane, CircularLane if turn != 1 else StraightLane)
            assert lane.length == pytest.approx(lay.L[pid], rel=1e-6)
            for s in np.linspace(0, lay.L[pid], 7):
                x, y, h = lay.route_points(np.array([pid]), np.array([s]))
                np.testing.assert_allclose(lane.position(s, 0.0), [x[0], -y[0]], atol=1e-6)
    # approach roads reach beyond R3
    app = net.get_lane(("N:in1", "N:stop1", 0))
    assert app.length >= lay.R3 - lay.box_half


def test_radii_validation():
    assert validate_radii(300, 500, 800) == (300.0, 500.0, 800.0)
    for r1, r2, r3 in ((500, 300, 800), (300, 800, 500), (300, 300, 800), (10, 500, 800)):
        with pytest.raises(ValueError, match=r"box_half < R1 < R2 < R3"):
            validate_radii(r1, r2, r3)
    with pytest.raises(ValueError, match="R2 must be a finite number"):
        validate_radii(300, float("nan"), 800)


def test_fleet_rows_equal_a_binary_search_after_adds_and_removals():
    """Fleet.rows (a compiled lookup in an id -> row table rebuilt when the
    fleet changes) against a binary search over the sorted ids: the same
    rows, -1 for absent, negative and not yet issued ids, through adds and
    removals, for 1-D and 2-D requests."""
    import numpy as np

    from icv_envs.sim.intersection_world import Fleet

    f = Fleet()
    rng = np.random.default_rng(0)
    for _ in range(30):
        f.add(int(rng.integers(0, 6)))
        if f.n:
            f.remove(rng.random(f.n) < 0.3)
        # the rows stay sorted by id (IntersectionWorld.substeps reads the largest id as the last)
        assert np.all(np.diff(f.vid) > 0)
        probe = rng.integers(-2, f.next_vid + 3, size=40)
        got = f.rows(probe)
        r = np.minimum(np.searchsorted(f.vid, probe), max(f.n - 1, 0))
        want = np.where((f.n > 0) & (f.vid[r] == probe), r, -1) if f.n else np.full(40, -1)
        assert got.dtype == np.int64 and np.array_equal(got, want)
        assert np.array_equal(f.rows(probe.reshape(8, 5)), want.reshape(8, 5))
        assert np.array_equal(np.concatenate([f.rows(probe[i:i + 4].tolist()) for i in range(0, 40, 4)]), want)
        assert all((r == -1) == (v not in set(f.vid.tolist())) for v, r in zip(probe.tolist(), got.tolist()))


@settings(max_examples=200, deadline=None)
@given(k=st.integers(0, 4), scalar=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_fleet_add_fills_fields_as_the_broadcast_did(k, scalar, seed):
    """Fleet.add (stop 41: one assignment per field's new rows) gives every
    field the values and dtype ``np.broadcast_to(np.asarray(v, dtype), (k,))``
    gave (floats into integer and bool fields included); an unknown field
    raises naming it, before anything is added."""

    from icv_envs.sim.intersection_world import Fleet

    rng = np.random.default_rng(seed)
    f = Fleet()
    spec = {"x": (np.float64, 0.0), "lane": (np.int64, -1), "ok": (bool, False), "t": (np.float32, 1.5)}
    for name, (dt, d) in spec.items():
        f.define(name, dt, d)
    f.add(2, x=1.0)
    vals = {"x": rng.normal(size=k) * 10, "lane": rng.normal(size=k) * 3, "ok": rng.normal(size=k)}
    if scalar:
        vals = {n: (v[0] if k else 2.7) for n, v in vals.items()}
    before = {n: getattr(f, n).copy() for n in spec}
    f.add(k, **vals)
    for name, (dt, d) in spec.items():
        want = np.concatenate([before[name], np.broadcast_to(np.asarray(vals.get(name, d), dtype=dt), (k,))])
        got = getattr(f, name)
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), name
    n0, next0 = f.n, f.next_vid
    with pytest.raises(ValueError, match="unknown vehicle fields"):
        f.add(1, x=0.0, nope=3)
    assert f.n == n0 and f.next_vid == next0 and all(len(getattr(f, n)) == n0 for n in spec)
