"""Tests for icv_envs.platoon.reservation (FCFS tile reservation, docs/intersection.md#reference-methods)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.platoon import (
    ReservationTable,
    footprint_mask,
    footprint_tiles,
    lane_path,
    movement_id,
    simulate_path_occupancy,
    tile_grid,
    tile_of_point,
)

SETTINGS = settings(max_examples=60, deadline=None, database=None)
NS = lane_path(movement_id("N", "straight"), 1)  # x = -6
ES = lane_path(movement_id("E", "straight"), 1)  # y = 6, crosses NS at (-6, 6)
NS_OPP = lane_path(movement_id("S", "straight"), 1)  # x = +6, parallel to NS


def _occ(path, s0, speed=10.0, **kw):
    return simulate_path_occupancy(path, s0, speed, **kw)


def test_tile_grid():
    n, c = tile_grid(1.0, 12.0)
    assert n == 24 and c.shape == (576, 2)
    assert np.allclose(c[0], [-11.5, -11.5]) and np.allclose(c[1], [-10.5, -11.5])
    assert np.allclose(c[24], [-11.5, -10.5])
    assert tile_of_point([-11.9, -11.9]).item() == 0
    assert tile_of_point([[0.2, 0.2], [13.0, 0.0]]).tolist() == [12 * 24 + 12, -1]
    assert tile_grid(0.7, 12.0)[0] == 35


@given(cx=st.floats(-14.0, 14.0), cy=st.floats(-14.0, 14.0), h=st.floats(-4.0, 4.0),
       length=st.floats(0.5, 8.0), width=st.floats(0.5, 3.0), buf=st.floats(0.0, 1.0),
       tile=st.sampled_from([0.5, 1.0, 1.5]), u=st.lists(st.floats(-1, 1), min_size=40, max_size=40),
       v=st.lists(st.floats(-1, 1), min_size=40, max_size=40))
@SETTINGS
def test_footprint_covers_rectangle(cx, cy, h, length, width, buf, tile, u, v):
    tiles = footprint_tiles(np.array([cx, cy]), h, length, width, buf, tile, 12.0)
    hl, hw = length / 2 + buf, width / 2 + buf
    # sampled points of the buffered rectangle, including its corners
    uu = np.concatenate([u, [-1, -1, 1, 1]]) * hl
    vv = np.concatenate([v, [-1, 1, -1, 1]]) * hw
    pts = np.column_stack([cx + uu * math.cos(h) - vv * math.sin(h),
                           cy + uu * math.sin(h) + vv * math.cos(h)])
    ids = tile_of_point(pts, tile, 12.0)
    assert set(ids[ids >= 0].tolist()) <= set(tiles.tolist())
    # conservative but not wasteful: every returned tile is within reach of the rectangle
    _, centres = tile_grid(tile, 12.0)
    reach = math.hypot(hl, hw) + tile * math.sqrt(2) / 2 + 1e-9
    assert np.all(np.linalg.norm(centres[tiles] - [cx, cy], axis=1) <= reach)


def test_footprint_axis_aligned_exact():
    # 2 x 1 m rectangle at (0.5, 0.5), no buffer: touches x in [-0.5, 1.5], y in [0, 1]
    t = footprint_tiles(np.array([0.5, 0.5]), 0.0, 2.0, 1.0, 0.0, 1.0, 12.0)
    cols = t % 24 - 12
    rows = t // 24 - 12
    assert set(zip(cols.tolist(), rows.tolist())) == {(c, r) for c in (-1, 0, 1) for r in (-1, 0, 1)}
    m = footprint_mask(np.array([[0.5, 0.5], [100.0, 0.0]]), np.array([0.0, 0.0]), 2.0, 1.0, 0.0)
    assert m.shape == (2, 576) and m[0].sum() == 9 and m[1].sum() == 0


def test_occupancy_crossing_the_box():
    steps, tiles = _occ(NS, -20.0, 10.0, start_step=100)
    assert steps[0] >= 100 and np.all(np.diff(steps) == 1)
    # the footprint first touches the box when the buffered front reaches the stop line
    hl = 2.5 + 0.5
    assert steps[0] - 100 == math.ceil((20.0 - hl) / (10.0 * 0.04) - 1e-9)
    allt = np.unique(np.concatenate(tiles))
    cols = allt % 24
    assert set(cols.tolist()) == set(range(4, 8))  # x in [-7.5, -4.5]: the 3 m wide buffered body
    # a stopped vehicle never clears the box
    with pytest.raises(ValueError, match="max_steps"):
        _occ(NS, -1.0, 0.0, max_steps=200)
    # braking profile slows the crossing down
    s_slow, _ = _occ(NS, -20.0, 10.0, accel=np.full(25, -3.0))
    assert s_slow[-1] > steps[-1] - 100


def test_crossing_conflict_and_retry():
    table = ReservationTable(time_buffer=5)
    # both arrive at the crossing point (-6, 6) together: NS at s = 6, ES at s = 18
    s1, t1 = _occ(NS, -20.0)
    s2, t2 = _occ(ES, -8.0)
    assert table.request("a", s1, t1)
    assert not table.request("b", s2, t2)
    assert table.vehicles == ["a"]
    # b slows down / arrives later: granted once its times are past a's
    for delay in range(0, 400, 5):
        if table.request("b", s2 + delay, t2):
            break
    else:
        pytest.fail("never granted")
    assert delay > 0 and table.vehicles == ["a", "b"]
    # no tile is held by both within the time buffer
    ha, hb = table.held_by("a"), table.held_by("b")
    for t, tiles in hb.items():
        for s in range(t - 5, t + 6):
            if s in ha:
                assert not set(ha[s].tolist()) & set(tiles.tolist())


def test_parallel_paths_both_granted():
    table = ReservationTable()
    assert table.request("a", *_occ(NS, -20.0))
    assert table.request("b", *_occ(NS_OPP, -20.0))


def test_release_and_rerequest():
    table = ReservationTable()
    s1, t1 = _occ(NS, -20.0)
    s2, t2 = _occ(ES, -8.0)
    assert table.request("a", s1, t1)
    assert not table.request("b", s2, t2)
    assert table.release("a") and not table.release("a")
    assert not table.occupancy(int(s1[10])).any()
    assert table.request("b", s2, t2)
    assert not table.request("a", s1, t1)
    assert table.release("b")
    assert table.request("a", s1, t1)  # the same vehicle again after its release
    # a vehicle's new request replaces its own reservation (never blocked by itself)
    assert table.request("a", s1 + 3, t1)
    assert min(table.held_by("a")) == s1[0] + 3


def test_fcfs_order_and_determinism():
    reqs = [("v%d" % k, *_occ(p, s0, start_step=st_))
            for k, (p, s0, st_) in enumerate([(NS, -20.0, 0), (ES, -8.0, 0), (NS_OPP, -20.0, 0),
                                              (ES, -8.0, 10), (NS, -20.0, 5)])]

    def run(order):
        table = ReservationTable()
        return [table.request(v, s, t) for v, s, t in order], table

    res, table = run(reqs)
    assert res == [True, False, True, False, False]
    res2, table2 = run(reqs)
    assert res2 == res
    for t in table.held_by("v0"):
        assert np.array_equal(table.occupancy(t), table2.occupancy(t))
    # serving in the other order flips who wins the crossing
    swapped = [reqs[1], reqs[0]] + reqs[2:]
    res3, _ = run(swapped)
    assert res3[:2] == [True, False]


def test_advance_drops_past():
    table = ReservationTable()
    s1, t1 = _occ(NS, -20.0)
    assert table.request("a", s1, t1)
    mid = int(s1[len(s1) // 2])
    table.advance(mid)
    assert table.holder(mid - 1, int(t1[0][0])) is None
    assert min(table.held_by("a")) == mid
    assert table.holder(mid, int(t1[s1.tolist().index(mid)][0])) == "a"
    with pytest.raises(ValueError, match="now"):
        table.request("b", [mid - 1], [[0]])
    with pytest.raises(ValueError, match="now_step"):
        table.advance(mid - 1)
    table.advance(int(s1[-1]) + 1)
    assert table.vehicles == [] and table.held_by("a") == {}


def test_time_buffer():
    table = ReservationTable(time_buffer=3)
    assert table.request("a", [10], [[5]])
    assert not table.request("b", [13], [[5]])
    assert table.request("b", [14], [[5]])
    assert table.request("c", [10], [[6]])  # other tile, same time
    assert table.request("d", [], [])  # empty request


def test_bad_arguments():
    table = ReservationTable()
    with pytest.raises(ValueError, match="0..575"):
        table.request("a", [1], [[576]])
    with pytest.raises(ValueError, match="one tile array per time step"):
        table.request("a", [1, 2], [[1]])
    with pytest.raises(ValueError, match="distinct"):
        table.request("a", [1, 1], [[1], [2]])
    with pytest.raises(ValueError, match="time_buffer"):
        ReservationTable(time_buffer=-1)
    with pytest.raises(ValueError, match="tile"):
        ReservationTable(tile=0.0)
    with pytest.raises(ValueError, match="speed"):
        simulate_path_occupancy(NS, -20.0, -1.0)
    with pytest.raises(ValueError, match="heading"):
        footprint_mask(np.zeros((3, 2)), np.zeros(2), 5.0, 2.0)


def _old_check_request(table, time_steps, tiles_per_step):
    """ReservationTable._check_request at b40d6e3 (stop 41), frozen: every
    step's tile array checked and made unique on its own."""
    steps = np.asarray(time_steps)
    if steps.ndim != 1 or (steps.size and not np.issubdtype(steps.dtype, np.integer)):
        raise ValueError(f"time_steps must be a 1-D array of integer steps, got {time_steps!r}")
    steps = steps.astype(np.int64)
    if len(tiles_per_step) != steps.size:
        raise ValueError(
            f"tiles_per_step must hold one tile array per time step: got "
            f"{len(tiles_per_step)} for {steps.size} steps"
        )
    if steps.size and steps.min() < table.now:
        raise ValueError(f"time_steps must be >= now = {table.now}, got step {int(steps.min())}")
    if np.unique(steps).size != steps.size:
        raise ValueError(f"time_steps must be distinct, got {steps.tolist()}")
    tiles = []
    for t in tiles_per_step:
        a = np.asarray(t)
        if a.size == 0:
            tiles.append(np.zeros(0, dtype=np.int64))
            continue
        if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer) or a.min() < 0 \
                or a.max() >= table.n_tiles:
            raise ValueError(
                f"tile ids must be 1-D integers in 0..{table.n_tiles - 1}, got {a.tolist()}"
            )
        tiles.append(np.unique(a.astype(np.int64)))
    return steps, tiles


