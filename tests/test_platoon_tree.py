"""Tests for icv_envs.platoon.tree (paper Sec. 4.2, docs/intersection.md#tree-layers)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.platoon import (
    DEFAULT_D_T,
    conflict_model,
    follower_references,
    movement_id,
    node_conflicts,
    reference_positions,
    tree_depths,
    tree_layers,
)

SETTINGS = settings(max_examples=80, deadline=None, database=None)
PAPER = conflict_model("paper").matrix


@st.composite
def conflict_matrices(draw, max_n=8):
    n = draw(st.integers(0, max_n))
    bits = draw(st.lists(st.booleans(), min_size=n * n, max_size=n * n))
    a = np.array(bits, dtype=bool).reshape(n, n)
    c = np.triu(a, 1)
    c = c | c.T
    np.fill_diagonal(c, True)
    return c


def _feasible(c, d):
    """Leader (0) at depth 0 conflicting with all; conflicting i < j need d[i] < d[j]."""
    full = np.ones((len(d), len(d)), dtype=bool)
    full[1:, 1:] = c
    i, j = np.triu_indices(len(d), 1)
    sel = full[i, j]
    return d[0] == 0 and np.all(d[i[sel]] < d[j[sel]])


def test_leader_only_and_simple():
    assert tree_depths(np.zeros((0, 0), dtype=bool)).tolist() == [0]
    assert tree_depths(np.eye(3, dtype=bool)).tolist() == [0, 1, 1, 1]
    assert tree_depths(np.ones((3, 3), dtype=bool)).tolist() == [0, 1, 2, 3]
    # chain 1-2, 2-3 only: 3 can join 1's layer? no, it conflicts with 2 (depth 2) -> 3
    c = np.array([[1, 1, 0], [1, 1, 1], [0, 1, 1]], dtype=bool)
    assert tree_depths(c).tolist() == [0, 1, 2, 3]
    c = np.array([[1, 0, 1], [0, 1, 0], [1, 0, 1]], dtype=bool)
    assert tree_depths(c).tolist() == [0, 1, 1, 2]


@given(c=conflict_matrices())
@SETTINGS
def test_layers_properties(c):
    d = tree_depths(c)
    m = c.shape[0]
    assert d.shape == (m + 1,) and d[0] == 0 and np.all(d[1:] >= 1)
    assert _feasible(c, d)
    layers = tree_layers(d)
    assert layers[0].tolist() == [0]
    assert sorted(np.concatenate(layers).tolist()) == list(range(m + 1))
    for k, layer in enumerate(layers):
        assert len(layer) > 0 and np.all(d[layer] == k)
        real = layer[layer > 0] - 1
        sub = c[np.ix_(real, real)] & ~np.eye(len(real), dtype=bool)
        assert not sub.any()  # no two conflicting nodes share a layer
    # elementwise minimality given earlier depths
    for j in range(1, m + 1):
        prev = [0] + [d[i + 1] for i in range(j - 1) if c[i, j - 1]]
        assert d[j] == 1 + max(prev)


@given(c=conflict_matrices(max_n=5))
@SETTINGS
def test_brute_force_shallowest(c):
    m = c.shape[0]
    d = tree_depths(c)
    best_max = None
    for cand in itertools.product(range(1, m + 1), repeat=m):
        e = np.array((0,) + cand)
        if not _feasible(c, e):
            continue
        # the greedy layering is below every feasible assignment, elementwise
        assert np.all(d <= e)
        best_max = e.max() if best_max is None else min(best_max, e.max())
    assert d.max() == best_max


def test_node_conflicts_and_paper_example():
    # nodes by distance: N-straight, E-straight, N-left, S-straight, N-right, W-straight, S-left
    mv = [movement_id(*p) for p in [("N", "straight"), ("E", "straight"), ("N", "left"),
                                   ("S", "straight"), ("N", "right"), ("W", "straight"),
                                   ("S", "left")]]
    c = node_conflicts(mv, PAPER)
    assert c.shape == (7, 7) and np.array_equal(c, c.T) and c.diagonal().all()
    d = tree_depths(c)
    assert d.tolist() == [0, 1, 2, 3, 4, 3, 5, 6]
    assert [layer.tolist() for layer in tree_layers(d)] == [[0], [1], [2], [3, 5], [4], [6], [7]]
    # two nodes with the same movement conflict (self)
    assert node_conflicts([4, 4], PAPER).all()
    # mutually non-conflicting movements share tree-layer 1 (exclusive lanes: opposing
    # straights and the right turns); under `paper` N-right diverges from N-straight,
    # S-right from S-straight and E-right converges with S-straight into N lane 1
    excl = conflict_model("exclusive").matrix
    assert tree_depths(node_conflicts([1, 7, 2, 8, 5], excl)).tolist() == [0, 1, 1, 1, 1, 1]
    assert tree_depths(node_conflicts([1, 7, 2, 8, 5], PAPER)).tolist() == [0, 1, 1, 2, 2, 2]


@given(mv=st.lists(st.integers(0, 11), min_size=1, max_size=10),
       gaps=st.lists(st.floats(0.0, 50.0), min_size=10, max_size=10),
       lengths=st.lists(st.floats(0.0, 60.0), min_size=10, max_size=10),
       D_t=st.floats(0.0, 40.0))
@SETTINGS
def test_reference_positions_ordering(mv, gaps, lengths, D_t):
    m = len(mv)
    first = 30.0 + np.cumsum(gaps[:m])
    ln = np.array(lengths[:m])
    d = tree_depths(node_conflicts(mv, PAPER))
    x = reference_positions(first, ln, d, D_t)
    assert x.shape == (m + 1,)
    assert x[0] == pytest.approx(first[0] - D_t)
    assert x[1] == pytest.approx(first[0])  # node 1 is on its reference
    full_len = np.concatenate([[0.0], ln])
    for k in range(m + 1):
        for n in range(m + 1):
            if d[n] < d[k]:
                # deeper layers farther by D_t plus the longest formation of each layer in between
                need = sum(D_t + full_len[d == i].max() for i in range(d[n], d[k]))
                assert x[k] - x[n] >= need - 1e-9
                assert x[k] >= x[n] + full_len[n] + D_t - 1e-9
            elif d[n] == d[k]:
                assert x[k] == pytest.approx(x[n])


def test_reference_positions_formula():
    # layers: T1 = {1, 2}, T2 = {3}, T3 = {4}
    d = np.array([0, 1, 1, 2, 3])
    x = reference_positions([40.0, 45.0, 50.0, 80.0], [10.0, 25.0, 5.0, 0.0], d, 10.0)
    x0 = 30.0
    assert x.tolist() == pytest.approx([x0, x0 + 10, x0 + 10, x0 + 20 + 25, x0 + 30 + 25 + 5])


def test_follower_references():
    assert follower_references(100.0, [0.0, 9.0, 18.0]).tolist() == [100.0, 109.0, 118.0]
    first = np.array([50.0, 80.0])
    node = np.array([0, 0, 1])
    assert follower_references(first[node], [0.0, 9.0, 4.5]).tolist() == [50.0, 59.0, 84.5]
    with pytest.raises(ValueError, match="offsets"):
        follower_references(1.0, [-1.0])


def test_default_d_t():
    assert DEFAULT_D_T == 20.0


def test_bad_inputs():
    with pytest.raises(ValueError, match="symmetric"):
        tree_depths(np.array([[1, 1], [0, 1]]))
    with pytest.raises(ValueError, match="square"):
        tree_depths(np.ones((2, 3), dtype=bool))
    with pytest.raises(ValueError, match="booleans"):
        tree_depths(np.array([[1, 2], [2, 1]]))
    with pytest.raises(ValueError, match="nondecreasing"):
        reference_positions([5.0, 3.0], [0.0, 0.0], [0, 1, 1], 10.0)
    with pytest.raises(ValueError, match="depths"):
        reference_positions([5.0, 6.0], [0.0, 0.0], [1, 1, 1], 10.0)
    with pytest.raises(ValueError, match="shapes"):
        reference_positions([5.0, 6.0], [0.0], [0, 1, 1], 10.0)
    with pytest.raises(ValueError, match="D_t"):
        reference_positions([5.0], [0.0], [0, 1], -1.0)
    with pytest.raises(ValueError, match="lengths"):
        reference_positions([5.0], [-2.0], [0, 1], 1.0)
    with pytest.raises(ValueError, match="0..11"):
        node_conflicts([12], PAPER)
    with pytest.raises(ValueError, match="depths"):
        tree_layers([0, -1])


@settings(max_examples=100, deadline=None)
@given(m=st.integers(0, 25), p=st.floats(0.0, 1.0), seed=st.integers(0, 2**31))
def test_compiled_depths_equal_the_written_out_rule(m, p, seed):
    """``tree_depths`` (compiled loop) against the rule of its docstring written
    out in Python, on random symmetric conflict matrices of every density;
    ``_reference_positions`` (unchecked) equals ``reference_positions``."""
    from icv_envs.platoon.tree import _reference_positions, reference_positions, tree_depths

    rng = np.random.default_rng(seed)
    c = rng.random((m, m)) < p
    c = np.triu(c, 1)
    c = c | c.T
    want = [0] + [1] * m
    for k in range(1, m):
        earlier = [want[i + 1] for i in range(k) if c[i, k]]
        want[k + 1] = max(1, 1 + max(earlier)) if earlier else 1
    got = tree_depths(c)
    assert got.dtype == np.int64 and got.tolist() == want
    if m:
        x = np.sort(rng.uniform(-50.0, 300.0, m))
        ln = rng.uniform(0.0, 40.0, m)
        assert np.array_equal(_reference_positions(x, ln, got, 20.0), reference_positions(x, ln, got, 20.0))
