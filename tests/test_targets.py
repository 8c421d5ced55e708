"""Tests for icv_envs.formation.targets (paper Sec. 3.1-3.2, docs/formation.md#target-equation)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.formation import (
    GEOMETRIES,
    formation_length,
    formation_targets,
    interlaced_targets,
    parallel_targets,
)

LS = 20.0

n_vehicles_st = st.integers(min_value=0, max_value=60)
n_lanes_st = st.integers(min_value=1, max_value=6)
spacing_st = st.floats(min_value=0.5, max_value=100.0, allow_nan=False, allow_infinity=False)
geometry_st = st.sampled_from(GEOMETRIES)
SETTINGS = settings(max_examples=80, deadline=None, database=None)


def _layers(x: np.ndarray, spacing: float, per_layer: float) -> np.ndarray:
    return np.floor(x / (per_layer * spacing) + 1e-9).astype(np.int64)


# ---------------------------------------------------------------------------
# paper examples
# ---------------------------------------------------------------------------
def test_table_five_lanes():
    x, lane = interlaced_targets(10, 5, LS)
    expected = [(0, 1), (0, 3), (0, 5), (1, 2), (1, 4), (2, 1), (2, 3), (2, 5), (3, 2), (3, 4)]
    assert list(zip((x / LS).tolist(), lane.tolist())) == [(float(a), b) for a, b in expected]
    assert x.dtype == np.float64 and lane.dtype == np.int64
    assert x.shape == lane.shape == (10,)


def test_caption_4_vehicles():
    # Fig. 2a: one layer containing two sublayers.
    x, lane = interlaced_targets(4, 5, LS)
    assert set(x.tolist()) == {0.0, LS}
    assert lane[x == 0.0].tolist() == [1, 3, 5]
    assert lane[x == LS].tolist() == [2]


def test_caption_7_vehicles():
    # Fig. 2b: two layers, the first full, the second has one sublayer.
    x, lane = interlaced_targets(7, 5, LS)
    assert set(x[:5].tolist()) == {0.0, LS}
    assert sorted(lane[:5].tolist()) == [1, 2, 3, 4, 5]
    assert set(x[5:].tolist()) == {2 * LS}
    assert set(lane[5:].tolist()) <= {1, 3, 5}


def test_caption_9_vehicles():
    # Fig. 2c: two layers, the first full, the second has two sublayers.
    x, lane = interlaced_targets(9, 5, LS)
    assert set(x[:5].tolist()) == {0.0, LS}
    assert set(x[5:].tolist()) == {2 * LS, 3 * LS}
    assert lane[5:].tolist() == [1, 3, 5, 2]


def test_single_lane_is_compressed_platoon():
    x, lane = interlaced_targets(5, 1, 12.5)
    np.testing.assert_array_equal(x, [0.0, 12.5, 25.0, 37.5, 50.0])
    np.testing.assert_array_equal(lane, [1, 1, 1, 1, 1])
    assert formation_length(5, 1, 12.5) == 50.0


def test_empty_and_single():
    for g in GEOMETRIES:
        x, lane = formation_targets(0, 3, geometry=g)
        assert x.shape == lane.shape == (0,)
        assert x.dtype == np.float64 and lane.dtype == np.int64
        assert formation_length(0, 3, geometry=g) == 0.0
        assert formation_length(1, 3, geometry=g) == 0.0


def test_parallel_example():
    x, lane = parallel_targets(7, 3, 10.0)
    np.testing.assert_array_equal(x, [0, 0, 0, 10, 10, 10, 20])
    np.testing.assert_array_equal(lane, [1, 2, 3, 1, 2, 3, 1])


def test_dispatch_matches():
    for g, fn in (("interlaced", interlaced_targets), ("parallel", parallel_targets)):
        a = formation_targets(11, 4, 15.0, geometry=g)
        b = fn(11, 4, 15.0)
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])


def test_accepts_numpy_integers():
    x, lane = interlaced_targets(np.int64(6), np.int32(3), np.float64(5.0))
    assert x.shape == (6,)


# ---------------------------------------------------------------------------
# properties
# ---------------------------------------------------------------------------
@SETTINGS
@given(n=n_vehicles_st, n_l=n_lanes_st, ls=spacing_st, g=geometry_st)
def test_common_properties(n, n_l, ls, g):
    x, lane = formation_targets(n, n_l, ls, geometry=g)
    assert x.shape == lane.shape == (n,)
    assert x.dtype == np.float64 and lane.dtype == np.int64
    if n == 0:
        return
    # lanes in range, x >= 0 and nondecreasing, first target front-left
    assert lane.min() >= 1 and lane.max() <= n_l
    assert np.all(x >= 0.0)
    assert np.all(np.diff(x) >= 0.0)
    assert x[0] == 0.0 and lane[0] == 1
    # unique targets
    pairs = set(zip(np.round(x / ls).astype(int).tolist(), lane.tolist()))
    assert len(pairs) == n
    # x is a multiple of the spacing
    np.testing.assert_allclose(x / ls, np.round(x / ls), atol=1e-9)
    # formation length
    assert formation_length(n, n_l, ls, geometry=g) == pytest.approx(x.max(), abs=0.0)
    # index-based layers (groups of n_l consecutive targets): one target per lane,
    # full layers hold every lane
    for start in range(0, n, n_l):
        grp = lane[start:start + n_l]
        assert len(set(grp.tolist())) == len(grp)
        if len(grp) == n_l:
            assert sorted(grp.tolist()) == list(range(1, n_l + 1))


@SETTINGS
@given(n=n_vehicles_st, n_l=n_lanes_st, ls=spacing_st, extra=st.integers(0, 20), g=geometry_st)
def test_prefix_property(n, n_l, ls, extra, g):
    x, lane = formation_targets(n, n_l, ls, geometry=g)
    x2, lane2 = formation_targets(n + extra, n_l, ls, geometry=g)
    np.testing.assert_array_equal(x, x2[:n])
    np.testing.assert_array_equal(lane, lane2[:n])


@SETTINGS
@given(n=n_vehicles_st, n_l=st.integers(min_value=2, max_value=6), ls=spacing_st)
def test_interlaced_sublayers(n, n_l, ls):
    x, lane = interlaced_targets(n, n_l, ls)
    if n == 0:
        return
    sub = np.round(x / ls).astype(int)
    # adjacent occupied sublayers are exactly L_s apart (no empty sublayer)
    assert set(np.diff(np.unique(sub)).tolist()) <= {1}
    # within one sublayer, no two lanes adjacent
    for s in np.unique(sub):
        lanes = np.sort(lane[sub == s])
        assert np.all(np.diff(lanes) >= 2)
    # geometric layers (two sublayers each) hold at most one target per lane
    layer = _layers(x, ls, 2.0)
    for m in np.unique(layer):
        lanes = lane[layer == m]
        assert len(set(lanes.tolist())) == len(lanes)
    # the first sublayer of a layer has odd lanes, the second even lanes
    assert np.all((lane[sub % 2 == 0] % 2) == 1)
    assert np.all((lane[sub % 2 == 1] % 2) == 0)


@SETTINGS
@given(n=n_vehicles_st, ls=spacing_st)
def test_interlaced_single_lane_property(n, ls):
    x, lane = interlaced_targets(n, 1, ls)
    np.testing.assert_allclose(x, np.arange(n) * ls)
    assert np.all(lane == 1)


@SETTINGS
@given(n=n_vehicles_st, n_l=n_lanes_st, ls=spacing_st)
def test_parallel_properties(n, n_l, ls):
    x, lane = parallel_targets(n, n_l, ls)
    if n == 0:
        return
    layer = np.round(x / ls).astype(int)
    # layers are L_s apart, consecutive, each fills lanes from the left
    np.testing.assert_array_equal(layer, np.arange(n) // n_l)
    for m in np.unique(layer):
        lanes = lane[layer == m]
        np.testing.assert_array_equal(lanes, np.arange(1, len(lanes) + 1))
    assert formation_length(n, n_l, ls, "parallel") == pytest.approx(((n - 1) // n_l) * ls)


@SETTINGS
@given(n=st.integers(2, 60), n_l=n_lanes_st)
def test_interlaced_longer_than_parallel(n, n_l):
    # the interlaced formation trades density for flexibility (paper Sec. 3.1)
    assert formation_length(n, n_l, geometry="interlaced") >= formation_length(
        n, n_l, geometry="parallel"
    )


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("fn", [interlaced_targets, parallel_targets, formation_targets,
                                formation_length])
@pytest.mark.parametrize(
    "args, match",
    [
        ((3, 0, 20.0), r"n_lanes.*0"),
        ((3, -2, 20.0), r"n_lanes.*-2"),
        ((-1, 3, 20.0), r"n_vehicles.*-1"),
        ((2.5, 3, 20.0), r"n_vehicles.*2\.5"),
        ((3, 2.0, 20.0), r"n_lanes.*2\.0"),
        ((True, 3, 20.0), r"n_vehicles.*True"),
        ((3, 3, 0.0), r"spacing.*0\.0"),
        ((3, 3, -5.0), r"spacing.*-5\.0"),
        ((3, 3, float("nan")), r"spacing.*nan"),
        ((3, 3, float("inf")), r"spacing.*inf"),
        ((3, 3, "20"), r"spacing.*'20'"),
    ],
)
def test_bad_input(fn, args, match):
    with pytest.raises(ValueError, match=match):
        fn(*args)


@pytest.mark.parametrize("fn", [formation_targets, formation_length])
@pytest.mark.parametrize("geometry", ["diamond", "Interlaced", "", None])
def test_unknown_geometry(fn, geometry):
    with pytest.raises(ValueError, match="unknown formation geometry") as info:
        fn(3, 3, 20.0, geometry=geometry)
    assert repr(geometry) in str(info.value)
    assert "interlaced" in str(info.value) and "parallel" in str(info.value)


def test_formation_managers_share_read_only_targets():
    """Stop 52: the targets a formation manager re-forms to are memoised for
    the process (each reset's new manager started an empty memo before):
    equal to formation_targets, read-only, shared between managers of one
    spacing and geometry, not between different ones."""
    from icv_envs.formation.targets import formation_targets
    from icv_envs.sim.formations import FormationManager

    a, b = FormationManager(spacing=20.0), FormationManager(spacing=20.0)
    c = FormationManager(spacing=25.0, geometry="parallel")
    for n, lanes in ((1, 1), (7, 3), (12, 4), (0, 2)):
        ta, tb, tc = a.targets(n, lanes), b.targets(n, lanes), c.targets(n, lanes)
        for got, want in zip(ta, formation_targets(n, lanes, 20.0)):
            np.testing.assert_array_equal(got, want)
            assert got.dtype == want.dtype and not got.flags.writeable
        assert all(x is y for x, y in zip(ta, tb))
        for got, want in zip(tc, formation_targets(n, lanes, 25.0, "parallel")):
            np.testing.assert_array_equal(got, want)