def _outcome(fn, *args):
    try:
        steps, tiles = fn(*args)
    except ValueError as exc:
        return ("error", str(exc))
    return ("ok", steps.dtype.str, steps.tolist(), [(t.dtype.str, t.tolist()) for t in tiles])


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_check_request_equals_the_per_step_checks(data):
    """``_check_request`` (stop 42: all steps' tiles checked at once when
    they are sorted int64 ids in range, the per-step checks otherwise)
    against the per-step checks it replaced: the same arrays (values and
    dtype) or the same error, on sorted, unsorted and repeated ids, empty
    steps of any shape, other integer and non-integer dtypes, 2-D arrays
    and ids at and past the grid's ends."""
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    table = ReservationTable(tile=2.0, box_half=5.0)  # a 5 x 5 grid
    n = table.n_tiles
    k = data.draw(st.integers(0, 6))
    steps = np.arange(k, dtype=np.int64) + data.draw(st.sampled_from([0, 3]))
    tiles = []
    for _ in range(k):
        kind = data.draw(st.sampled_from(["sorted", "sorted", "unsorted", "repeat", "empty", "empty2d", "int32",
                                          "uint", "bool", "float", "2d", "edge", "past", "negative", "list"]))
        a = np.sort(rng.choice(n, int(rng.integers(1, 6)), replace=False)).astype(np.int64)
        if kind == "unsorted":
            a = a[::-1].copy()
        elif kind == "repeat":
            a = np.concatenate([a, a[:1]])
        elif kind == "empty":
            a = np.zeros(0, dtype=np.int64)
        elif kind == "empty2d":
            a = np.zeros((0, 3))
        elif kind == "int32":
            a = a.astype(np.int32)
        elif kind == "uint":
            a = a.astype(np.uint64)
        elif kind == "bool":
            a = np.ones(3, dtype=bool)
        elif kind == "float":
            a = a.astype(float)
        elif kind == "2d":
            a = a.reshape(1, -1)
        elif kind == "edge":
            a = np.array([0, n - 1], dtype=np.int64)
        elif kind == "past":
            a = np.array([1, n], dtype=np.int64)
        elif kind == "negative":
            a = np.array([-1, 2], dtype=np.int64)
        elif kind == "list":
            a = a.tolist()
        tiles.append(a)
    want = _outcome(_old_check_request, table, steps, tiles)
    assert _outcome(table._check_request, steps, tiles) == want


