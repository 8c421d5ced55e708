"""Tests for the vectorised simulation core: icv_envs.sim.traffic (bicycle
model, lane-sorted neighbour search, sweep-and-prune collisions, IDM),
icv_envs.sim.road (RoadLayout) and icv_envs.sim.vehicle (ICVVehicle)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from icv_envs.sim.road import Obstacle, OffRamp, OnRamp, RoadLayout
from icv_envs.sim.traffic import (
    LAT_ACCEL_MAX,
    limit_steering,
    Traffic,
    bicycle_step,
    find_collisions,
    followers,
    idm_acceleration,
    lane_index,
    leaders,
    occupied_lanes,
    rect_overlap,
)
from icv_envs.sim.vehicle import ICVVehicle

SETTINGS = settings(max_examples=150, deadline=None, database=None)
FEW = settings(max_examples=60, deadline=None, database=None)
finite = dict(allow_nan=False, allow_infinity=False)


def fl(lo, hi):
    return st.floats(min_value=lo, max_value=hi, **finite)


# ===========================================================================
# helpers / references
# ===========================================================================
def corners(cx, cy, h, length, width):
    """Corners of an oriented rectangle, counter-clockwise, shape (4, 2)."""
    u = np.array([math.cos(h), math.sin(h)])
    n = np.array([-u[1], u[0]])
    c = np.array([cx, cy])
    a, b = 0.5 * length, 0.5 * width
    return np.array([c + a * u + b * n, c - a * u + b * n, c - a * u - b * n, c + a * u - b * n])


def penetration(p, q):
    """SAT from explicit corners: min over the 4 edge normals of the projection
    overlap (positive: interiors intersect, negative: separated by that much)."""
    best = np.inf
    for poly in (p, q):
        for k in range(2):
            e = poly[k + 1] - poly[k]
            ax = np.array([-e[1], e[0]]) / np.hypot(*e)
            pp, qq = p @ ax, q @ ax
            best = min(best, min(pp.max(), qq.max()) - max(pp.min(), qq.min()))
    return best


def clip_area(subject, clip):
    """Area of the intersection of two convex CCW polygons (Sutherland-Hodgman)."""
    out = [tuple(v) for v in subject]
    m = len(clip)
    for k in range(m):
        a, b = clip[k], clip[(k + 1) % m]
        inp, out = out, []
        if not inp:
            break

        def side(p):
            return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])

        def inside(p):
            return side(p) >= 0

        def inter(p, q):
            sp, sq = side(p), side(q)
            t = sp / (sp - sq)  # sp and sq have opposite signs here
            return (p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1]))

        for idx in range(len(inp)):
            cur, prev = inp[idx], inp[idx - 1]
            if inside(cur):
                if not inside(prev):
                    out.append(inter(prev, cur))
                out.append(cur)
            elif inside(prev):
                out.append(inter(prev, cur))
    if len(out) < 3:
        return 0.0
    xs = np.array([p[0] for p in out])
    ys = np.array([p[1] for p in out])
    return 0.5 * abs(np.dot(xs, np.roll(ys, -1)) - np.dot(ys, np.roll(xs, -1)))


def brute_collisions(cx, cy, h, length, width):
    n = len(cx)
    if n < 2:
        return set()
    i, j = np.triu_indices(n, 1)
    hit = rect_overlap(cx[i], cy[i], h[i], length[i], width[i], cx[j], cy[j], h[j], length[j], width[j])
    return {frozenset((int(a), int(b))) for a, b in zip(i[hit], j[hit])}


# ===========================================================================
# 1. find_collisions == brute force
# ===========================================================================
@st.composite
def vehicle_sets(draw, max_n=60):
    n = draw(st.integers(0, max_n))
    span = draw(st.sampled_from([3.0, 20.0, 80.0, 400.0]))
    n_lanes = draw(st.integers(1, 4))
    grid = draw(st.booleans())
    if grid:
        # exact-touching configurations: grid positions, axis-aligned bodies
        xs = draw(st.lists(st.integers(0, int(2 * span)), min_size=n, max_size=n))
        cx = np.array(xs, dtype=float) * 0.5
        lanes = draw(st.lists(st.integers(0, n_lanes - 1), min_size=n, max_size=n))
        dy = draw(st.lists(st.sampled_from([-1.0, 0.0, 1.0]), min_size=n, max_size=n))
        cy = 4.0 * np.array(lanes, dtype=float) + np.array(dy)
        h = np.array(draw(st.lists(st.sampled_from([0.0, 0.0, 0.1, -0.25]), min_size=n, max_size=n)))
        length = np.array(draw(st.lists(st.sampled_from([3.0, 4.0, 5.0, 12.0]), min_size=n, max_size=n)))
        width = np.array(draw(st.lists(st.sampled_from([1.5, 2.0, 2.5]), min_size=n, max_size=n)))
    else:
        cx = np.array(draw(st.lists(fl(0.0, span), min_size=n, max_size=n)))
        cy = np.array(draw(st.lists(fl(-2.0, 4.0 * (n_lanes - 1) + 2.0), min_size=n, max_size=n)))
        h = np.array(draw(st.lists(fl(-0.5, 0.5), min_size=n, max_size=n)))
        length = np.array(draw(st.lists(fl(3.0, 12.0), min_size=n, max_size=n)))
        width = np.array(draw(st.lists(fl(1.5, 2.6), min_size=n, max_size=n)))
    return (cx.astype(float), cy.astype(float), h.astype(float), length.astype(float), width.astype(float))


@SETTINGS
@given(vehicle_sets())
def test_find_collisions_matches_brute_force(vs):
    cx, cy, h, length, width = vs
    i, j = find_collisions(cx, cy, h, length, width)
    assert len(i) == len(j)
    assert i.dtype.kind == "i" and j.dtype.kind == "i"
    assert np.all(i != j)
    got = [frozenset((int(a), int(b))) for a, b in zip(i, j)]
    assert len(got) == len(set(got)), "duplicate pairs"
    assert set(got) == brute_collisions(cx, cy, h, length, width)


def test_find_collisions_dense_stack_and_trivial():
    # everyone on the same spot: all pairs collide
    n = 40
    z = np.zeros(n)
    i, j = find_collisions(z, z, z, np.full(n, 5.0), np.full(n, 2.0))
    assert {frozenset(p) for p in zip(i.tolist(), j.tolist())} == {
        frozenset((a, b)) for a in range(n) for b in range(a + 1, n)
    }
    # a platoon with 1 m bumper gaps: nothing collides; 0 and 1 vehicles: nothing
    x = np.arange(10) * 6.0
    assert len(find_collisions(x, np.zeros(10), np.zeros(10), np.full(10, 5.0), np.full(10, 2.0))[0]) == 0
    for m in (0, 1):
        a, b = find_collisions(np.zeros(m), np.zeros(m), np.zeros(m), np.full(m, 5.0), np.full(m, 2.0))
        assert len(a) == len(b) == 0
    # long vehicle overlapping a short one many places away in x order
    cx = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.5])
    cy = np.array([0.0, 8.0, 8.0, 8.0, 8.0, 0.0])
    length = np.array([12.0, 3.0, 3.0, 3.0, 3.0, 3.0])
    i, j = find_collisions(cx, cy, np.zeros(6), length, np.full(6, 2.0))
    assert frozenset((0, 5)) in {frozenset(p) for p in zip(i.tolist(), j.tolist())}


# ===========================================================================
# 2. rect_overlap
# ===========================================================================
rect_st = st.tuples(fl(-15.0, 15.0), fl(-6.0, 6.0), fl(-math.pi, math.pi), fl(1.0, 12.0), fl(1.0, 3.0))


def ro(a, b):
    return bool(rect_overlap(*a, *b))


@SETTINGS
@given(rect_st, rect_st)
def test_rect_overlap_matches_polygon_reference(a, b):
    pa, pb = corners(*a), corners(*b)
    pen = penetration(pa, pb)
    got = ro(a, b)
    assert got == ro(b, a)  # symmetric
    if pen > 1e-7:
        assert got
        assert clip_area(pa, pb) > 0.0
    elif pen < -1e-7:
        assert not got
        assert clip_area(pa, pb) < 1e-9
    # a corner strictly inside the other rectangle implies overlap
    for p, q, rect in ((pa, pb, b), (pb, pa, a)):
        cxq, cyq, hq, lq, wq = rect
        for c in p:
            d = c - np.array([cxq, cyq])
            lon = d[0] * math.cos(hq) + d[1] * math.sin(hq)
            lat = -d[0] * math.sin(hq) + d[1] * math.cos(hq)
            if abs(lon) < 0.5 * lq - 1e-7 and abs(lat) < 0.5 * wq - 1e-7:
                assert got


@SETTINGS
@given(rect_st, fl(-math.pi, math.pi), fl(-30.0, 30.0), fl(-30.0, 30.0), rect_st)
def test_rect_overlap_rotation_invariant(a, alpha, px, py, b):
    assume(abs(penetration(corners(*a), corners(*b))) > 1e-6)

    def rot(r):
        cx, cy, h, length, width = r
        dx, dy = cx - px, cy - py
        ca, sa = math.cos(alpha), math.sin(alpha)
        return (px + ca * dx - sa * dy, py + sa * dx + ca * dy, h + alpha, length, width)

    assert ro(a, b) == ro(rot(a), rot(b))


@SETTINGS
@given(rect_st)
def test_rect_overlap_identical_and_far(a):
    assert ro(a, a)
    cx, cy, h, length, width = a
    assert not ro(a, (cx + 30.0, cy, h, length, width))
    assert not ro(a, (cx, cy - 30.0, h + 0.3, length, width))


@SETTINGS
@given(fl(-20, 20), fl(-5, 5), fl(0.5, 12), fl(0.5, 3), fl(-20, 20), fl(-5, 5), fl(0.5, 12), fl(0.5, 3), st.booleans())
def test_rect_overlap_axis_aligned_interval_test(x1, y1, l1, w1, x2, y2, l2, w2, flip):
    # heading pi is still axis aligned; cos(pi) is not exactly -1 in floats so
    # only use it away from exact touching
    h1 = math.pi if flip else 0.0
    sep_x = abs(x2 - x1) - 0.5 * (l1 + l2)
    sep_y = abs(y2 - y1) - 0.5 * (w1 + w2)
    if flip:
        assume(abs(sep_x) > 1e-9 and abs(sep_y) > 1e-9)
    expected = (abs(x2 - x1) < 0.5 * (l1 + l2)) and (abs(y2 - y1) < 0.5 * (w1 + w2))
    assert ro((x1, y1, h1, l1, w1), (x2, y2, 0.0, l2, w2)) == expected
    # and a rectangle rotated by 90 degrees swaps its extents
    assume(abs(sep_x) > 1e-9 and abs(sep_y) > 1e-9)
    assert ro((x1, y1, math.pi / 2, w1, l1), (x2, y2, 0.0, l2, w2)) == expected


def test_rect_overlap_exact_touching_is_not_a_collision():
    a = (0.0, 0.0, 0.0, 5.0, 2.0)
    assert not ro(a, (5.0, 0.0, 0.0, 5.0, 2.0))  # bumper to bumper
    assert not ro(a, (0.0, 2.0, 0.0, 5.0, 2.0))  # side by side
    assert ro(a, (4.999, 0.0, 0.0, 5.0, 2.0))
    # vectorised form
    out = rect_overlap(np.zeros(3), np.zeros(3), np.zeros(3), 5.0, 2.0, np.array([0.0, 4.0, 6.0]), 0.0, 0.0, 5.0, 2.0)
    assert out.tolist() == [True, True, False]


# ===========================================================================
# 3. lane index, leaders, followers
# ===========================================================================
MARGIN = 0.0  # any overlap of the footprint with a lane lists the vehicle there (issue 11)


@st.composite
def lane_scenes(draw):
    n_lanes = draw(st.integers(1, 5))
    W = draw(st.sampled_from([3.0, 3.5, 4.0, 4.5]))
    n = draw(st.integers(0, 40))
    ticks = draw(st.lists(st.integers(-200, 4000), min_size=n, max_size=n, unique=True))
    cx = np.array(ticks, dtype=float) * 0.25 + 0.1
    cy = np.array(draw(st.lists(fl(-W, W * n_lanes), min_size=n, max_size=n)))
    width = np.array(draw(st.lists(fl(1.5, 2.6), min_size=n, max_size=n)))
    return n_lanes, W, cx.astype(float), cy.astype(float), width.astype(float)


def brute_occupies(cy, w, lane, W, n_lanes):
    return 0 <= lane < n_lanes and abs(cy - lane * W) < 0.5 * (W + w) - MARGIN


@SETTINGS
@given(lane_scenes())
def test_occupied_lanes_margin_rule(scene):
    n_lanes, W, cx, cy, width = scene
    rows, lanes = occupied_lanes(cy, width, W, n_lanes)
    got = set(zip(rows.tolist(), lanes.tolist()))
    assert len(got) == len(rows)
    exp = {(i, l) for i in range(len(cy)) for l in range(-2, n_lanes + 2) if brute_occupies(cy[i], width[i], l, W, n_lanes)}
    assert got == exp


@SETTINGS
@given(lane_scenes())
def test_leaders_followers_match_brute_force(scene):
    n_lanes, W, cx, cy, width = scene
    n = len(cx)
    index = lane_index(cx, cy, width, W, n_lanes, road_length=1000.0)
    q_rows = np.repeat(np.arange(n), n_lanes + 2)
    q_lanes = np.tile(np.arange(-1, n_lanes + 1), n)
    lead = leaders(index, q_rows, q_lanes, cx)
    foll = followers(index, q_rows, q_lanes, cx)
    assert lead.shape == foll.shape == (len(q_rows),)
    for k, (i, lane) in enumerate(zip(q_rows.tolist(), q_lanes.tolist())):
        occ = [j for j in range(n) if j != i and brute_occupies(cy[j], width[j], lane, W, n_lanes)]
        ahead = [j for j in occ if cx[j] > cx[i]]
        behind = [j for j in occ if cx[j] < cx[i]]
        exp_l = min(ahead, key=lambda j: cx[j]) if ahead else -1
        exp_f = max(behind, key=lambda j: cx[j]) if behind else -1
        assert lead[k] == exp_l, (i, lane)
        assert foll[k] == exp_f, (i, lane)


def test_leaders_empty_and_ties():
    e = np.zeros(0)
    index = lane_index(e, e, e, 4.0, 3, 1000.0)
    assert leaders(index, np.zeros(0, int), np.zeros(0, int), e).shape == (0,)
    # two co-located vehicles see each other as leaders (at a negative gap),
    # never as followers, and never themselves
    cx = np.array([10.0, 10.0, 30.0, -5.0])
    cy = np.zeros(4)
    index = lane_index(cx, cy, np.full(4, 2.0), 4.0, 2, 1000.0)
    assert leaders(index, [0, 1], [0, 0], cx).tolist() == [1, 0]
    assert followers(index, [0, 1], [0, 0], cx).tolist() == [3, 3]
    # alongside in the next lane: visible from that lane too
    cx2 = np.array([10.0, 10.0])
    cy2 = np.array([0.0, 4.0])
    index = lane_index(cx2, cy2, np.full(2, 2.0), 4.0, 2, 1000.0)
    assert leaders(index, [0, 1], [1, 0], cx2).tolist() == [1, 0]
    # vehicle straddling lanes 0 and 1 is seen from both
    cx = np.array([0.0, 20.0, 40.0])
    cy = np.array([0.0, 2.0, 4.0])
    index = lane_index(cx, cy, np.full(3, 2.0), 4.0, 2, 1000.0)
    assert leaders(index, [0, 2], [0, 1], cx).tolist() == [1, -1]
    assert followers(index, [2, 0], [1, 0], cx).tolist() == [1, -1]


# ===========================================================================
# 4. dynamics
# ===========================================================================
controls_st = st.lists(
    st.tuples(fl(-6.0, 3.0), fl(-np.deg2rad(30.0), np.deg2rad(30.0))), min_size=1, max_size=60
)


@FEW
@given(
    fl(-100, 100), fl(-5, 5), fl(-0.5, 0.5), fl(0.0, 30.0), fl(2.0, 4.0), st.sampled_from([0.05, 0.1, 0.2]), controls_st
)
def test_traffic_step_equals_bicycle_step_and_icv_vehicle(x0, y0, h0, v0, wb, dt, controls):
    v_max = 30.0
    tr = Traffic(wheelbase=wb)
    tr.add([x0, x0 + 50.0], [y0, y0 + 4.0], [v0, 0.5 * v0], heading=[h0, -h0])
    s = (tr.x.copy(), tr.y.copy(), tr.heading.copy(), tr.speed.copy())
    veh = ICVVehicle(None, [0.0, 0.0], heading=h0, speed=v0)
    veh.WHEELBASE = wb
    hwb = 0.5 * wb
    veh.position = np.array([x0 + hwb * math.cos(h0), y0 + hwb * math.sin(h0)])
    for a, phi in controls:
        acc = np.array([a, -a])
        steer = np.array([phi, -phi])
        applied = limit_steering(steer, tr.speed, wb)  # the lateral-acceleration bound (issue 11)
        tr.step(acc, steer, dt, v_max)
        s = bicycle_step(*s, acc, steer, dt, wb, v_max, lat_accel_max=LAT_ACCEL_MAX)
        for arr, ref in zip((tr.x, tr.y, tr.heading, tr.speed), s):
            np.testing.assert_array_equal(arr, ref)
        np.testing.assert_array_equal(tr.accel, acc)
        np.testing.assert_array_equal(tr.steer, applied)
        assert np.all((tr.speed >= 0.0) & (tr.speed <= v_max))
        veh.action = {"acceleration": a, "steering": phi}
        veh.step(dt)
    cx, cy = tr.center()
    np.testing.assert_allclose(veh.position, [cx[0], cy[0]], rtol=0, atol=1e-8)
    assert veh.heading == pytest.approx(tr.heading[0], abs=1e-10)
    assert veh.speed == pytest.approx(tr.speed[0], abs=1e-10)


def test_icv_vehicle_clips_controls_and_runs_on_a_highway_env_road():
    from highway_env.road.road import Road

    road = Road(network=RoadLayout(3, 500.0).to_network())
    veh = ICVVehicle(road, [10.0, 4.0], heading=0.0, speed=20.0)
    veh.action = {"acceleration": 100.0, "steering": 2.0}
    veh.step(0.1)
    x, y, h, v = bicycle_step(10.0 - 1.4, 4.0, 0.0, 20.0, 3.0, np.deg2rad(30.0), 0.1, 2.8, 30.0,
                              lat_accel_max=LAT_ACCEL_MAX)
    assert veh.speed == pytest.approx(v)
    assert veh.heading == pytest.approx(h)
    np.testing.assert_allclose(veh.position, [x + 1.4 * math.cos(h), y + 1.4 * math.sin(h)], atol=1e-12)
    assert veh.lane_index[2] == 1
    veh.crashed = True
    veh.action = {"acceleration": 3.0, "steering": 0.3}
    h_before, v_before = veh.heading, veh.speed
    veh.step(0.1)
    assert veh.heading == pytest.approx(h_before + 0.0)  # steering forced to 0... heading rate 0
    assert veh.speed == pytest.approx(v_before - 0.6)


@FEW
@given(fl(0.0, 30.0), fl(-math.pi, math.pi), st.integers(1, 100))
def test_zero_steering_drives_straight(v0, h0, steps):
    tr = Traffic()
    tr.add(0.0, 0.0, v0, heading=h0)
    for _ in range(steps):
        tr.step(np.zeros(1), np.zeros(1), 0.1, 30.0)
    assert tr.heading[0] == h0
    dist = v0 * 0.1 * steps
    np.testing.assert_allclose([tr.x[0], tr.y[0]], [dist * math.cos(h0), dist * math.sin(h0)], atol=1e-9)


@FEW
@given(fl(1.0, 30.0), fl(0.02, 0.5) | fl(-0.5, -0.02), fl(-math.pi, math.pi))
def test_constant_steering_traces_a_circle(v, phi, h0):
    L, dt = 2.8, 0.01
    tr = Traffic(wheelbase=L, lat_accel_max=None)  # the pure kinematic model
    tr.add(3.0, -2.0, v, heading=h0)
    omega = v * math.tan(phi) / L
    xs, ys = [tr.x[0]], [tr.y[0]]
    for k in range(200):
        tr.step(np.zeros(1), np.full(1, phi), dt, 30.0)
        # heading rate is v tan(phi) / L
        assert tr.heading[0] == pytest.approx(h0 + (k + 1) * omega * dt, rel=1e-9, abs=1e-9)
        xs.append(tr.x[0])
        ys.append(tr.y[0])
    R = L / math.tan(phi)  # signed: positive turns towards +y
    # forward Euler puts the rear axle on a regular polygon whose circumradius
    # tends to R as dt -> 0
    alpha = omega * dt
    Rc = v * dt / (2.0 * math.sin(alpha / 2.0))
    assert Rc == pytest.approx(R, rel=1e-3)
    # centre of that polygon: left of the first chord by Rc cos(alpha/2)
    mx = 0.5 * (xs[0] + xs[1])
    my = 0.5 * (ys[0] + ys[1])
    ox = mx - Rc * math.cos(alpha / 2.0) * math.sin(h0)
    oy = my + Rc * math.cos(alpha / 2.0) * math.cos(h0)
    d = np.hypot(np.array(xs) - ox, np.array(ys) - oy)
    np.testing.assert_allclose(d, abs(Rc), rtol=1e-7)
    # and close to the continuous circle of radius L / tan(phi)
    cx0 = 3.0 - R * math.sin(h0)
    cy0 = -2.0 + R * math.cos(h0)
    np.testing.assert_allclose(np.hypot(np.array(xs) - cx0, np.array(ys) - cy0), abs(R), rtol=0, atol=0.02 * abs(R) + 0.05)


def test_speed_is_clipped_to_zero_and_v_max():
    tr = Traffic()
    tr.add([0.0, 0.0], [0.0, 4.0], [0.5, 29.9])
    tr.step(np.array([-6.0, 3.0]), np.zeros(2), 0.1, 30.0)
    assert tr.speed.tolist() == [0.0, 30.0]


# ===========================================================================
# 5. Traffic bookkeeping
# ===========================================================================
ops_st = st.lists(
    st.one_of(
        st.tuples(st.just("add"), st.integers(1, 6)),
        st.tuples(st.just("remove"), st.lists(st.booleans(), min_size=0, max_size=40)),
    ),
    min_size=1,
    max_size=25,
)


@SETTINGS
@given(ops_st)
def test_traffic_add_remove_rows_keep_rows_aligned(ops):
    tr = Traffic()
    model: dict[int, tuple] = {}
    seen: list[int] = []
    for op, arg in ops:
        if op == "add":
            k = arg
            base = tr.next_vid
            x = base + np.arange(k) * 1.0  # x encodes the id
            ids = tr.add(x, 0.5 * x, 2.0 * x, heading=0.01 * x, length=3.0 + x, width=1.5, exit=k - 2, time=float(base))
            assert ids.tolist() == list(range(base, base + k))
            assert all(i > s for i in ids for s in seen)
            seen.extend(ids.tolist())
            for v in ids.tolist():
                model[v] = (float(v), 0.5 * v, 2.0 * v, 0.01 * v, 3.0 + v, k - 2, float(base))
        else:
            mask = np.zeros(tr.n, dtype=bool)
            m = np.array(arg[: tr.n], dtype=bool)
            mask[: len(m)] = m
            for v in tr.vid[mask].tolist():
                del model[v]
            tr.remove(mask)
        # invariants
        assert tr.n == len(model)
        assert np.all(np.diff(tr.vid) > 0)
        for f in ("x", "y", "heading", "speed", "accel", "steer", "length", "width", "spawn_time", "lc_x0",
                  "lc_y0", "lc_y1", "lc_len", "tgt_behind", "exit", "group", "lc_lane", "tgt_lane", "crashed"):
            assert len(getattr(tr, f)) == tr.n, f
        assert sorted(model) == tr.vid.tolist()
        for row, v in enumerate(tr.vid.tolist()):
            x, y, sp, h, ln, ex, t = model[v]
            assert (tr.x[row], tr.y[row], tr.speed[row], tr.heading[row], tr.length[row]) == (x, y, sp, h, ln)
            assert tr.width[row] == 1.5 and tr.exit[row] == ex and tr.spawn_time[row] == t
            assert tr.group[row] == -1 and tr.lc_lane[row] == -1 and tr.tgt_lane[row] == -1 and not tr.crashed[row]
        if tr.n:
            vids = tr.vid[::-1]
            np.testing.assert_array_equal(tr.rows(vids), np.arange(tr.n)[::-1])
            np.testing.assert_array_equal(tr.vid[tr.rows(vids)], vids)


def test_traffic_add_scalar_and_center():
    tr = Traffic(wheelbase=2.0)
    ids = tr.add(5.0, 4.0, 10.0, heading=math.pi / 2)
    assert ids.tolist() == [0] and tr.n == 1
    cx, cy = tr.center()
    assert cx[0] == pytest.approx(5.0) and cy[0] == pytest.approx(5.0)
    tr.remove(np.array([True]))
    assert tr.n == 0
    assert tr.add([1.0, 2.0], 0.0, 0.0).tolist() == [1, 2]  # ids are never reused


# ===========================================================================
# 6. RoadLayout
# ===========================================================================
def test_available_lane_drop_obstacle_and_ramps():
    road = RoadLayout(
        3,
        2000.0,
        lane_ends=[np.inf, np.inf, 800.0],
        on_ramps=[OnRamp(500.0, 600.0, approach=200.0)],
        off_ramps=[OffRamp(1200.0, 1250.0, 1400.0)],
        obstacles=[Obstacle(lane=1, x=1000.0, length=10.0)],
    )
    assert road.has_ramp_lane and road.ramp_lane == 3 and road.total_lanes == 4
    av = road.available
    # lane drop: lane 2 exists on [0, 800)
    assert av(2, [0.0, 799.9, 800.0, 900.0]).tolist() == [True, True, False, False]
    assert av(0, [-0.1, 0.0, 1999.0]).tolist() == [False, True, True]
    # obstacle blocks lane 1 on [995, 1005] (closed), other lanes free there
    assert av(1, [994.9, 995.0, 1000.0, 1005.0, 1005.1]).tolist() == [True, False, False, False, True]
    assert av(0, 1000.0) and not av(2, 1000.0)
    # ramp lane: [300, 600] for the on-ramp, [1200, 1400] for the off-ramp
    assert av(3, [299.0, 300.0, 450.0, 600.0, 601.0, 1000.0, 1200.0, 1399.0, 1400.0, 1401.0]).tolist() == [
        False, True, True, True, False, False, True, True, True, False
    ]
    assert not av(4, 500.0).any() and not av(-1, 500.0).any()
    # broadcasting
    assert av(np.array([[0], [2]]), np.array([100.0, 900.0])).tolist() == [[True, True], [True, False]]
    # interval_end
    ie = road.interval_end
    assert ie(0, 10.0) == np.inf
    assert ie(2, [10.0, 700.0]).tolist() == [800.0, 800.0]
    assert ie(1, [10.0, 996.0, 1006.0]).tolist() == [995.0, 995.0, np.inf]
    assert ie(3, [0.0, 350.0, 700.0, 1300.0, 1500.0]).tolist() == [600.0, 600.0, 1400.0, 1400.0, np.inf]
    assert road.in_merge([450.0, 550.0, 650.0]).tolist() == [False, True, False]
    assert road.in_diverge([1199.0, 1225.0, 1300.0]).tolist() == [False, True, False]
    assert road.n_exits == 1 and road.exit_position(0) == 1400.0
    assert road.diverge_start(0) == 1200.0 and road.diverge_end(0) == 1250.0
    assert road.lane_of([-3.0, 0.0, 5.9, 6.1, 100.0]).tolist() == [0, 0, 1, 2, 3]
    assert RoadLayout(2, 100.0).available(2, 50.0).tolist() is False  # no ramp lane


def test_interval_end_ramp_lane_with_touching_on_and_off_ramps():
    road = RoadLayout(3, 2000.0, on_ramps=[OnRamp(300.0, 400.0, approach=100.0)], off_ramps=[OffRamp(400.0, 450.0, 600.0)])
    assert road.available(3, np.linspace(200.0, 600.0, 81)).all()  # one continuous ramp-lane stretch
    assert road.interval_end(3, [250.0, 399.0]).tolist() == [600.0, 600.0]


@st.composite
def layouts(draw):
    n = draw(st.integers(1, 4))
    length = 1000.0
    ends = [draw(st.one_of(st.just(np.inf), fl(0.0, 1200.0), st.integers(0, 1000).map(float))) for _ in range(n)]
    obs = draw(
        st.lists(
            st.builds(
                Obstacle,
                lane=st.integers(0, n - 1),
                x=st.one_of(fl(-20.0, 1100.0), st.integers(0, 100).map(lambda k: 10.0 * k)),
                length=st.one_of(fl(0.0, 60.0), st.sampled_from([4.0, 10.0, 20.0])),
            ),
            max_size=5,
        )
    )
    return RoadLayout(n, length, lane_ends=np.array(ends), obstacles=obs)


def critical_points(road: RoadLayout, lo: float, hi: float) -> np.ndarray:
    pts = [lo, hi]
    pts += [float(e) for e in road.lane_ends if np.isfinite(e)]
    for o in road.obstacles:
        pts += [o.x - o.length / 2, o.x + o.length / 2]
    pts = np.array(sorted(p for p in pts if lo <= p <= hi))
    mids = 0.5 * (pts[1:] + pts[:-1])
    return np.concatenate([pts, mids, np.linspace(lo, hi, 50)])


@SETTINGS
@given(
    layouts(),
    fl(-100.0, 1100.0) | st.integers(-5, 110).map(lambda k: 10.0 * k),
    fl(0.0, 400.0) | st.sampled_from([0.0, 10.0, 20.0]),
)
def test_drivable_main_lanes_matches_dense_sampling(road, x0, w):
    x1 = x0 + w
    lo = max(x0, 0.0)
    hi = max(x1, lo)
    xs = critical_points(road, lo, hi)
    exp = [lane for lane in range(road.n_lanes) if road.available(lane, xs).all()]
    assert road.drivable_main_lanes(x0, x1) == exp


@SETTINGS
@given(layouts(), fl(0.0, 1100.0), st.data())
def test_interval_end_main_lanes(road, x, data):
    lane = data.draw(st.integers(0, road.n_lanes - 1))
    end = float(road.interval_end(lane, x))
    if not road.available(lane, x):
        return
    assert end > x
    hi = min(end, 5000.0)
    xs = critical_points(road, x, hi)
    xs = xs[xs < end]
    assert road.available(lane, xs).all()
    if np.isfinite(end):
        assert not road.available(lane, end)
    # vectorised call agrees with scalar calls
    lanes = np.arange(road.n_lanes)
    np.testing.assert_array_equal(road.interval_end(lanes, x), [road.interval_end(int(l), x) for l in lanes])


def test_drivable_main_lanes_examples():
    road = RoadLayout(
        3,
        1000.0,
        lane_ends=[np.inf, np.inf, 500.0],
        obstacles=[Obstacle(lane=0, x=-20.0, length=10.0), Obstacle(lane=1, x=300.0, length=20.0)],
    )
    assert road.drivable_main_lanes(-100.0, 100.0) == [0, 1, 2]  # the obstacle at x < 0 is off the road
    assert road.drivable_main_lanes(0.0, 290.0) == [0, 2]  # touching the obstacle's rear end
    assert road.drivable_main_lanes(310.0, 400.0) == [0, 2]  # touching its front end
    assert road.drivable_main_lanes(310.1, 499.9) == [0, 1, 2]
    assert road.drivable_main_lanes(400.0, 500.0) == [0, 1]  # lane 2 ends at 500 (exclusive)
    assert road.drivable_main_lanes(600.0, 500.0) == [0, 1]  # reversed window collapses to x0
    assert road.drivable_main_lanes(-50.0, -10.0) == [0, 1, 2]  # window clipped to [0, 0]


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(n_lanes=0, length=100.0),
        dict(n_lanes=-2, length=100.0),
        dict(n_lanes=2.5, length=100.0),
        dict(n_lanes=2, length=-1.0),
        dict(n_lanes=2, length=0.0),
        dict(n_lanes=2, length=float("inf")),
        dict(n_lanes=2, length=float("nan")),
        dict(n_lanes=2, length=100.0, lane_ends=[100.0]),
        dict(n_lanes=2, length=100.0, lane_ends=[[100.0, 100.0]]),
        dict(n_lanes=2, length=100.0, obstacles=[Obstacle(lane=2, x=50.0)]),
        dict(n_lanes=2, length=100.0, obstacles=[Obstacle(lane=-1, x=50.0)]),
    ],
)
def test_road_layout_rejects_invalid_arguments(kwargs):
    with pytest.raises(ValueError):
        RoadLayout(**kwargs)


def _network_lanes(net):
    return [lane for tos in net.graph.values() for lanes in tos.values() for lane in lanes]


@FEW
@given(layouts(), st.booleans(), st.booleans())
def test_to_network_covers_the_road(road, with_on, with_off):
    road = RoadLayout(
        road.n_lanes,
        road.length,
        lane_width=road.lane_width,
        lane_ends=road.lane_ends,
        on_ramps=[OnRamp(200.0, 300.0)] if with_on else [],
        off_ramps=[OffRamp(600.0, 650.0, 800.0)] if with_off else [],
        obstacles=road.obstacles,
    )
    lanes = _network_lanes(road.to_network())
    W = road.lane_width
    for lane in lanes:
        assert 0.0 <= lane.start[0] < lane.end[0] <= road.length
        assert lane.start[1] == lane.end[1]
        assert lane.width == W
    xs = np.linspace(0.5, road.length - 0.5, 60)
    for li in range(road.total_lanes):
        y = li * W
        for x in xs:
            if li < road.n_lanes:
                exists = x < road.lane_ends[li]  # obstacles are drawn separately
            else:
                exists = bool(road.available(li, x))
            covered = any(lane.start[1] == y and lane.start[0] <= x <= lane.end[0] for lane in lanes)
            strictly = any(lane.start[1] == y and lane.start[0] < x < lane.end[0] for lane in lanes)
            if exists:
                assert covered, (li, x)
            elif not any(abs(x - c) < 1e-9 for c in road.lane_ends):
                assert not strictly, (li, x)
            # the closest lane of a point on an existing lane centre is that lane
    from highway_env.road.lane import StraightLane

    assert all(isinstance(lane, StraightLane) for lane in lanes)


# ===========================================================================
# 7. IDM
# ===========================================================================
@SETTINGS
@given(fl(0.0, 40.0), fl(1.0, 40.0))
def test_idm_free_road(v, v0):
    a = float(idm_acceleration(v, v0, np.inf, 0.0))
    if v < v0:
        assert 0.0 < a <= 3.0
    elif v > v0:
        assert a < 0.0
    else:
        assert a == pytest.approx(0.0, abs=1e-12)
    assert float(idm_acceleration(v, v0, np.inf, 5.0, free_term=False)) == 3.0
    assert float(idm_acceleration(v, v0, np.inf, 0.0, a_max=1.5, free_term=False)) == 1.5


@SETTINGS
@given(fl(0.0, 40.0), fl(1.0, 40.0), fl(-15.0, 15.0), st.lists(fl(0.0, 500.0), min_size=2, max_size=20), st.booleans())
def test_idm_monotone_in_gap(v, v0, dv, gaps, free_term):
    gaps = np.sort(np.array(gaps))
    a = idm_acceleration(np.full(len(gaps), v), v0, gaps, dv, free_term=free_term)
    assert a.shape == gaps.shape
    assert np.all(np.diff(a) >= -1e-12)
    assert np.all(a <= 3.0)
    # a closer leader never lets the vehicle accelerate more than the free road
    assert np.all(a <= idm_acceleration(v, v0, np.inf, dv, free_term=free_term) + 1e-12)
    # a much faster approach (larger dv) never increases the acceleration
    a2 = idm_acceleration(np.full(len(gaps), v), v0, gaps, dv + 5.0, free_term=free_term)
    assert np.all(a2 <= a + 1e-12)


def test_idm_brakes_hard_at_small_gaps():
    assert idm_acceleration(20.0, 30.0, 1.0, 0.0) < -100.0
    assert idm_acceleration(0.0, 30.0, 0.0, 0.0) < 0.0  # gap is clamped, no division by zero
    np.testing.assert_allclose(idm_acceleration(0.0, 30.0, 2.0, 0.0, free_term=False), 0.0, atol=1e-12)


def test_interval_end_of_lanes_that_do_not_exist():
    road = RoadLayout(3, 1000.0)
    assert np.all(road.interval_end([-1, 5], [10.0, 10.0]) == -np.inf)
