"""The compiled kernels (icv_envs.sim._kernels) against the numpy code they
replaced, on random inputs (hypothesis): same results, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from icv_envs.sim._kernels import drivable_lane_bits, segment_max, sweep_candidates
from icv_envs.sim.road import Obstacle, RoadLayout


def _numpy_sweep(xs, ys, hxs, hys, reach):
    n = len(xs)
    out_a, out_k = [], []
    for k in range(1, n):
        dx = xs[k:] - xs[:-k]
        near = dx < reach
        if not near.any():
            break
        cand = near & (dx < hxs[k:] + hxs[:-k]) & (np.abs(ys[k:] - ys[:-k]) < hys[k:] + hys[:-k])
        a = np.flatnonzero(cand)
        out_a.append(a)
        out_k.append(np.full(len(a), k))
    if not out_a:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_a), np.concatenate(out_k)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 300), span=st.floats(5.0, 3000.0), seed=st.integers(0, 2**31))
def test_sweep_matches_numpy(n, span, seed):
    rng = np.random.default_rng(seed)
    cx = np.sort(rng.uniform(0, span, n))
    cy = rng.integers(0, 4, n) * 4.0 + rng.normal(0, 1.0, n)
    h = rng.normal(0, 0.3, n)
    L, W = rng.uniform(4, 6, n), rng.uniform(1.8, 2.2, n)
    c, s = np.abs(np.cos(h)), np.abs(np.sin(h))
    hx, hy = 0.5 * (L * c + W * s), 0.5 * (L * s + W * c)
    a, k = sweep_candidates(cx, cy, hx, hy, 2.0 * hx.max())
    a0, k0 = _numpy_sweep(cx, cy, hx, hy, 2.0 * hx.max())
    assert np.array_equal(a, a0) and np.array_equal(k, k0)


@settings(max_examples=40, deadline=None)
@given(sizes=st.lists(st.integers(0, 6), min_size=1, max_size=20), seed=st.integers(0, 2**31))
def test_segment_max(sizes, seed):
    v = np.random.default_rng(seed).normal(size=sum(sizes))
    ends = np.cumsum(sizes)
    starts = ends - np.array(sizes)
    got = segment_max(v, starts, ends)
    want = [v[s:e].max() if e > s else -np.inf for s, e in zip(starts, ends)]
    assert np.array_equal(got, np.array(want))


@settings(max_examples=60, deadline=None)
@given(x0=st.floats(-2e4, 2e4), length=st.floats(0.0, 3000.0), periodic=st.booleans(), seed=st.integers(0, 2**31))
def test_drivable_lane_bits_match_road(x0, length, periodic, seed):
    rng = np.random.default_rng(seed)
    obstacles = [Obstacle(int(rng.integers(0, 4)), float(rng.uniform(0, 10_000)), 4.0) for _ in range(rng.integers(0, 3))]
    ends = np.full(4, np.inf) if periodic else np.where(rng.random(4) < 0.3, rng.uniform(0, 10_000, 4), np.inf)
    road = RoadLayout(4, 10_000.0, 4.0, ends, [], [], obstacles, periodic=periodic)
    x1 = x0 + length
    want = sum(1 << lane for lane in road.drivable_main_lanes(x0, x1))
    L = road.length
    span = np.minimum(np.maximum(np.array([x1 - x0]), 0.0), L)
    got = drivable_lane_bits(np.mod(np.array([x0]), L), span, np.array([x0]), np.array([x1]), periodic, L,
                             road.lane_ends, np.asarray(road._ob_lane, dtype=np.int64),
                             np.asarray(road._ob_lo, dtype=np.float64), np.asarray(road._ob_hi, dtype=np.float64),
                             np.ones(4, dtype=bool))
    assert int(got[0]) == want