@pytest.mark.parametrize("throughput,seed", [(2200.0, 1), (3000.0, 0)])
def test_fcfs_requests_take_the_one_pass_check(throughput, seed):
    """The FCFS expert's requests (``np.flatnonzero`` of tile masks) are
    checked in one pass (``_sorted_tiles``), and each is checked as the
    per-step checks would: granted and refused requests both reached."""
    from icv_envs.envs.intersection_v0 import parallel_env

    real = ReservationTable._check_request
    seen = {"requests": 0, "one_pass": 0}

    def checked(self, time_steps, tiles_per_step):
        got = real(self, time_steps, tiles_per_step)
        assert _outcome(lambda: got) == _outcome(_old_check_request, self, time_steps, tiles_per_step)
        seen["requests"] += 1
        seen["one_pass"] += self._sorted_tiles([np.asarray(t) for t in tiles_per_step]) is not None
        return got

    ReservationTable._check_request = checked
    try:
        env = parallel_env(method="fcfs", throughput=throughput, duration=150.0)
        obs, infos = env.reset(seed=seed)
        while env.agents:
            obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    finally:
        ReservationTable._check_request = real
    st_ = env.core.expert.stats
    assert seen["requests"] > 20 and seen["one_pass"] == seen["requests"], seen
    assert st_["granted"] > 10 and st_["rejected"] > 10, st_


