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


# ------------------------------------------- formation/_kernels.join_search
def _numpy_join_duration(d0, v0, a0, accel=1.5, decel=3.0, jerk=2.0, t_min=2.0, grow=1.05, max_duration=600.0,
                         v_lo=-np.inf, v_hi=np.inf):
    """The vectorised search join_duration ran before it was compiled (all
    candidates in lockstep, every sample of every profile materialised)."""
    from icv_envs.formation.control import _quintic

    d0, v0, a0 = (np.atleast_1d(np.asarray(x, dtype=np.float64)) for x in (d0, v0, a0))
    hi_a, lo_a = np.maximum(accel, a0), np.minimum(-decel, a0)
    vhi = np.maximum(np.broadcast_to(np.asarray(v_hi, dtype=np.float64), d0.shape), v0)
    vlo = np.minimum(np.broadcast_to(np.asarray(v_lo, dtype=np.float64), d0.shape), v0)
    tau = np.linspace(0.0, 1.0, 201)

    def feasible(T, idx):
        Ti = T[:, None]
        _, v, a, j = _quintic(tau[None, :] * Ti, Ti, d0[idx][:, None], v0[idx][:, None], a0[idx][:, None])
        return ((a.max(axis=1) <= hi_a[idx] + 1e-9) & (a.min(axis=1) >= lo_a[idx] - 1e-9)
                & (np.abs(j).max(axis=1) <= jerk + 1e-9) & (v.max(axis=1) <= vhi[idx] + 1e-9)
                & (v.min(axis=1) >= vlo[idx] - 1e-9)) | (T >= max_duration)

    ad = np.abs(d0)
    est = np.maximum.reduce([np.sqrt(5.7735 * ad / max(accel, decel)), np.cbrt(60.0 * ad / jerk),
                             np.abs(v0) / max(accel, decel)])
    lo = np.maximum(float(t_min), 0.7 * est)
    T = lo.copy()
    bad = np.flatnonzero(~feasible(lo, np.arange(d0.size)))
    if len(bad):
        lo_b = lo[bad]
        hi_b = np.minimum(2.0 * lo_b, max_duration)
        todo = np.ones(len(bad), dtype=bool)
        while todo.any():
            k = np.flatnonzero(todo)
            fk = feasible(hi_b[k], bad[k])
            lo_b[k[~fk]] = hi_b[k[~fk]]
            hi_b[k[~fk]] = np.minimum(2.0 * hi_b[k[~fk]], max_duration)
            todo[k[fk]] = False
        while True:
            k = np.flatnonzero(hi_b > lo_b * grow)
            if not len(k):
                break
            mid = np.sqrt(lo_b[k] * hi_b[k])
            fm = feasible(mid, bad[k])
            hi_b[k[fm]] = mid[fm]
            lo_b[k[~fm]] = mid[~fm]
        T[bad] = hi_b
    return T


_finite_f = st.floats(-200.0, 200.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(_finite_f, st.floats(-25.0, 25.0), st.floats(-6.0, 3.0)), min_size=1, max_size=20),
       st.floats(-30.0, 0.0), st.floats(0.0, 15.0), st.sampled_from([60.0, 120.0, 600.0]))
def test_join_search_equals_the_numpy_search(rows, v_lo, v_hi, max_duration):
    """The compiled duration search (per member, early exit) gives the
    numpy search's durations bit for bit."""
    from icv_envs.formation.control import join_duration

    d0, v0, a0 = (np.array(c, dtype=np.float64) for c in zip(*rows))
    kw = dict(accel=1.5, decel=3.0, jerk=2.0, t_min=2.0, max_duration=max_duration, v_lo=v_lo, v_hi=v_hi)
    np.testing.assert_array_equal(join_duration(d0, v0, a0, **kw), _numpy_join_duration(d0, v0, a0, **kw))