def test_fcfs_coordinated_mask_equals_isin():
    """``FcfsExpert._coordinated`` (stop 42: the plan holders' rows) is the
    mask ``np.isin(f.vid, plan ids)`` it replaced, through adds and
    removals, with plans of vehicles no longer on the road."""
    from icv_envs.policies.fcfs import FcfsExpert
    from icv_envs.sim.intersection_world import Fleet

    f = Fleet()
    rng = np.random.default_rng(3)
    me = FcfsExpert.__new__(FcfsExpert)
    for _ in range(40):
        f.add(int(rng.integers(0, 5)))
        if f.n:
            f.remove(rng.random(f.n) < 0.3)
        ids = rng.integers(0, f.next_vid + 2, size=int(rng.integers(0, 8)))
        me.plans = {int(v): {} for v in ids}
        want = np.isin(f.vid, np.fromiter(me.plans, dtype=np.int64, count=len(me.plans)))
        got = me._coordinated(f)
        assert got.dtype == bool and np.array_equal(got, want)


def test_fcfs_asks_a_replaced_request():
    """A table whose ``request`` is replaced (on a subclass or on the
    table) is asked through it, not through ``request_prepared``."""
    from icv_envs.envs.intersection_v0 import parallel_env
    from icv_envs.platoon.reservation import ReservationTable

    asked = []

    class Counting(ReservationTable):
        def request(self, vehicle_id, time_steps, tiles_per_step):
            asked.append(vehicle_id)
            return super().request(vehicle_id, time_steps, tiles_per_step)

    env = parallel_env(method="fcfs", throughput=2200.0, duration=120.0)
    obs, infos = env.reset(seed=1)
    old = env.core.expert.table
    tab = Counting(old.tile, old.box_half, old.dt, old.time_buffer)
    env.core.expert.table = tab
    for _ in range(400):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    assert asked and tab.vehicles
