"""The compiled kernels (icv_envs.sim._kernels) against the numpy code they
replaced, on random inputs (hypothesis): same results, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from pinned_numpy import at_pinned_level

from icv_envs.sim._kernels import drivable_lane_bits, sweep_candidates
from icv_envs.sim._kernels.formation import drivable_lane_bits1
from icv_envs.sim.formations import FormationManager
from icv_envs.sim.road import Obstacle, RoadLayout
from icv_envs.sim.traffic import LaneIndex, occupied_lanes, rect_overlap


def _random_road(rng, ramps=(), periodic=False, obstacles_below=4):
    """A three-lane 2 km road for the road kernels' tests: up to
    ``obstacles_below - 1`` random obstacles (inside [10, 1990] m on a ring,
    off its seam), random lane ends on a straight road, on-ramps over
    ``ramps`` ((start, end) pairs)."""
    from icv_envs.sim.road import OnRamp

    lo, hi = (10.0, 1_990.0) if periodic else (0.0, 2_000.0)
    obstacles = [Obstacle(int(rng.integers(0, 3)), float(rng.uniform(lo, hi)), 4.0)
                 for _ in range(rng.integers(0, obstacles_below))]
    ends = np.full(3, np.inf) if periodic else np.where(rng.random(3) < 0.4, rng.uniform(0, 2_000, 3), np.inf)
    return RoadLayout(3, 2_000.0, 4.0, ends, [OnRamp(a, b) for a, b in ramps], [], obstacles, periodic=periodic)


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


def _numpy_hold_targets(grp, gids, A, chg, r, tb, cx, d_members, vid, deadline, time, max_lead, brake_step,
                        stall_error, road):
    """The array code of FormationManager._hold_targets that
    :func:`~icv_envs.sim._kernels.hold_targets` replaced (segments of a
    stable sort by formation id, a segment maximum), frozen here."""
    def seg_max(values, starts, ends):
        out = np.full(len(starts), -np.inf)
        for g in range(len(starts)):
            for i in range(starts[g], ends[g]):
                if values[i] > out[g]:
                    out[g] = values[i]
        return out

    A = A.copy()
    order_rows = np.argsort(grp, kind="stable")
    sorted_g = grp[order_rows]
    starts = np.searchsorted(sorted_g, gids, side="left")
    ends = np.searchsorted(sorted_g, gids, side="right")
    has = ends > starts
    counts = ends - starts
    seg_end = np.cumsum(counts)
    seg_start = seg_end - counts
    pos = np.arange(int(seg_end[-1])) - np.repeat(seg_start - starts, counts)
    rr = order_rows[pos]
    kk = np.repeat(np.arange(len(gids)), counts)
    m = np.flatnonzero(grp >= 0)
    at = np.empty(len(grp), dtype=np.int64)
    at[m] = np.arange(len(m))
    implied = seg_max(road.wrap(cx[rr] + tb[rr] - A[kk]) - d_members[at[rr]], seg_start, seg_end)
    back = np.where(~chg & (implied < -max_lead), implied + max_lead, 0.0)
    back = np.where(r < 0, np.minimum(back, r), back)
    brake = has & (back < 0)
    A[brake] = road.mod(A[brake] + np.maximum(back[brake], brake_step))
    late_rows = (np.abs(road.wrap(cx[rr] - (A[kk] - tb[rr]))) > stall_error) & (time > deadline[vid[rr]])
    late = seg_max(late_rows.astype(np.float64), seg_start, seg_end) > 0.5
    return A, has, brake, late


@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 60), n_gids=st.integers(1, 12), periodic=st.booleans(), seed=st.integers(0, 2**31))
def test_hold_targets_equals_the_array_code(n, n_gids, periodic, seed):
    """Front-target brake and stall flags of the formation layer: the
    compiled pass equals the array code it replaced, bit for bit (members
    of ids not asked about, formations without members, re-forming ones,
    no room / negative room, ring seams)."""
    from icv_envs.sim._kernels import hold_targets

    rng = np.random.default_rng(seed)
    road = _random_road(rng, periodic=periodic)
    L = float(road.length)
    gids = np.sort(rng.choice(20, n_gids, replace=False)).tolist()
    pool = np.array(gids + [-1, -1, 19 if 19 not in gids else -1])
    grp = rng.choice(pool, n).astype(np.int64)
    G = len(gids)
    A = rng.uniform(0.0, L, G)
    chg = rng.random(G) < 0.3
    r = np.where(rng.random(G) < 0.3, np.nan, rng.uniform(-30.0, 60.0, G))
    tb = rng.choice([0.0, 8.0, 16.0, 24.0], n)
    cx = np.where(rng.random(n) < 0.5, A[rng.integers(0, G, n)] - tb + rng.normal(0, 30.0, n), rng.uniform(0, L, n))
    cx = np.mod(cx, L) if periodic else cx
    d_members = rng.normal(0.0, 20.0, int((grp >= 0).sum()))
    vid = rng.permutation(n + 5)[:n].astype(np.int64)
    deadline = rng.uniform(0.0, 100.0, n + 5)
    time, max_lead, brake_step, stall_error = float(rng.uniform(0, 100)), 10.0, -0.04 * 2.0, 5.0
    want = _numpy_hold_targets(grp, np.array(gids), A, chg, r, tb, cx, d_members, vid, deadline, time, max_lead,
                               brake_step, stall_error, road)
    slot = np.full(max(gids) + 1, -1, dtype=np.int64)
    slot[gids] = np.arange(G)
    A_got = A.copy()
    has, brake, late = hold_targets(grp, slot, A_got, chg, r, tb, cx, d_members, vid, deadline, time, max_lead,
                                    brake_step, stall_error, L if periodic else -1.0)
    for g, w in zip((A_got, has, brake, late), want):
        np.testing.assert_array_equal(g, w)


@settings(max_examples=60, deadline=None)
@given(x0=st.floats(-2e4, 2e4), length=st.floats(0.0, 3000.0), periodic=st.booleans(), seed=st.integers(0, 2**31))
@example(x0=0.0, length=0.0, periodic=True, seed=61137)  # (an obstacle across the seam before: CI, stop 44)
def test_drivable_lane_bits_match_road(x0, length, periodic, seed):
    rng = np.random.default_rng(seed)
    # (obstacles 4 m long whose stretch lies inside [0, 10 km): on a ring, RoadLayout rejects one that
    # straddles the seam, which a centre drawn from [0, 10 km) gave about once in a hundred runs)
    obstacles = [Obstacle(int(rng.integers(0, 4)), float(rng.uniform(2.0, 10_000 - 2.0)), 4.0)
                 for _ in range(rng.integers(0, 3))]
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
    # the one-window kernel and the manager's lane set built on it (with an allowed-lane mask)
    args = (road.lane_ends, np.asarray(road._ob_lane, dtype=np.int64), np.asarray(road._ob_lo, dtype=np.float64),
            np.asarray(road._ob_hi, dtype=np.float64))
    assert drivable_lane_bits1(x0, x1, periodic, L, *args, np.ones(4, dtype=bool)) == want
    allowed = tuple(int(v) for v in np.flatnonzero(rng.random(5) < 0.6))  # lane 4 does not exist: ignored
    fm = FormationManager(allowed_lanes=allowed, lookahead=float(rng.uniform(0.0, 400.0)))
    anchor, flen = x0 + fm.lookahead * 0.5, float(rng.uniform(0.0, 200.0))
    lanes = road.drivable_main_lanes(anchor - flen - 10.0, anchor + fm.lookahead)
    assert fm._lane_set(road, anchor, flen) == tuple(lane for lane in lanes if lane in allowed)


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


# ------------------------------------------------ the fused physics substep
@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 60), periodic=st.booleans(), limit=st.booleans(), seed=st.integers(0, 2**31))
def test_kinematic_substep_equals_traffic_step(n, periodic, limit, seed):
    """kinematic_substep gives Traffic.step's state (with the crashed
    override and the standing time of World.substep) and Traffic.center's
    body centres, bit for bit where NumPy's SIMD dispatch is at most AVX2
    (X86_V3): the compiled code calls libm's sin, cos, tan and atan, as
    NumPy's float64 ufuncs do there. NumPy's AVX-512 kernels (SVML) round
    tan and atan differently in the last bit, so in a process that runs
    them the check allows 1e-9 (the end-to-end bit-identity is checked in
    the pinned process of tests/test_trajectory_hash.py)."""
    from trajectory_hash import _active_targets_above

    from icv_envs.sim._kernels import kinematic_substep
    from icv_envs.sim.traffic import Traffic

    rng = np.random.default_rng(seed)
    period = 10_000.0 if periodic else None
    tr = Traffic(2.8, period=period, lat_accel_max=4.9 if limit else None)
    tr.x = rng.uniform(-50.0, 10_050.0, n) if not periodic else rng.uniform(0.0, 10_000.0, n)
    tr.y = rng.uniform(-2.0, 14.0, n)
    tr.heading = rng.normal(0.0, 0.2, n)
    tr.speed = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(0.0, 32.0, n))
    tr.crashed = rng.random(n) < 0.2
    tr.stopped_for = np.where(rng.random(n) < 0.5, rng.uniform(0.0, 40.0, n), 0.0)
    a = rng.uniform(-6.0, 3.0, n)
    phi = rng.uniform(-0.6, 0.6, n)
    got = kinematic_substep(tr.x, tr.y, tr.heading, tr.speed, a, phi, tr.crashed, tr.stopped_for, 2.8,
                            4.9 if limit else -1.0, 0.04, 30.0, -1.0 if period is None else period)
    st0 = tr.stopped_for
    tr.step(np.where(tr.crashed, -6.0, a), np.where(tr.crashed, 0.0, phi), 0.04, 30.0)
    cx, cy = tr.center()
    want = (tr.x, tr.y, tr.heading, tr.speed, tr.accel, tr.steer, np.where(tr.speed < 0.1, st0 + 0.04, 0.0), cx, cy)
    exact = not _active_targets_above()
    for g, w in zip(got, want):
        if exact:
            np.testing.assert_array_equal(g, w)
        else:
            np.testing.assert_allclose(g, w, rtol=0.0, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 60), ramp=st.booleans(), seed=st.integers(0, 2**31))
def test_road_check_equals_lane_of_and_available(n, ramp, seed):
    from icv_envs.sim._kernels import road_check

    rng = np.random.default_rng(seed)
    road = _random_road(rng, [(300.0, 500.0)] if ramp else [], obstacles_below=3)
    cx = rng.uniform(-20.0, 2_020.0, n)
    cy = rng.uniform(-4.0, 4.0 * road.total_lanes + 2.0, n)
    lane, off, at_end, n_off, n_end = road_check(cx, cy, road.lane_width, road.n_lanes, road.total_lanes,
                                                 road.lane_ends, road._ob_lane, road._ob_lo, road._ob_hi,
                                                 road._ramp_iv, 0.5, road.length)
    want_lane = road.lane_of(cy)
    want_off = ~road.available(want_lane, cx) | (np.abs(cy - want_lane * road.lane_width) > 0.5 * road.lane_width + 0.5)
    want_end = cx >= road.length
    want_off &= ~want_end
    np.testing.assert_array_equal(lane, want_lane)
    np.testing.assert_array_equal(off, want_off)
    np.testing.assert_array_equal(at_end, want_end)
    assert (n_off, n_end) == (int(want_off.sum()), int(want_end.sum()))


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 1200), seed=st.integers(0, 2**31))
def test_pairwise_sum_rounds_as_numpy_sum(n, seed):
    from icv_envs.sim._kernels import pairwise_sum

    rng = np.random.default_rng(seed)
    a = rng.standard_normal(n) * 10.0 ** rng.uniform(-6, 6, n)
    lo = int(rng.integers(0, 4)) if n > 4 else 0
    assert pairwise_sum(a, lo, n - lo) == a[lo:].sum()


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 300), sorted_ids=st.booleans(), seed=st.integers(0, 2**31))
def test_motion_record_equals_numpy(n, sorted_ids, seed):
    """MotionStats.record (compiled) accumulates exactly what the numpy
    expressions it replaced did."""
    from icv_envs.sim.metrics import STOPPED_SPEED, MotionStats

    rng = np.random.default_rng(seed)
    vid = np.sort(rng.choice(2 * n, n, replace=False)) if sorted_ids else rng.integers(0, n, n)
    v0, v1 = rng.uniform(0, 30, n), np.where(rng.random(n) < 0.1, 0.0, rng.uniform(0, 30, n))
    a = rng.uniform(-6, 3, n)
    m = MotionStats()
    m.record(vid, v0, v1, a, 0.04)
    m.record(vid, v1, v0, -a, 0.04)
    cnt, s1, s2 = np.zeros(2 * n, np.int64), np.zeros(2 * n), np.zeros(2 * n)
    tot = [0.0, 0.0, 0.0, 0]
    for p, q, c in ((v0, v1, a), (v1, v0, -a)):
        tot[0] += float(q.sum())
        tot[1] += float(np.abs(q - p).sum()) / 0.04
        tot[2] += float(np.abs(c).sum())
        tot[3] += int((q < STOPPED_SPEED).sum())
        np.add.at(cnt, vid, 1)
        np.add.at(s1, vid, q)
        np.add.at(s2, vid, q * q)
    assert (m.speed_sum, m.realised_abs_accel_sum, m.commanded_abs_accel_sum, m.stopped_steps) == tuple(tot)
    k = int(vid.max()) + 1
    assert len(m._n) >= k
    np.testing.assert_array_equal(m._n[:k], cnt[:k])
    np.testing.assert_array_equal(m._s1[:k], s1[:k])
    np.testing.assert_array_equal(m._s2[:k], s2[:k])
    with pytest.raises(ValueError, match="one length"):
        m.record(vid, v0[:-1] if n > 1 else v0[:0], v1, a, 0.04)


# ------------------------------------------------- collisions compiled whole
def _numpy_find_collisions(cx, cy, heading, length, width, period: float | None = None):
    """traffic.find_collisions as numpy code, before it was compiled whole (the reference)."""
    n = len(cx)
    if n < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if period is not None:
        # ring: vehicles near the seam get a ghost one lap on; pairs found
        # through a ghost are mapped back to real rows
        near = np.flatnonzero(cx < 2.0 * float(np.max(length)) + 1.0)
        if len(near):
            idx = np.concatenate([np.arange(n), near])
            gi, gj = _numpy_find_collisions(
                np.concatenate([cx, cx[near] + period]), cy[idx], heading[idx], length[idx], width[idx]
            )
            a, b = idx[gi], idx[gj]
            keep = a != b
            pairs = {(min(x, y), max(x, y)) for x, y in zip(a[keep].tolist(), b[keep].tolist())}
            if not pairs:
                return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
            arr = np.array(sorted(pairs), dtype=np.int64)
            return arr[:, 0], arr[:, 1]
    c, s = np.abs(np.cos(heading)), np.abs(np.sin(heading))
    hx = 0.5 * (length * c + width * s)
    hy = 0.5 * (length * s + width * c)
    order = np.argsort(cx, kind="stable")
    xs, ys, hxs, hys = cx[order], cy[order], hx[order], hy[order]
    reach = 2.0 * hxs.max()
    a, k = _numpy_sweep(xs, ys, hxs, hys, reach)
    if not len(a):
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    i = order[a]
    j = order[a + k]
    hit = rect_overlap(cx[i], cy[i], heading[i], length[i], width[i], cx[j], cy[j], heading[j], length[j], width[j])
    return i[hit], j[hit]


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 60), frames=st.integers(1, 6), periodic=st.booleans(), limit=st.booleans(),
       seed=st.integers(0, 2**31))
def test_kinematic_substep_carry_equals_kinematic_substep(n, frames, periodic, limit, seed):
    """Stop 43: the frames' integration carrying the heading's cosine and
    sine and the steering's tangent from frame to frame gives
    kinematic_substep's state frame by frame, bit for bit (the same libm
    calls on the same doubles; both compiled, so no NumPy SIMD question),
    and leaves the new headings' cos and sin, which the collision test
    takes. Steering values include signed zeros and the lateral limit
    (which changes the angle as the speed changes)."""
    from icv_envs.sim._kernels import kinematic_substep
    from icv_envs.sim._kernels.physics import kinematic_substep_carry

    rng = np.random.default_rng(seed)
    period = 10_000.0 if periodic else -1.0
    x = rng.uniform(0.0, 10_000.0, n)
    y = rng.uniform(-2.0, 14.0, n)
    h = np.where(rng.random(n) < 0.3, -0.0, rng.normal(0.0, 0.3, n))
    v = np.where(rng.random(n) < 0.2, 0.0, rng.uniform(0.0, 32.0, n))
    crashed = rng.random(n) < 0.2
    sf = np.where(rng.random(n) < 0.5, rng.uniform(0.0, 40.0, n), 0.0)
    a = rng.uniform(-6.0, 3.0, n)
    phi = rng.choice([0.0, -0.0, 0.3, -0.6], n) if seed % 2 else rng.uniform(-0.6, 0.6, n)
    lat = 4.9 if limit else -1.0
    trig = np.empty((4, n))
    s1 = s2 = (x, y, h, v, a, phi, sf)
    for f in range(frames):
        # (the frames' callers keep the controls; the carry holds even when
        # they change: a zero steering angle flips its sign every frame)
        phi = np.where(phi == 0.0, -phi, phi)
        w = kinematic_substep(s1[0], s1[1], s1[2], s1[3], a, phi, crashed, s1[6], 2.8, lat, 0.04, 30.0, period)
        g = kinematic_substep_carry(s2[0], s2[1], s2[2], s2[3], a, phi, crashed, s2[6], 2.8, lat, 0.04, 30.0,
                                    period, trig, f == 0)
        for gi, wi in zip(g, w):
            np.testing.assert_array_equal(gi, wi)
            assert np.array_equal(np.signbit(gi), np.signbit(wi))
        np.testing.assert_array_equal(trig[0], _libm(w[2], "cos"))
        np.testing.assert_array_equal(trig[1], _libm(w[2], "sin"))
        s1, s2 = w, g


@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 60), lat=st.sampled_from([0.0, 1.0, 4.9, 9.0]), seed=st.integers(0, 2**31))
def test_steering_limit_skips_atan_only_where_it_cannot_bind(n, lat, seed):
    """Stop 52: the substep calls ``atan(z)`` (``z = lat L / max(v^2,
    1e-9)``) only when the steering angle is not below ``0.99 z / (1 + z)``,
    a lower bound of ``atan(z)``; the angle it keeps equals
    ``min(max(s, -atan(z)), atan(z))`` with libm's ``atan`` bit for bit
    (signed zeros too) for angles drawn around that bound and around
    ``atan(z)`` itself, at speeds from standing to 40 m/s."""
    import math

    from icv_envs.sim._kernels import kinematic_substep

    rng = np.random.default_rng(seed)
    v = np.where(rng.random(n) < 0.1, 0.0, rng.uniform(0.0, 40.0, n))
    z = lat * 2.8 / np.maximum(v * v, 1e-9)
    pm = np.array([math.atan(q) for q in z])
    lb = 0.99 * z / (1.0 + z)
    base = np.choose(rng.integers(0, 4, n), [pm, lb, rng.uniform(0.0, 0.6, n), np.zeros(n)])
    s = base * rng.choice([1.0 - 1e-15, 1.0, 1.0 + 1e-15, 0.999, 1.001], n) * rng.choice([1.0, -1.0], n)
    s = np.where(rng.random(n) < 0.05, -0.0, s)
    zeros = np.zeros(n)
    got = kinematic_substep(zeros, zeros, zeros, v, zeros, s, np.zeros(n, dtype=bool), zeros, 2.8, lat, 0.04, 60.0,
                            -1.0)[5]
    want = np.array([min(max(a, -p), p) for a, p in zip(s.tolist(), pm.tolist())])
    np.testing.assert_array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))


def _libm(a, name):
    """``math.cos``/``math.sin`` of each value (libm's, as the kernels call it)."""
    import math

    return np.array([getattr(math, name)(float(t)) for t in a])


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 80), span=st.floats(5.0, 400.0), periodic=st.booleans(), seed=st.integers(0, 2**31))
def test_collision_pairs_from_cos_sin_equal_collision_pairs(n, span, periodic, seed):
    """Stop 43: the collision sweeps given the headings' cosines and sines
    find the same pairs in the same order as from the headings (the
    highway's frames and the intersection box's sweep along x)."""
    from icv_envs.sim._kernels import collision_pairs
    from icv_envs.sim._kernels.intersection import box_collision_pairs, box_collision_pairs_cs
    from icv_envs.sim._kernels.neighbours import collision_pairs_cs

    rng = np.random.default_rng(seed)
    cx = rng.uniform(0, span, n)
    cy = rng.integers(0, 3, n) * 4.0 + rng.normal(0, 1.2, n)
    h = rng.normal(0, 0.4, n)
    L, W = rng.uniform(4, 6, n), rng.uniform(1.8, 2.2, n)
    ch, sh = _libm(h, "cos"), _libm(h, "sin")
    for g, w in zip(collision_pairs_cs(cx, cy, ch, sh, L, W, span if periodic else -1.0),
                    collision_pairs(cx, cy, h, L, W, span if periodic else -1.0)):
        np.testing.assert_array_equal(g, w)
    # the box: both legs' directions, vehicles around a 20 m box
    bx = rng.uniform(-40.0, 40.0, n)
    by = rng.uniform(-40.0, 40.0, n)
    hb = rng.choice([0.0, 0.5 * np.pi, np.pi, -0.5 * np.pi], n) + rng.normal(0, 0.3, n)
    cb, sb = _libm(hb, "cos"), _libm(hb, "sin")
    for g, w in zip(box_collision_pairs_cs(bx, by, hb, cb, sb, L, W, 10.0), box_collision_pairs(bx, by, hb, L, W, 10.0)):
        np.testing.assert_array_equal(g, w)


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 80), span=st.floats(5.0, 400.0), periodic=st.booleans(), seed=st.integers(0, 2**31))
def test_collision_pairs_equal_the_numpy_code(n, span, periodic, seed):
    """Dense traffic (many overlaps, ghosts at the seam of a short ring):
    the compiled find_collisions finds the numpy code's pairs in its order."""
    from icv_envs.sim.traffic import find_collisions

    rng = np.random.default_rng(seed)
    period = span if periodic else None
    cx = rng.uniform(0, span, n)
    cy = rng.integers(0, 3, n) * 4.0 + rng.normal(0, 1.2, n)
    h = rng.normal(0, 0.4, n)
    L, W = rng.uniform(4, 6, n), rng.uniform(1.8, 2.2, n)
    got = find_collisions(cx, cy, h, L, W, period=period)
    want = _numpy_find_collisions(cx, cy, h, L, W, period=period)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, np.asarray(w, dtype=np.int64))


# ------------------------------------------- lane index and leaders compiled
def _numpy_lane_index(cx, cy, width, lane_width, n_lanes, road_length, periodic: bool = False, ghost: float = 1000.0,
                      reserved_lane=None, length=None, heading=None):
    """traffic.lane_index as numpy code, before it was compiled (the reference)."""
    rows, lanes = occupied_lanes(cy, width, lane_width, n_lanes, length=length, heading=heading)
    if reserved_lane is not None:
        res = np.flatnonzero((reserved_lane >= 0) & (reserved_lane < n_lanes))
        if len(res):
            pair = np.concatenate([rows, res]) * (n_lanes + 1) + np.concatenate([lanes, reserved_lane[res]])
            _, first = np.unique(pair, return_index=True)
            rows = np.concatenate([rows, res])[np.sort(first)]
            lanes = np.concatenate([lanes, reserved_lane[res]])[np.sort(first)]
    xs = cx[rows]
    if periodic and len(rows):
        L = float(road_length)
        g = min(ghost, 0.5 * L)
        lo, hi = xs < g, xs > L - g
        rows = np.concatenate([rows, rows[lo], rows[hi]])
        lanes = np.concatenate([lanes, lanes[lo], lanes[hi]])
        xs = np.concatenate([xs, xs[lo] + L, xs[hi] - L])
    offset = 4.0 * (abs(road_length) + 1e4)
    keys = lanes * offset + xs
    order = np.argsort(keys, kind="stable")
    return LaneIndex(keys[order], rows[order], lanes[order], xs[order], offset)


def _numpy_leaders(index, q_rows, q_lanes, cx, return_x: bool = False):
    """traffic.leaders as numpy code, before it was compiled (the reference)."""
    q_rows = np.asarray(q_rows, dtype=np.int64)
    q_lanes = np.asarray(q_lanes, dtype=np.int64)
    out = np.full(len(q_rows), -1, dtype=np.int64)
    xo = np.full(len(q_rows), np.inf)
    nk = len(index.keys)
    if not nk:
        return (out, xo) if return_x else out
    qk = q_lanes * index.offset + cx[q_rows]
    pos = np.searchsorted(index.keys, qk, side="left")
    todo = np.ones(len(q_rows), dtype=bool)
    for j in range(3):  # skip the vehicle's own entry (it appears at most once per lane)
        p = np.minimum(pos + j, nk - 1)
        ok = todo & (pos + j < nk) & (index.lanes[p] == q_lanes) & (index.rows[p] != q_rows)
        out[ok] = index.rows[p[ok]]
        xo[ok] = index.x[p[ok]]
        todo &= ~ok & (pos + j < nk) & (index.lanes[p] == q_lanes)
    return (out, xo) if return_x else out


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 120), periodic=st.booleans(), footprint=st.booleans(), reserve=st.booleans(),
       seed=st.integers(0, 2**31))
def test_lane_index_and_leaders_equal_the_numpy_code(n, periodic, footprint, reserve, seed):
    """The compiled index lists the numpy code's (row, lane, x) entries in
    its order, with the same keys; leaders() finds the same rows and x."""
    from icv_envs.sim.traffic import lane_index, leaders

    rng = np.random.default_rng(seed)
    L = 3000.0
    cx = rng.uniform(0, L, n)
    cx[: n // 4] = cx[n // 4: 2 * (n // 4)]  # vehicles exactly alongside (identical x)
    cy = rng.uniform(-1.0, 13.0, n)
    w, ln, h = rng.uniform(1.8, 2.2, n), rng.uniform(4, 6, n), rng.normal(0, 0.3, n)
    res = np.where(rng.random(n) < 0.3, rng.integers(-1, 5, n), -1) if reserve else None
    kw = dict(periodic=periodic, ghost=500.0, reserved_lane=res)
    if footprint:
        kw.update(length=ln, heading=h)
    got = lane_index(cx, cy, w, 4.0, 4, L, **kw)
    want = _numpy_lane_index(cx, cy, w, 4.0, 4, L, **kw)
    for f in ("keys", "rows", "lanes", "x"):
        np.testing.assert_array_equal(getattr(got, f), getattr(want, f))
    assert got.offset == want.offset
    q_rows = rng.integers(0, max(n, 1), 2 * n)
    q_lanes = rng.integers(0, 4, 2 * n)
    for a, b in zip(leaders(got, q_rows, q_lanes, cx, return_x=True),
                    _numpy_leaders(want, q_rows, q_lanes, cx, return_x=True)):
        np.testing.assert_array_equal(a, b)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 200), seed=st.integers(0, 2**31))
def test_headway_record_equals_numpy(n, seed):
    """HeadwayStats.record (compiled) keeps what the numpy code kept."""
    from icv_envs.sim.metrics import HEADWAY_BIN, STOPPED_SPEED, HeadwayStats

    rng = np.random.default_rng(seed)
    hs = HeadwayStats()
    ref = {"min_gap": np.inf, "min_th": np.inf, "samples": 0, "hist": np.zeros_like(hs._hist)}
    for _ in range(3):
        gap = np.where(rng.random(n) < 0.2, np.inf, rng.uniform(-2.0, 300.0, n))
        v = np.where(rng.random(n) < 0.2, rng.uniform(0, 0.2, n), rng.uniform(0, 30.0, n))
        hs.record(gap, v)
        has = np.isfinite(gap)
        if has.any():
            ref["min_gap"] = min(ref["min_gap"], float(gap[has].min()))
            moving = has & (v >= STOPPED_SPEED)
            if moving.any():
                th = np.maximum(gap[moving], 0.0) / v[moving]
                ref["min_th"] = min(ref["min_th"], float(th.min()))
                b = np.minimum((th / HEADWAY_BIN).astype(np.int64), len(ref["hist"]) - 1)
                ref["hist"] += np.bincount(b, minlength=len(ref["hist"]))
                ref["samples"] += int(moving.sum())
    assert (hs.min_gap, hs.min_time_headway, hs.samples) == (ref["min_gap"], ref["min_th"], ref["samples"])
    np.testing.assert_array_equal(hs._hist, ref["hist"])
    with pytest.raises(ValueError, match="one length"):
        hs.record(np.zeros(3), np.zeros(2))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(_finite_f, st.floats(-25.0, 25.0), st.floats(-6.0, 3.0)), min_size=1, max_size=20),
       st.floats(-30.0, 0.0), st.floats(0.0, 15.0), st.sampled_from([60.0, 120.0]))
def test_banded_join_search_equals_two_join_duration_calls(rows, v_lo, v_hi, cap):
    """The formation layer's plan durations in one compiled call equal
    join_duration within the band, then without it where the band search
    reached its cap (the two calls the manager made), bit for bit."""
    from icv_envs.formation.control import _join_duration_banded, join_duration

    d0, v0, a0 = (np.array(c, dtype=np.float64) for c in zip(*rows))
    lim = dict(accel=1.5, decel=3.0, jerk=2.0, t_min=2.0)
    want = join_duration(d0, v0, a0, **lim, v_lo=v_lo, v_hi=v_hi, max_duration=cap)
    stuck = want >= cap
    if stuck.any():
        want[stuck] = join_duration(d0[stuck], v0[stuck], a0[stuck], **lim)
    got = _join_duration_banded(d0, v0, a0, 1.5, 3.0, 2.0, 2.0, v_lo, v_hi, cap)
    np.testing.assert_array_equal(got, want)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 50), seed=st.integers(0, 2**31))
def test_quintic_equals_the_written_out_formula(n, seed):
    """_quintic computes each power once; the values are those of the
    formula written out term by term (as it was), bit for bit."""
    from icv_envs.formation.control import _quintic

    rng = np.random.default_rng(seed)
    t, T = rng.uniform(-1, 60, n), rng.uniform(0.5, 60, n)
    d0, v0, a0 = rng.uniform(-100, 100, n), rng.uniform(-15, 15, n), rng.uniform(-6, 3, n)
    got = _quintic(t, T, d0, v0, a0)
    t = np.minimum(np.maximum(t, 0.0), T)
    c3 = -(20.0 * d0 + 12.0 * v0 * T + 3.0 * a0 * T ** 2) / (2.0 * T ** 3)
    c4 = (30.0 * d0 + 16.0 * v0 * T + 3.0 * a0 * T ** 2) / (2.0 * T ** 4)
    c5 = -(12.0 * d0 + 6.0 * v0 * T + a0 * T ** 2) / (2.0 * T ** 5)
    want = (d0 + v0 * t + 0.5 * a0 * t ** 2 + c3 * t ** 3 + c4 * t ** 4 + c5 * t ** 5,
            v0 + a0 * t + 3.0 * c3 * t ** 2 + 4.0 * c4 * t ** 3 + 5.0 * c5 * t ** 4,
            a0 + 6.0 * c3 * t + 12.0 * c4 * t ** 2 + 20.0 * c5 * t ** 3,
            6.0 * c3 + 24.0 * c4 * t + 60.0 * c5 * t ** 2)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    assert _quintic(t, T, d0, v0, a0, jerk=False)[3] is None


# ------------------------------------------------ observation neighbours
def _numpy_neighbours(road, rows, F, K, pd):
    """HighwayFormationEnv._neighbours as numpy code, before it was compiled (the reference)."""
    n = len(F)
    cx = F[:, 1]
    order = np.argsort(cx, kind="stable")
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    offs = np.concatenate([np.arange(-K, 0), np.arange(1, K + 1)])
    cand_rank = rank[rows][:, None] + offs[None, :]
    if road.periodic:  # round the ring: ranks wrap, each vehicle at most once
        valid = np.abs(offs)[None, :] <= (n - 1) // 2 + (offs[None, :] > 0) * ((n - 1) % 2)
        cand_rank = np.mod(cand_rank, n)
    else:
        valid = (cand_rank >= 0) & (cand_rank < n)
    cand = order[np.clip(cand_rank, 0, n - 1)]
    dist = np.abs(road.wrap(cx[cand] - cx[rows][:, None]))
    dist = np.where(valid & (dist < pd), dist, np.inf)
    pick = np.argsort(dist, axis=1, kind="stable")[:, :K]
    sel = np.take_along_axis(cand, pick, axis=1)
    present = np.isfinite(np.take_along_axis(dist, pick, axis=1))
    return sel, present


@settings(max_examples=80, deadline=None)
@given(n=st.integers(2, 60), K=st.integers(1, 8), periodic=st.booleans(), seed=st.integers(0, 2**31))
def test_nearest_along_road_equals_the_numpy_code(n, K, periodic, seed):
    from icv_envs.sim._kernels import nearest_along_road

    rng = np.random.default_rng(seed)
    road = RoadLayout(3, 1000.0, 4.0, periodic=periodic)
    F = np.zeros((n, 3))
    F[:, 1] = rng.uniform(0, 1000.0, n)
    F[: n // 3, 1] = F[n // 3: 2 * (n // 3), 1]  # ties
    rows = rng.permutation(n)[: rng.integers(1, n + 1)]
    pd = float(rng.choice([30.0, 150.0, 600.0]))
    got = nearest_along_road(np.ascontiguousarray(F[:, 1]), rows.astype(np.int64), K, pd, periodic, 1000.0)
    want = _numpy_neighbours(road, rows, F, K, pd)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)


# --------------------------------------------------- lane interval ends
def _numpy_interval_end(self, lane, x):
    end = np.full(lane.shape, -np.inf)  # lanes that do not exist end at once
    main = (lane >= 0) & (lane < self.n_lanes)
    if main.any():
        lm, xm = lane[main], x[main]
        e = self.lane_ends[lm].copy()
        if len(self._ob_lane):
            cand = np.where(
                (lm[:, None] == self._ob_lane[None, :]) & (self._ob_hi[None, :] >= xm[:, None]),
                self._ob_lo[None, :],
                np.inf,
            ).min(axis=1)
            e = np.minimum(e, cand)
        end[main] = e
    ramp = lane == self.n_lanes
    if ramp.any() and not len(self._ramp_iv):
        end[ramp] = -np.inf
    if ramp.any() and len(self._ramp_iv):
        xr = x[ramp]
        cand = np.where(self._ramp_iv[None, :, 1] >= xr[:, None], self._ramp_iv[None, :, 1], np.inf).min(axis=1)
        end[ramp] = cand
    return end


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 80), ramp=st.booleans(), seed=st.integers(0, 2**31))
def test_interval_end_equals_the_numpy_code(n, ramp, seed):
    rng = np.random.default_rng(seed)
    road = _random_road(rng, [(300.0, 500.0), (900.0, 1200.0)] if ramp else [])
    lane = rng.integers(-1, 5, (n, 2))
    x = rng.uniform(-50.0, 2_050.0, (n, 2))
    np.testing.assert_array_equal(road._interval_end(lane, x), _numpy_interval_end(road, lane, x))


def test_patched_join_profiles_equal_a_full_evaluation():
    """JoinPlans.profile's answers, kept or evaluated again after members
    were re-planned since its cached answer, equal a full evaluation (numpy's
    join_profile, whose powers are the kernel's libm ones at AVX2:
    :func:`_exact_or_ulps`)."""
    from icv_envs.envs.highway_formation_v0 import parallel_env
    from icv_envs.formation.control import join_profile

    env = parallel_env(scenario="lane-drop")
    env.reset(seed=3)
    man, tr = env.core.world.manager, env.core.world.traffic
    patched = 0
    for _ in range(60):
        ex = env.expert_actions()
        c = man._plans._cache
        plans_before = man.plans
        env.step({a: ex[a] for a in env.agents})
        tr = env.core.world.traffic
        m = np.flatnonzero(tr.group >= 0)
        if not len(m):
            continue
        c = man._plans._cache
        if c is not None and c[0][1] == tr.vid[m].tobytes() and c[1] != man.plans:
            patched += 1
        got = man._profile(tr, m)
        vid = tr.vid[m]
        jp = man._plans
        want = join_profile(man.time - jp.t0[vid], jp.T[vid], jp.d0[vid], jp.v0[vid], jp.a0[vid])
        for g, w in zip(got, want):
            _exact_or_ulps(g, w)
        # re-plan some members now and ask again: the patched answer is the full one
        man._plan(tr, env.core.world.road, m[::3], tr.center()[0])
        got = man._profile(tr, m)
        jp = man._plans
        want = join_profile(man.time - jp.t0[vid], jp.T[vid], jp.d0[vid], jp.v0[vid], jp.a0[vid])
        for g, w in zip(got, want):
            _exact_or_ulps(g, w)
        patched += 1
    assert patched > 10


# ------------------------------------------------ PET occupancy (intersection)
def _numpy_pet_record(self, t, vid, pid, s, length):
    """PetStats.record as numpy code, before its transitions were compiled (the reference)."""
    vid = np.asarray(vid, dtype=np.int64)
    pid = np.asarray(pid, dtype=np.int64)
    self._fit(vid)
    ok = pid < len(self._lo)
    vid, pid = vid[ok], pid[ok]
    x = np.asarray(s, dtype=np.float64)[ok][:, None]
    h = 0.5 * np.asarray(length, dtype=np.float64)[ok][:, None]
    occ = (x - h < self._hi[pid]) & (x + h > self._lo[pid])
    # only the listed vehicles and those inside an area until now can
    # change (every other row is empty before and after): events are
    # handled over those rows, in increasing id as over the whole table
    cand = np.union1d(vid, self._busy)
    at = np.searchsorted(cand, vid)
    old = self._occ[cand]
    new = np.zeros_like(old)
    new[at] = occ
    prev_pid = self._pid[cand]
    self._pid[vid] = pid
    for v, k in zip(*np.nonzero(old & ~new)):
        q = prev_pid[v]
        self._leave(t, int(self._ids[q, k]), int(self._side[q, k]))
    for v, k in zip(*np.nonzero(new & ~old)):
        q = self._pid[cand[v]]
        self._enter(t, int(self._ids[q, k]), int(self._side[q, k]))
    self._occ[cand] = new
    self._busy = cand[new.any(axis=1)]


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_pet_record_equals_the_numpy_code(seed):
    """PetStats.record (compiled transitions) produces the numpy code's PET
    samples, counters and tables over a random sequence of updates."""
    from icv_envs.sim.intersection_layout import IntersectionLayout
    from icv_envs.sim.intersection_metrics import ConflictAreas, PetStats

    rng = np.random.default_rng(seed)
    areas = ConflictAreas(IntersectionLayout())
    a, b = PetStats(areas), PetStats(areas)
    P = a._lo.shape[0]
    n_veh = 30
    paths = rng.integers(0, P + 1, n_veh)  # P: a path without areas (skipped)
    pos = rng.uniform(-40.0, 10.0, n_veh)
    speed = rng.uniform(0.0, 3.0, n_veh)
    for step in range(60):
        pos = pos + speed
        listed = np.flatnonzero(rng.random(n_veh) < 0.8)
        vid = listed + 3
        t = 0.04 * step
        args = (t, vid, paths[listed], pos[listed], np.full(len(listed), 4.5))
        a.record(*args)
        _numpy_pet_record(b, *args)
        if step % 10 == 9:  # re-routes: a vehicle's path changes
            paths[rng.integers(0, n_veh)] = rng.integers(0, P)
    assert a.samples == b.samples
    np.testing.assert_array_equal(a.inside, b.inside)
    np.testing.assert_array_equal(a.last_exit, b.last_exit)
    assert a.pending == b.pending
    np.testing.assert_array_equal(a._occ, b._occ)
    np.testing.assert_array_equal(a._pid, b._pid)
    np.testing.assert_array_equal(a._busy, b._busy)


def test_center_cache_follows_the_state_and_refuses_in_place_writes():
    """Traffic.center() is kept per state: a new x array gives new centres,
    and an in-place write into the arrays it was computed from raises
    (instead of leaving stale centres)."""
    from icv_envs.sim.traffic import Traffic

    tr = Traffic(2.8)
    tr.add(np.array([10.0, 30.0]), np.array([0.0, 4.0]), np.array([20.0, 20.0]))
    cx, _ = tr.center()
    np.testing.assert_array_equal(cx, tr.x + 1.4)
    with pytest.raises(ValueError, match="read-only"):
        tr.x[1] -= 20.0
    with pytest.raises(ValueError, match="read-only"):
        cx[0] = 0.0
    tr.x = tr.x - np.array([0.0, 20.0])
    np.testing.assert_array_equal(tr.center()[0], np.array([11.4, 11.4]))


def _numpy_available(self, lane, x):
    """Whether ``lane`` is drivable at ``x`` (vectorised, broadcasting)."""
    lane, x = np.broadcast_arrays(np.asarray(lane, dtype=np.int64), np.asarray(x, dtype=np.float64))
    x = self.mod(x)
    out = np.zeros(lane.shape, dtype=bool)
    main = (lane >= 0) & (lane < self.n_lanes)
    if main.any():
        lm, xm = lane[main], x[main]
        ok = (xm >= 0) & (xm < self.lane_ends[lm])
        if len(self._ob_lane):
            blocked = (
                (lm[:, None] == self._ob_lane[None, :])
                & (xm[:, None] >= self._ob_lo[None, :])
                & (xm[:, None] <= self._ob_hi[None, :])
            ).any(axis=1)
            ok &= ~blocked
        out[main] = ok
    ramp = lane == self.n_lanes
    if ramp.any() and len(self._ramp_iv):
        xr = x[ramp]
        out[ramp] = ((xr[:, None] >= self._ramp_iv[None, :, 0]) & (xr[:, None] <= self._ramp_iv[None, :, 1])).any(
            axis=1
        )
    return out



@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 60), ramp=st.booleans(), periodic=st.booleans(), seed=st.integers(0, 2**31))
def test_available_equals_the_numpy_code(n, ramp, periodic, seed):
    rng = np.random.default_rng(seed)
    road = _random_road(rng, [(300.0, 500.0)] if ramp else [], periodic=periodic)
    lane = rng.integers(-1, 5, (n, 3))
    x = rng.uniform(-2_050.0, 4_050.0, (n, 3))
    x[:, 0] = np.round(x[:, 0])  # on interval ends too
    np.testing.assert_array_equal(road.available(lane, x), _numpy_available(road, lane, x))
    assert road.available(1, 10.0).shape == ()


@pytest.mark.parametrize("module, config", [
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 40.0}),
    ("highway_formation_v0", {"scenario": "lane-drop"}),
    ("intersection_v0", {}),
])
@pytest.mark.parametrize("opts", [{}, {"absolute": True}, {"normalize": False}, {"clip": False},
                                  {"features": ["presence", "x", "vy", "target_dx"], "vehicles_count": 3}])
def test_kinematics_kernel_equals_the_array_path(module, config, opts):
    """Kinematics.observe_rows through the compiled kernel and through the
    array code give the same float32 observations (ring, straight road,
    intersection; every option)."""
    import importlib

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    obs_cfg = {"type": "Kinematics", **opts}
    if module == "intersection_v0" and "features" in opts:
        obs_cfg.pop("features")
    env = mod.parallel_env(observation=obs_cfg, **config)
    env.reset(seed=2)
    for _ in range(60):
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    core = env.core
    rows = np.arange(len(core._vehicles().vid))
    F = core._features()
    got = core.observation_type.observe_rows(rows, F)
    core._wrap_period = lambda: None
    want = core.observation_type.observe_rows(rows, F)
    assert got.dtype == want.dtype == np.float32
    np.testing.assert_array_equal(got, want)
    assert len(rows) > 3


def _exact_or_ulps(got, want):
    """Bit for bit where NumPy's dispatch is at most X86_V3 (its float64
    ``power`` and ``exp`` are libm's there, as the kernels'); above it (an
    AVX-512 machine, whose NumPy rounds them as its SIMD library does) within
    1e-12 relative or 1e-9 absolute (the quintic's terms cancel near its
    end: last-bit differences of its powers give 2e-12 relative there; the
    pinned fingerprints of tests/test_trajectory_hash.py and the pinned tests
    check the exact values end to end)."""
    from trajectory_hash import _active_targets_above

    if _active_targets_above():
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)
    else:
        np.testing.assert_array_equal(got, want)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 50), seed=st.integers(0, 2**31))
def test_profile_eval_equals_quintic(n, seed):
    """The compiled profile evaluation (stored coefficients, libm's powers)
    gives _quintic's values (numpy's powers) where the plan still runs and
    the stored end values, exactly, where it has ended (``time - t0 >= T``)."""
    from icv_envs.formation._kernels import profile_eval
    from icv_envs.formation.control import _quintic, _quintic_coeffs

    rng = np.random.default_rng(seed)
    m = n + 7  # plan arrays indexed by vehicle id, more ids than rows
    T = rng.uniform(0.5, 60, m)
    t0 = rng.uniform(0, 100, m)
    d0, v0, a0 = rng.uniform(-100, 100, m), rng.uniform(-15, 15, m), rng.uniform(-6, 3, m)
    c3, c4, c5 = _quintic_coeffs(T, d0, v0, a0)
    fd, fv, fa = rng.normal(size=m), rng.normal(size=m), rng.normal(size=m)
    vid = rng.choice(m, n, replace=False).astype(np.int64)
    time = float(rng.uniform(0, 160))
    P = profile_eval(vid, time, t0, T, fd, fv, fa, d0, v0, a0, c3, c4, c5)
    assert P.shape == (3, n)
    t = time - t0[vid]
    run = t < T[vid]
    want = _quintic(t[run], T[vid][run], d0[vid][run], v0[vid][run], a0[vid][run], jerk=False)[:3]
    for row, w, ended in zip(P, want, (fd, fv, fa)):
        _exact_or_ulps(row[run], w)
        np.testing.assert_array_equal(row[~run], ended[vid][~run])


@pytest.mark.parametrize("module, config, seed, steps, random_share", [
    ("highway_formation_v0", {"vehicles_count": 20}, 0, 120, 0.5),  # collisions and off-road from random actions
    ("highway_formation_v0", {"road_length": 400.0, "vehicles_count": 10, "duration": 60.0}, 1, 200, 0.0),  # road end
    ("highway_formation_v0", {"scenario": "off-ramp"}, 2, 250, 0.0),  # exits on a straight road
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 150.0, "method": "lane-lp"}, 2, 700, 0.0),  # ring: exits, missed
    ("highway_formation_v0", {"vehicles_count": 8, "obstacle": {"lane": 1, "position": 300.0}}, 3, 100, 0.3),
    # (from stop 53, the frames crash vehicles off the road themselves: with exits, and on the ring)
    ("highway_formation_v0", {"scenario": "off-ramp"}, 4, 150, 0.3),
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 60.0, "method": "lane-lp"}, 5, 200, 0.3),
])
def test_fused_substeps_equal_one_substep_at_a_time(module, config, seed, steps, random_share):
    """World.substeps (quiet frames compiled in one call) leaves the same
    state, statistics, events and observations as World.substep called once
    per frame (forced here by giving the world no ``substeps``)."""
    import importlib

    from icv_envs.sim.world import World

    mod = importlib.import_module(f"icv_envs.envs.{module}")

    def run(fused):
        env = mod.parallel_env(**config)
        env.reset(seed=seed)
        if not fused:
            env.core.world.substeps = None  # the env then takes substep() frame by frame
        rng = np.random.default_rng(seed)
        trace = []
        for t in range(steps):
            if not env.agents and env.episode_over:
                break
            ex = env.expert_actions()
            acts = {a: (rng.uniform(-1, 1, 2) if rng.random() < random_share else ex[a]) for a in env.agents}
            obs, rew, term, trunc, _ = env.step(acts)
            trace.append((sorted(obs), [obs[a].tobytes() for a in sorted(obs)], [rew[a] for a in sorted(obs)],
                          [(term[a], trunc[a]) for a in sorted(obs)]))
        w = env.core.world
        if fused and w._no_exit_rows is not None:  # the kept no-exit rows, read by every fused call, unchanged
            _, exit_id, ex_x, de = w._no_exit_rows
            assert (exit_id == -1).all() and np.isposinf(ex_x).all() and np.isposinf(de).all()
        m = w.motion
        moments = tuple(x.tobytes() for x in m.moments())
        return trace, w.stats, w.time, (m.vehicle_steps, m.speed_sum, m.realised_abs_accel_sum,
                                        m.commanded_abs_accel_sum, m.stopped_steps), moments

    assert hasattr(World, "substeps")
    fused, plain = run(True), run(False)
    assert fused[1] == plain[1] and fused[2] == plain[2] and fused[3] == plain[3] and fused[4] == plain[4]
    assert fused[0] == plain[0]


def test_frames_crash_a_vehicle_off_the_road_without_stopping():
    """A vehicle that leaves the road in a frame where nothing else happens
    is crashed inside the compiled frames (from stop 53): ``World.substeps``
    runs every frame it was asked for, the vehicle is crashed, and the
    collision, its ``road`` fault and the crashed id are counted once; with
    the vehicle crashed and off the road, the frames after it are no event
    either (``substep``'s Python path is never taken)."""
    from icv_envs.envs.highway_formation_v0 import parallel_env
    from icv_envs.sim.world import StepEvents, World

    env = parallel_env(vehicles_count=6, initial_position=None)
    env.reset(seed=0)
    w = env.core.world
    tr = w.traffic
    w.set_expert_driven(tr.vid, np.zeros(tr.n, dtype=bool))
    # the outermost vehicle steered hard off the road's edge (the others go straight on)
    r = int(np.argmin(tr.y))
    steer = np.zeros(tr.n)
    steer[r] = -0.6
    calls = []
    real = World._substep_events
    World._substep_events = lambda self, *a, **k: (calls.append(1), real(self, *a, **k))[1]
    try:
        events = StepEvents()
        ran = w.substeps(np.zeros(tr.n), steer, 40, events)
    finally:
        World._substep_events = real
    assert ran == 40 and not calls
    assert tr.crashed[r] and int(np.count_nonzero(tr.crashed)) == 1
    assert events.crashed == {int(tr.vid[r])}
    assert w.stats["collisions"] == 1
    assert w.stats["collisions_by_fault"]["road"] == {"expert": 0, "policy": 1}


def _numpy_intersection_events(lay, cx, cy, f, t):
    """The per-frame event tests of ``IntersectionWorld.substep`` and its PET
    candidate selection as the array code wrote them before they were
    compiled (frozen here as the oracle); ``f`` a dict of the fleet's arrays
    (updated the way the array code updated them)."""
    from icv_envs.platoon.geometry import N_LANES
    from icv_envs.sim.intersection_world import _OFFROAD_MARGIN, _OUT

    b, w = lay.box_half, lay.lane_width
    leg = f["leg"]
    ox = b * _OUT[leg, 0]
    oy = b * _OUT[leg, 1]
    d = lay.app_dir[leg]
    r = lay.app_right[leg]
    u = (cx - ox) * d[:, 0] + (cy - oy) * d[:, 1]
    lat_leg = (cx - ox) * r[:, 0] + (cy - oy) * r[:, 1]
    n = len(cx)
    crash = np.zeros(n, dtype=bool)
    new_wrong = np.zeros(n, dtype=bool)
    clear_all = np.zeros(n, dtype=bool)
    newly = ~f["entered"] & (u >= 0.0)
    if newly.any():
        f["entered"] = f["entered"] | newly
        f["plane"] = np.where(newly, np.clip(np.floor(lat_leg / w), 0, N_LANES - 1).astype(np.int64), f["plane"])
        f["enter_time"] = np.where(newly, t, f["enter_time"])
    appr = ~f["entered"]
    crash |= appr & ((lat_leg < -_OFFROAD_MARGIN) | (lat_leg > N_LANES * w + _OFFROAD_MARGIN))
    inside = np.maximum(np.abs(cx), np.abs(cy)) <= b
    newdep = f["entered"] & ~f["departed"] & ~inside
    if newdep.any():
        k = np.flatnonzero(newdep)
        proj = cx[k, None] * _OUT[None, :, 0] + cy[k, None] * _OUT[None, :, 1]
        e = np.argmax(proj, axis=1)
        f["exit_leg"][k] = e
        f["departed"][k] = True
        wrong = e != lay.exit_of[f["mv"][k]]
        f["wrong_exit"][k[wrong]] = True
        new_wrong[k[wrong]] = True
    dep = f["departed"]
    removed = np.zeros(n, dtype=bool)
    if dep.any():
        k = np.flatnonzero(dep)
        e = f["exit_leg"][k]
        past = cx[k] * _OUT[e, 0] + cy[k] * _OUT[e, 1] - b
        lat_e = (cx[k] - b * _OUT[e, 0]) * lay.dep_right[e, 0] + (cy[k] - b * _OUT[e, 1]) * lay.dep_right[e, 1]
        crash[k] |= (lat_e < -_OFFROAD_MARGIN) | (lat_e > N_LANES * w + _OFFROAD_MARGIN)
        clear_now = ~f["cleared"][k] & (past >= 0.5 * f["length"][k])
        f["cleared"][k[clear_now]] = True
        clear_all[k[clear_now]] = True
        removed[k] = past >= lay.departure_length
    in_box = f["entered"] & ~f["departed"]
    min_box = float(f["speed"][in_box].min()) if in_box.any() else np.inf
    left = appr & (u < -(lay.R3 - b + 50.0))
    # _record_pet
    near = (u >= -20.0) & ~f["departed"]
    if f["departed"].any():
        k = np.flatnonzero(f["departed"])
        e = f["exit_leg"][k]
        past = cx[k] * _OUT[e, 0] + cy[k] * _OUT[e, 1] - lay.box_half
        near[k] = past < 20.0
    k = np.flatnonzero(near & ~f["crashed"])
    plane = np.where(f["plane"][k] >= 0, f["plane"][k], f["tlane"][k])
    pid = 3 * f["mv"][k] + plane
    phase = np.where(f["departed"][k], 2, np.where(f["entered"][k], 1, 0))
    s, _ = lay.project(pid, cx[k], cy[k], phase)
    return u, lat_leg, crash, new_wrong, clear_all, removed, left, k, pid, s, min_box


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 80), seed=st.integers(0, 2**31))
def test_intersection_events_equal_the_array_code(n, seed):
    """The compiled per-frame event tests of the intersection world
    (``sim/_kernels/intersection.py``) against the array code they replaced,
    over random fleets around and inside the box: every returned mask, the
    PET rows, path ids and route coordinates (the turn arcs' finished by
    ``arc_project``, as the world does), and every fleet array they update."""
    from icv_envs.platoon.geometry import N_LANES
    from icv_envs.sim._kernels.intersection import intersection_events
    from icv_envs.sim.intersection_world import _OFFROAD_MARGIN, _OUT, IntersectionLayout

    rng = np.random.default_rng(seed)
    lay = IntersectionLayout()
    mv = rng.integers(0, 12, n)
    entered = rng.random(n) < 0.5
    departed = entered & (rng.random(n) < 0.5)
    f = {
        "leg": lay.leg_of[mv].astype(np.int64), "mv": mv.astype(np.int64), "length": rng.uniform(3.0, 12.0, n),
        "speed": rng.uniform(0.0, 15.0, n), "crashed": rng.random(n) < 0.1, "tlane": rng.integers(0, 3, n),
        "entered": entered, "departed": departed, "cleared": departed & (rng.random(n) < 0.5),
        "wrong_exit": departed & (rng.random(n) < 0.2), "exit_leg": np.where(departed, rng.integers(0, 4, n), -1),
        "plane": np.where(entered, rng.integers(0, 3, n), np.where(rng.random(n) < 0.5, -1, rng.integers(0, 3, n))),
        "enter_time": rng.uniform(0.0, 50.0, n),
    }
    reach = lay.box_half + rng.choice([5.0, 30.0, 900.0])
    cx, cy = rng.uniform(-reach, reach, n), rng.uniform(-reach, reach, n)
    on_axis = rng.random(n) < 0.3  # some on a leg's axis, where the departure and approach tests bite
    cx[on_axis] = rng.uniform(-6 * lay.lane_width, 6 * lay.lane_width, int(on_axis.sum()))
    # some on a whole-metre grid (lengths too), where the boundary cases of every test are hit exactly
    grid = rng.random(n) < 0.4
    cx[grid], cy[grid] = np.rint(cx[grid]), np.rint(cy[grid])
    f["length"][grid] = rng.integers(3, 13, int(grid.sum()))
    t = float(rng.uniform(0.0, 100.0))
    ref = {k: np.array(v, copy=True) for k, v in f.items()}
    want = _numpy_intersection_events(lay, cx, cy, ref, t)
    got_f = {k: np.array(v, copy=True) for k, v in f.items()}
    b = lay.box_half
    got = intersection_events(
        cx, cy, got_f["speed"], got_f["leg"], got_f["mv"], got_f["length"], got_f["crashed"], got_f["tlane"],
        got_f["entered"], got_f["departed"], got_f["cleared"], got_f["wrong_exit"], got_f["exit_leg"],
        got_f["plane"], got_f["enter_time"], _OUT, lay.app_dir, lay.app_right, lay.dep_right, lay.exit_of, b,
        lay.lane_width, N_LANES, _OFFROAD_MARGIN, -(lay.R3 - b + 50.0), lay.departure_length, t,
        lay.P0, lay.D0, lay.P1, lay.D1, lay.L, lay.arc)
    u, lat, crash, new_wrong, clear_now, removed, left, rows, pid, s, arc, min_box = got
    if arc.any():
        k = np.flatnonzero(arc)
        s[k] = lay.arc_project(pid[k], cx[rows[k]], cy[rows[k]])[0]
    for name, a, b_ in zip(("u", "lat", "crash", "new_wrong", "clear_now", "removed", "left", "pet rows", "pet pid",
                            "pet s"), (u, lat, crash, new_wrong, clear_now, removed, left, rows, pid, s), want):
        assert a.dtype.kind == np.asarray(b_).dtype.kind and np.array_equal(a, b_), name
    assert min_box == want[-1]
    for k in f:
        assert np.array_equal(got_f[k], ref[k]), k


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 80), span=st.floats(20.0, 300.0), seed=st.integers(0, 2**31))
def test_box_collision_pairs_equal_the_array_code(n, span, seed):
    """``IntersectionWorld.collision_pairs`` compiled whole against the array
    code it replaced (two sweeps over row subsets, joined and deduplicated),
    over dense random fleets on the legs and in the box."""
    import math

    from icv_envs.sim._kernels.intersection import box_collision_pairs
    from icv_envs.sim.traffic import find_collisions

    rng = np.random.default_rng(seed)
    b = 16.0
    cx, cy = rng.uniform(-span, span, n), rng.uniform(-span, span, n)
    axis = rng.random(n) < 0.5
    cx[axis] = rng.uniform(-12.0, 12.0, int(axis.sum()))
    heading = rng.uniform(-math.pi, math.pi, n)
    length, width = rng.uniform(3.0, 12.0, n), rng.uniform(1.5, 2.6, n)
    ax, ay = np.abs(cx), np.abs(cy)
    near = np.maximum(ax, ay) < b + 10.0
    out_i, out_j = [], []
    for sel, swap in ((near | (ax >= ay), False), (near | (ay > ax), True)):
        rows = np.flatnonzero(sel)
        if len(rows) < 2:
            continue
        if swap:
            i, j = find_collisions(cy[rows], cx[rows], 0.5 * math.pi - heading[rows], length[rows], width[rows])
        else:
            i, j = find_collisions(cx[rows], cy[rows], heading[rows], length[rows], width[rows])
        out_i.append(rows[i])
        out_j.append(rows[j])
    want = (np.zeros(0, dtype=np.int64),) * 2
    if out_i and len(np.concatenate(out_i)):
        i, j = np.concatenate(out_i), np.concatenate(out_j)
        key = np.unique(np.minimum(i, j) * (n + 1) + np.maximum(i, j))
        want = key // (n + 1), key % (n + 1)
    got = box_collision_pairs(cx, cy, heading, length, width, b)
    for g, w in zip(got, want):
        assert g.dtype == np.int64 and np.array_equal(g, w)


@settings(max_examples=80, deadline=None)
@given(G=st.integers(2, 60), periodic=st.booleans(), grid=st.booleans(), seed=st.integers(0, 2**31))
def test_room_ahead_equals_the_pairwise_matrix(G, periodic, grid, seed):
    """``room_ahead`` (the formation layer's nearest-formation-ahead distance,
    compiled row by row) against the pairwise matrix it replaced, on rings and
    straight roads, with ties (whole-metre positions) and zero lengths."""
    from icv_envs.sim._kernels.formation import room_ahead

    rng = np.random.default_rng(seed)
    length = 2000.0
    A = rng.uniform(0.0, length if periodic else 3 * length, G)
    Lf = np.where(rng.random(G) < 0.2, 0.0, rng.uniform(0.0, 150.0, G))
    if grid:
        A, Lf = np.rint(A), np.rint(Lf)

    def wrap(d):
        return np.mod(d + 0.5 * length, length) - 0.5 * length if periodic else d

    rel = wrap(A[None, :] - Lf[None, :] - A[:, None])
    np.fill_diagonal(rel, np.inf)
    rel = np.where(rel > -Lf[:, None], rel, np.inf)
    assert np.array_equal(room_ahead(A, Lf, length if periodic else -1.0), rel.min(axis=1))


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 120), periodic=st.booleans(), grid=st.booleans(), seed=st.integers(0, 2**31))
def test_own_lane_gaps_equal_the_array_code(n, periodic, grid, seed):
    """``own_lane_gap_rows`` (``World.own_lane_gaps`` compiled) against the
    array code it replaced: ``road.lane_of``, ``leaders`` (numpy) and the gap
    arithmetic, with vehicles exactly alongside, on lane centres and lane
    lines (whole-metre grid: ``rint`` ties), beyond the outer lanes, and on
    rings (ghosts round the seam)."""
    from icv_envs.sim._kernels import own_lane_gap_rows
    from icv_envs.sim.traffic import lane_index

    rng = np.random.default_rng(seed)
    L, lw, total = 3000.0, 4.0, 5
    cx = rng.uniform(0, L, n)
    cx[: n // 4] = cx[n // 4: 2 * (n // 4)]
    cy = rng.uniform(-3.0, 22.0, n)
    if grid:
        cx, cy = np.rint(cx), np.rint(cy / 2.0) * 2.0  # lane lines at odd multiples of 2 m: rint ties
    length = rng.uniform(4.0, 12.0, n)
    index = lane_index(cx, cy, rng.uniform(1.8, 2.2, n), lw, total, L, periodic=periodic, ghost=500.0)
    road = RoadLayout(total, L, lw, periodic=periodic)
    lane = road.lane_of(cy)
    lead, lx = _numpy_leaders(index, np.arange(n), lane, cx, return_x=True)
    gap = np.full(n, np.inf)
    ok = lead >= 0
    gap[ok] = lx[ok] - cx[ok] - 0.5 * (length[lead[ok]] + length[ok])
    got_gap, got_lead = own_lane_gap_rows(index.keys, index.rows, index.lanes, index.x, float(index.offset), cx, cy,
                                          length, lw, total)
    assert got_lead.dtype == np.int64
    np.testing.assert_array_equal(got_lead, lead)
    np.testing.assert_array_equal(got_gap, gap)


@settings(max_examples=80, deadline=None)
@given(n=st.integers(0, 60), a_max=st.floats(0.5, 6.0), a_min=st.floats(-9.0, -0.5), steer=st.floats(0.1, 1.2),
       seed=st.integers(0, 2**31))
def test_normalised_actions_equal_the_array_code(n, a_max, a_min, steer, seed):
    """The highway expert's normalisation compiled against the array code it
    replaced, with values beyond the limits, exactly at them, signed zeros and NaN."""
    from icv_envs.policies._kernels import normalised_actions
    from icv_envs._ufuncs import clip as uclip

    rng = np.random.default_rng(seed)
    a = rng.uniform(2.0 * a_min, 2.0 * a_max, n)
    phi = rng.uniform(-2.0 * steer, 2.0 * steer, n)
    special = np.array([0.0, -0.0, np.nan, a_max, a_min, np.inf, -np.inf])
    a[: min(n, 7)] = special[: min(n, 7)]
    phi[: min(n, 7)] = np.array([-0.0, 0.0, steer, np.nan, -steer, -np.inf, np.inf])[: min(n, 7)]
    want = uclip(np.stack([np.where(a >= 0, a / a_max, -a / a_min), phi / steer], axis=1), -1.0, 1.0)
    got = normalised_actions(a, phi, a_max, a_min, steer)
    assert got.shape == (n, 2) and got.dtype == np.float64
    np.testing.assert_array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))


def _numpy_formation_features(env):
    """HighwayFormationEnv._features as the array code wrote it before it was
    compiled (frozen here as the oracle)."""
    from icv_envs._ufuncs import clip as uclip

    w = env.world
    tr = w.traffic
    cx, cy = tr.center()
    x_ref, lane_ref, v_ref, member = w.manager.references(tr)
    F = np.zeros((tr.n, 13))
    F[:, 0] = 1.0
    F[:, 1] = cx
    F[:, 2] = cy
    ch, sh = np.cos(tr.heading), np.sin(tr.heading)
    F[:, 3] = tr.speed * ch
    F[:, 4] = tr.speed * sh
    F[:, 5] = ch
    F[:, 6] = sh
    F[:, 7] = np.where(member, w.road.wrap(np.where(member, x_ref, 0.0) - cx), 0.0)
    F[:, 8] = np.where(member, lane_ref * w.road.lane_width - cy, 0.0)
    F[:, 9] = np.where(member, v_ref - tr.speed, 0.0)
    F[:, 10] = member
    road = w.road
    F[:, 11] = 1.0
    if road.n_exits:
        has = tr.exit >= 0
        if has.any():
            F[has, 11] = road.exit_ahead(tr.exit[has], cx[has]) / 1000.0
    lane = road.lane_of(cy)
    F[:, 12] = uclip((road.interval_end(lane, cx) - cx) / 200.0, 0.0, 1.0)
    return F


def _numpy_references(manager, traffic):
    """FormationManager._references as the array code wrote it (oracle)."""
    member = traffic.group >= 0
    x_ref = np.full(traffic.n, np.nan)
    v_ref = np.full(traffic.n, np.nan)
    a_ref = np.full(traffic.n, np.nan)
    if member.any():
        m = np.flatnonzero(member)
        d, dv, dd = manager._profile(traffic, m)
        x_ref[m] = manager._slot_x(traffic, m) + d
        if traffic.period is not None:
            x_ref[m] = np.mod(x_ref[m], traffic.period)
        v_ref[m] = manager.speed + dv
        a_ref[m] = dd
    lane_ref = np.where(member, traffic.tgt_lane, -1)
    return (x_ref, lane_ref, v_ref, member), a_ref


def _numpy_formation_rewards(env, rows, crashed_now, F):
    """HighwayFormationEnv._rewards_rows as the array code wrote it (oracle)."""
    from icv_envs._ufuncs import clip as uclip

    c = env.config
    w = env.world
    tr = w.traffic
    wts = c["reward"]
    vmax = float(c["speed_range"][1])
    progress = tr.speed[rows] / vmax
    gap, _ = w.own_lane_gaps()
    headway = 2.0 + tr.speed * 1.0
    safety = -uclip(1.0 - gap[rows] / headway[rows], 0.0, 1.0)
    safety = np.where(crashed_now, -1.0, safety)
    ua = env._last_actions[rows] if len(env._last_actions) == tr.n else np.zeros((len(rows), 2))
    comfort = -0.5 * (ua[:, 0] ** 2 + ua[:, 1] ** 2)
    member = F[rows, 10] > 0
    L_s = float(c["formation"]["spacing"])
    form = np.where(member, np.exp(-(F[rows, 7] / L_s) ** 2 - (F[rows, 8] / w.road.lane_width) ** 2), 0.0)
    total = wts["progress"] * progress + wts["safety"] * safety + wts["comfort"] * comfort + wts["formation"] * form
    return total, {"progress": progress, "safety": safety, "comfort": comfort, "formation": form}


@pytest.mark.parametrize("module, config, random_share", [
    ("highway_formation_v0", {"vehicles_count": 20}, 0.5),  # collisions, off-road, free vehicles
    ("highway_formation_v0", {"scenario": "off-ramp"}, 0.0),  # exits on a straight road
    ("highway_formation_v0", {"scenario": "lane-drop"}, 0.2),  # lane ends
    ("highway_formation_v0", {"vehicles_count": 8, "obstacle": {"lane": 1, "position": 300.0}}, 0.3),
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 60.0}, 0.1),  # the ring: wrap, ramps, exits
])
@at_pinned_level  # the kernels' exp and powers are libm's, numpy's at AVX2 (tests/pinned_numpy.py)
def test_formation_features_and_rewards_equal_the_array_code(module, config, random_share):
    """The compiled references, feature rows and reward terms of the highway env give
    the array code's values bit for bit, step after step (the crashes and
    the random actions' comfort terms included; a step's F and rewards are
    compared before the step's removals)."""
    import importlib

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    env = mod.parallel_env(**config)
    env.reset(seed=3)
    core = env.core
    rng = np.random.default_rng(3)
    seen = {"member": 0, "crashed": 0, "exit": 0, "lane_end": 0, "steps": 0}
    orig = type(core)._rewards_rows

    def checked(self, rows, crashed_now, F):
        got_r, got_a = self.world.manager._references(self.world.traffic)
        want_r, want_a = _numpy_references(self.world.manager, self.world.traffic)
        for g, x in zip(got_r + (got_a,), want_r + (want_a,)):
            assert g.dtype == x.dtype
            np.testing.assert_array_equal(g, x)
        want_F = _numpy_formation_features(self)
        np.testing.assert_array_equal(F, want_F)
        got = orig(self, rows, crashed_now, F)
        want = _numpy_formation_rewards(self, rows, crashed_now, F)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1].keys() == want[1].keys()
        for k in want[1]:
            np.testing.assert_array_equal(got[1][k], want[1][k])
        seen["member"] += int((F[:, 10] > 0).sum())
        seen["crashed"] += int(np.sum(crashed_now))
        seen["exit"] += int((F[:, 11] != 1.0).sum())
        seen["lane_end"] += int((F[:, 12] < 1.0).sum())
        seen["steps"] += 1
        return got

    core._rewards_rows = checked.__get__(core)
    for _ in range(150):
        if not env.agents:
            break
        ex = env.expert_actions()
        env.step({a: (rng.uniform(-1, 1, 2) if rng.random() < random_share else ex[a]) for a in env.agents})
    assert seen["steps"] > 20 and seen["member"] > 0
    if random_share >= 0.5:
        assert seen["crashed"] > 0
    if "off-ramp" in config.get("scenario", "") or module == "highway_ramps_v0":
        assert seen["exit"] > 0
    if "lane-drop" in config.get("scenario", "") or "obstacle" in config or module == "highway_ramps_v0":
        assert seen["lane_end"] > 0


@pytest.mark.parametrize("config, random_share", [
    ({"vehicles_count": 20}, 0.5),  # collisions, off-road, free vehicles
    ({"scenario": "lane-drop"}, 0.2),  # lane ends
    ({"vehicles_count": 8, "obstacle": {"lane": 1, "position": 300.0}}, 0.3),
    ({"vehicles_count": 12, "observation": {"type": "Kinematics", "vehicles_count": 1}}, 0.3),  # no neighbours
    ({"vehicles_count": 12, "observation": {"type": "Kinematics", "absolute": True, "normalize": False,
                                            "features": ["presence", "x", "vx", "target_dx"]}}, 0.3),
    ({"vehicles_count": 12, "observation": {"type": "Kinematics", "clip": False, "perception_distance": 40.0},
      "reward": {"progress": 0.3, "safety": 2.0, "comfort": 0.05, "formation": 0.7}}, 0.3),
])
def test_formation_post_rows_equal_the_separate_calls(config, random_share):
    """The highway env's one-pass ``_post_rows`` (features, rewards and
    ``Kinematics`` observations in one compiled call) gives the separate
    methods' rewards, reward components and observations bit for bit, step
    after step, on roads without exits (where it is taken: counted), with
    crashes, lane ends and other observation and reward settings."""
    import icv_envs.envs.highway_rows as hf
    from icv_envs.envs.highway_formation_v0 import parallel_env
    from post_rows_check import post_rows_checked

    env = parallel_env(**config)
    env.reset(seed=5)
    rng = np.random.default_rng(5)
    with post_rows_checked(env.core, hf, "formation_post_rows", hf.HighwayRows._post_rows) as seen:
        for _ in range(120):
            if not env.agents:
                break
            ex = env.expert_actions()
            env.step({a: (rng.uniform(-1, 1, 2) if rng.random() < random_share else ex[a]) for a in env.agents})
    assert seen["steps"] > 20 and seen["fused"] == seen["steps"]
    if random_share >= 0.5:
        assert seen["crashed"] > 0


@pytest.mark.parametrize("seed", range(6))
def test_formation_post_rows_kernel_on_a_ring(seed):
    """The one-pass kernel against the four kernels it calls, on random
    states of a ring (``periodic``: the neighbour search and the
    observation's dx folded round it, the features' wrap), which no env
    reaches through it (every ring has exits)."""
    from icv_envs.sim._kernels import (formation_feature_rows, formation_post_rows, formation_reward_terms,
                                       formation_reward_total, kinematics_rows, nearest_along_road)

    rng = np.random.default_rng(seed)
    n, L, W, lanes = int(rng.integers(1, 30)), 1000.0, 4.0, 4
    cx, cy = rng.uniform(0, L, n), rng.integers(0, lanes, n) * W + rng.normal(0, 0.3, n)
    v, h = rng.uniform(0, 30, n), rng.normal(0, 0.05, n)
    member = rng.random(n) < 0.6
    x_ref = np.where(member, rng.uniform(0, L, n), np.nan)
    lane_ref = np.where(member, rng.integers(0, lanes, n), -1).astype(np.int64)
    v_ref = np.where(member, rng.uniform(20, 30, n), np.nan)
    road = (float(W), lanes, L, lanes, np.full(lanes, np.inf), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0),
            np.zeros((0, 2)))
    rows = np.arange(n, dtype=np.int64)
    gap, crashed, ua = rng.uniform(0, 80, n), rng.random(n) < 0.1, rng.uniform(-1, 1, (n, 2))
    idx = np.arange(13, dtype=np.int64)
    V, pd = int(rng.integers(1, 9)), 150.0
    s_abs, s_rel = rng.uniform(1, 100, 13), rng.uniform(1, 100, 13)
    flags = (bool(rng.random() < 0.3), bool(rng.random() < 0.7), bool(rng.random() < 0.7))
    ch, sh = np.cos(h), np.sin(h)
    got = formation_post_rows(cx, cy, v, ch, sh, x_ref, lane_ref, v_ref, member, *road[:2], L, *road[3:], rows, v,
                              30.0, gap, crashed, ua, 20.0, W, 0.4, 1.0, 0.1, V - 1, pd, True, L, idx, V, s_abs, s_rel,
                              *flags, L, 0.6)
    F = formation_feature_rows(cx, cy, v, ch, sh, x_ref, lane_ref, v_ref, member, *road[:2], L, *road[3:])
    want = formation_reward_terms(rows, v, 30.0, gap, crashed, ua, F, 20.0, W, 0.4, 1.0, 0.1)
    if V > 1 and n > 1:
        sel, present = nearest_along_road(np.ascontiguousarray(F[:, 1]), rows, V - 1, pd, True, L)
    else:
        sel, present = np.zeros((n, 0), dtype=np.int64), np.zeros((n, 0), dtype=bool)
    obs = kinematics_rows(F, rows, sel, present, idx, V, s_abs, s_rel, *flags, L)
    progress, safety, comfort, expo, member_q, partial = want
    total, form = formation_reward_total(member_q, expo, partial, 0.6)
    T, obs_got = got  # (the reward and its terms as rows of one array)
    assert T.shape == (5, n)
    for g, w in zip((T[0], T[1], T[2], T[3], T[4], obs_got), (total, progress, safety, comfort, form, obs)):
        assert g.dtype == w.dtype and g.tobytes() == w.tobytes()


def test_formation_post_rows_not_taken_where_it_does_not_apply():
    """The one-pass path is left for the separate calls on a road with exits,
    with another observation type and when a hook is overridden (on a
    subclass or on the instance): none of them reaches the kernel."""
    import icv_envs.envs.highway_rows as hf
    from icv_envs.envs.highway_formation import HighwayFormationEnv
    from icv_envs.envs.highway_formation_v0 import parallel_env

    calls = []
    kernel = hf.formation_post_rows
    hf.formation_post_rows = lambda *a: calls.append(1) or kernel(*a)
    try:
        for cfg in ({"scenario": "off-ramp"}, {"vehicles_count": 6, "observation": {"type": "OccupancyGrid"}}):
            env = parallel_env(**cfg)
            env.reset(seed=0)
            for _ in range(3):
                env.step({a: env.expert_actions()[a] for a in env.agents})
        env = parallel_env(vehicles_count=6)
        env.reset(seed=0)
        env.core._rewards_rows = type(env.core)._rewards_rows.__get__(env.core)  # an instance override
        env.step({a: env.expert_actions()[a] for a in env.agents})

        class Sub(HighwayFormationEnv):
            def _features(self):
                return super()._features()

        sub = Sub(config={"vehicles_count": 6})
        sub.ma_reset(seed=0)
        sub.ma_step({f"icv_{v}": a for v, a in zip(sub.world.traffic.vid.tolist(), sub.expert_actions())})
        orig = HighwayFormationEnv._neighbours  # a replacement on the class itself
        env = parallel_env(vehicles_count=6)
        env.reset(seed=0)
        HighwayFormationEnv._neighbours = lambda self, *a: orig(self, *a)
        try:
            env.step({a: env.expert_actions()[a] for a in env.agents})
        finally:
            del HighwayFormationEnv._neighbours  # (the mixin's, HighwayRows._neighbours, again)
        assert HighwayFormationEnv._neighbours is hf.HighwayRows._neighbours
        assert calls == []
        env = parallel_env(vehicles_count=6)  # the control: the plain env takes it
        env.reset(seed=0)
        env.step({a: env.expert_actions()[a] for a in env.agents})
        assert calls == [1]
    finally:
        hf.formation_post_rows = kernel


def _drive_patched(env, rng, steps, random_share, **patches):
    """``steps`` policy steps of ``env`` with ``FormationExpert``'s methods
    replaced by ``patches`` (restored afterwards); each agent takes a random
    action with probability ``random_share``, else the expert's."""
    from icv_envs.policies.formation_expert import FormationExpert

    saved = {k: getattr(FormationExpert, k) for k in patches}
    for k, f in patches.items():
        setattr(FormationExpert, k, f)
    try:
        for _ in range(steps):
            if not env.agents:
                break
            ex = env.expert_actions()
            env.step({a: (rng.uniform(-1, 1, 2) if rng.random() < random_share else ex[a]) for a in env.agents})
    finally:
        for k, f in saved.items():
            setattr(FormationExpert, k, f)


def _numpy_safety_cap(expert, world, index, acc, lane, desired, member, exiting, bounds=None):
    """FormationExpert's safety envelope as the array code wrote it before it
    was compiled (frozen here as the oracle)."""
    from icv_envs._ufuncs import clip as uclip
    from icv_envs.sim.traffic import idm_acceleration, leaders

    p = expert.p
    tr, road = world.traffic, world.road
    cx, _ = tr.center()
    v = tr.speed
    n = tr.n
    active = tr.lc_lane >= 0
    q_rows = [index.rows]
    q_lanes = [index.lanes]
    if active.any():
        a_rows = np.flatnonzero(active)
        q_rows.append(a_rows)
        q_lanes.append(tr.lc_lane[a_rows])
    q_rows = np.concatenate(q_rows)
    q_lanes = np.concatenate(q_lanes)
    lead, lx = leaders(index, q_rows, q_lanes, cx, return_x=True)
    has_l = lead >= 0
    gap = np.full(len(q_rows), np.inf)
    gap[has_l] = lx[has_l] - cx[q_rows[has_l]] - 0.5 * (tr.length[lead[has_l]] + tr.length[q_rows[has_l]])
    dv = np.where(has_l, v[q_rows] - v[np.maximum(lead, 0)], 0.0)
    end = road.interval_end(q_lanes, cx[q_rows])
    leaving = (tr.lc_lane[q_rows] >= 0) & (tr.lc_lane[q_rows] != q_lanes)
    exit_ramp_end = (q_lanes == road.n_lanes) & exiting[q_rows]
    own_or_target = (q_lanes == lane[q_rows]) | (q_lanes == tr.lc_lane[q_rows])
    gap_end = np.where(leaving | exit_ramp_end | ~own_or_target, np.inf, end - cx[q_rows] - 0.5 * tr.length[q_rows])
    k_q = np.abs(desired[q_rows] - q_lanes)
    must_leave = (k_q > 0) & ~leaving & ~exit_ramp_end & own_or_target & (
        end < road.interval_end(desired[q_rows], cx[q_rows]))
    gap_end = np.where(must_leave, end - k_q * p.lc_min_length - cx[q_rows], gap_end)
    use_end = gap_end < gap
    gap = np.where(use_end, gap_end, gap)
    dv = np.where(use_end, v[q_rows], dv)
    Tq = np.where(member[q_rows], p.member_time_gap, p.idm_T)
    safe = idm_acceleration(v[q_rows], p.v_max, gap, dv, p.a_max, p.idm_b, Tq, p.idm_s0, free_term=False)
    cap = np.full(n, np.inf)
    np.minimum.at(cap, q_rows, safe)
    acc = np.minimum(acc, cap)
    lo, hi = (p.a_min, p.a_max) if bounds is None else bounds
    return uclip(acc, lo, hi), int(must_leave.sum()), int((use_end & ~must_leave).sum()), int(active.sum())


@pytest.mark.parametrize("module, config, random_share, steps", [
    ("highway_formation_v0", {"vehicles_count": 20}, 0.5, 150),
    ("highway_formation_v0", {"scenario": "lane-drop"}, 0.0, 150),  # a lane end as a standing leader
    ("highway_formation_v0", {"scenario": "on-ramp"}, 0.0, 300),  # k lane changes before the ramp lane ends
    ("highway_formation_v0", {"scenario": "off-ramp"}, 0.0, 300),  # exits: the ramp end does not hold an exiting vehicle
    ("highway_formation_v0", {"vehicles_count": 8, "obstacle": {"lane": 1, "position": 300.0}}, 0.3, 300),
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 60.0}, 0.0, 150),  # the ring
])
def test_expert_safety_cap_equals_the_array_code(module, config, random_share, steps):
    """FormationExpert._safety_cap (compiled) returns the array code's
    accelerations bit for bit on every call of a run, over lane changes,
    lane ends that must be left, ramps and exits."""
    import importlib

    from icv_envs.policies.formation_expert import FormationExpert

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    env = mod.parallel_env(**config)
    env.reset(seed=4)
    rng = np.random.default_rng(4)
    seen = {"calls": 0, "must_leave": 0, "end": 0, "active": 0}
    orig = FormationExpert._safety_cap

    def checked(self, world, index, acc, lane, desired, member, exiting):
        got = orig(self, world, index, acc, lane, desired, member, exiting)
        want, ml, ue, act = _numpy_safety_cap(self, world, index, acc, lane, desired, member, exiting)
        np.testing.assert_array_equal(got, want)
        assert got.dtype == want.dtype
        # the bare envelope (no control law under it, no clipping): every binding query shows
        bare = (np.full(len(acc), np.inf), lane, desired, member, exiting)
        np.testing.assert_array_equal(orig(self, world, index, *bare, bounds=(-np.inf, np.inf)),
                                      _numpy_safety_cap(self, world, index, *bare, bounds=(-np.inf, np.inf))[0])
        seen["calls"] += 1
        seen["must_leave"] += ml
        seen["end"] += ue
        seen["active"] += act
        return got

    _drive_patched(env, rng, steps, random_share, _safety_cap=checked)
    assert seen["calls"] > 50 and seen["active"] > 0
    if config.get("scenario") == "on-ramp":
        assert seen["must_leave"] > 0
    if "obstacle" in config or config.get("scenario") == "lane-drop":
        assert seen["end"] > 0


def test_each_kernel_is_specialised_once_in_a_run():
    """A run of every env (and the batch, with and without the expert) calls
    each compiled kernel with one set of argument types: a second
    specialisation (say a read-only array where a writable one was passed
    before) costs a compile, or a cache load of tens of milliseconds, in
    every fresh process. Run in a fresh interpreter so other tests' calls
    do not count."""
    import subprocess
    import sys

    code = r'''
import sys
import numpy as np
from icv_envs.vector import BatchedWorlds
for expert in (False, True):
    bw = BatchedWorlds(3, expert=expert, seed=0)
    bw.reset()
    out = None
    for _ in range(60):
        out = bw.step(out[5]["expert_actions"] if expert and out else np.zeros((3, bw.K, 2)))
from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0
for mod, cfg in [(highway_ramps_v0, dict(vgr=0.5, duration=60.0)), (intersection_v0, {}),
                 (highway_formation_v0, dict(scenario="off-ramp")), (highway_formation_v0, dict(scenario="on-ramp"))]:
    env = mod.parallel_env(**cfg)
    env.reset(seed=1)
    for _ in range(150):
        if not env.agents:
            break
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
from numba.core.registry import CPUDispatcher
seen, multi = 0, []
for name, m in list(sys.modules.items()):
    if name.startswith("icv_envs"):
        for k, v in vars(m).items():
            if isinstance(v, CPUDispatcher) and v.__module__ == name and v.signatures:
                seen += 1
                if len(v.signatures) > 1:
                    multi.append((name, k, [[str(t) for t in s] for s in v.signatures]))
print(seen)
print(multi)
'''
    # twice: the first run fills the kernel cache if it is cold (compiling a
    # kernel also types the helpers it calls, once per calling kernel, which
    # is no cost to a process that loads them from the cache); the second is
    # the fresh process of a user with the cache filled, the one that counts
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
    seen, multi = out.stdout.strip().splitlines()[-2:]
    assert int(seen) >= 20  # the kernels a run calls (25 when written)
    assert multi == "[]", multi


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 40), seed=st.integers(0, 2**31), dup=st.booleans())
def test_plan_rows_equal_numpy_plan(n, seed, dup):
    """JoinPlans.plan's compiled store gives the tables the array code gave
    (_quintic_coeffs, then _quintic at t = T; its powers
    libm's, numpy's there: :func:`_exact_or_ulps`); a repeated id keeps its
    last plan, as numpy's fancy assignment does."""
    from icv_envs.formation._kernels import plan_rows
    from icv_envs.formation.control import _quintic, _quintic_coeffs

    rng = np.random.default_rng(seed)
    m = n + 9
    vid = rng.choice(m, n, replace=dup).astype(np.int64)
    T = rng.uniform(0.5, 120.0, n)
    d0, v0, a0 = rng.uniform(-300, 300, n), rng.uniform(-15, 15, n), rng.uniform(-6, 3, n)
    time = float(rng.uniform(0, 500))
    names = ("t0", "T", "d0", "v0", "a0", "c3", "c4", "c5", "fd", "fv", "fa")
    want = {k: rng.normal(size=m) for k in names}
    got = {k: v.copy() for k, v in want.items()}
    # the array code plan() ran before
    want["t0"][vid], want["T"][vid] = time, T
    want["d0"][vid], want["v0"][vid], want["a0"][vid] = d0, v0, a0
    want["c3"][vid], want["c4"][vid], want["c5"][vid] = _quintic_coeffs(T, d0, v0, a0)
    want["fd"][vid], want["fv"][vid], want["fa"][vid] = _quintic(T, T, d0, v0, a0, jerk=False)[:3]
    plan_rows(vid, time, T, d0, v0, a0, *(got[k] for k in names))
    for k in names:
        _exact_or_ulps(got[k], want[k])


@at_pinned_level  # plan_pass' cbrt is libm's, NumPy's at AVX2 (tests/pinned_numpy.py)
@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 30), periodic=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_plan_pass_is_the_separate_calls(n, periodic, seed):
    """``plan_pass`` (``FormationManager._plan`` in one call, from stop 50)
    gives the durations and tables of the calls it joined, bit for bit:
    ``plan_inputs_rows``, NumPy's ``cbrt`` of the search's start,
    ``join_search_banded`` with the band as arrays, ``plan_rows``; members
    far from their slot (the fallback search without the band) included."""
    from icv_envs.formation._kernels import join_search_banded, plan_rows
    from icv_envs.formation.control import _PROFILE_SAMPLES, JOIN_GROW, JOIN_SEARCH_CAP
    from icv_envs.sim._kernels.formation import plan_inputs_rows
    from icv_envs.sim._kernels.formation_step import plan_pass
    from icv_envs.sim.join_plans import JOIN_MAX_DURATION

    rng = np.random.default_rng(seed)
    length = 2_000.0 if periodic else -1.0
    anchors = np.append(rng.uniform(0, 2_000, 5), np.nan)
    group = rng.integers(0, 5, n)
    behind = rng.uniform(0, 120, n) * rng.choice([1.0, 0.0], n)
    cx = rng.uniform(0, 2_000, n)
    speed = rng.uniform(0, 40, n)
    accel = rng.uniform(-9, 5, n)
    vid = np.sort(rng.choice(3 * n, n, replace=False)).astype(np.int64)
    rows = np.sort(rng.choice(n, rng.integers(1, n + 1), replace=False)).astype(np.int64)
    v_form, accel_lim, decel, jerk, t_min, time = 25.0, 1.5, 3.0, 2.0, 2.0, float(rng.uniform(0, 500))
    band = (18.0 - v_form, 33.0 - v_form)
    names = ("t0", "T", "d0", "v0", "a0", "c3", "c4", "c5", "fd", "fv", "fa")
    want = {k: rng.normal(size=3 * n) for k in names}
    got = {k: v.copy() for k, v in want.items()}
    d0, v0, a0 = plan_inputs_rows(rows, group, behind, anchors, cx, speed, accel, v_form, -decel, accel_lim, length)
    cb = np.cbrt(60.0 * np.abs(d0) / jerk)
    m = len(rows)
    T_want = join_search_banded(cb, d0, v0, a0, accel_lim, decel, jerk, t_min, JOIN_GROW, JOIN_MAX_DURATION,
                                np.full(m, band[0]), np.full(m, band[1]), True, JOIN_SEARCH_CAP, _PROFILE_SAMPLES)
    plan_rows(vid[rows], time, T_want, d0, v0, a0, *(want[k] for k in names))
    T_got = plan_pass(rows, group, behind, anchors, cx, speed, accel, vid, v_form, length, time, accel_lim, decel,
                      jerk, t_min, JOIN_GROW, JOIN_MAX_DURATION, band[0], band[1], JOIN_SEARCH_CAP, _PROFILE_SAMPLES,
                      *(got[k] for k in names))
    assert T_got.tobytes() == T_want.tobytes()
    for k in names:
        assert got[k].tobytes() == want[k].tobytes(), k


@at_pinned_level  # libm's atan2 against NumPy's arctan2: exact at AVX2 (tests/pinned_numpy.py)
@settings(max_examples=100, deadline=None)
@given(n=st.integers(1, 40), seed=st.integers(0, 2**32 - 1), on_axis=st.booleans())
def test_arc_project_rows_is_the_numpy_expression(n, seed, on_axis):
    """``IntersectionLayout.arc_project`` through ``arc_project_rows`` (from
    stop 50) against the NumPy expression it replaced, bit for bit: points
    around every turn arc, some exactly on the axes through an arc's centre
    (``atan2`` of a zero leg) and at the angle's wrap."""
    from icv_envs.sim._kernels.intersection import arc_project_rows
    from icv_envs.sim.intersection_layout import IntersectionLayout

    lay = IntersectionLayout()
    arcs = np.flatnonzero(lay.arc)
    rng = np.random.default_rng(seed)
    q = rng.choice(arcs, n).astype(np.int64)
    ang = rng.uniform(-np.pi, np.pi, n)
    if on_axis:
        ang[: n // 2] = rng.choice([0.0, np.pi / 2, np.pi, -np.pi / 2], n // 2)
    rad = lay.R[q] + rng.uniform(-3.0, 3.0, n)
    cx = lay.C[q, 0] + rad * np.cos(ang)
    cy = lay.C[q, 1] + rad * np.sin(ang)
    if on_axis:
        cy[: n // 2] = np.where(np.abs(np.sin(ang[: n // 2])) < 0.5, lay.C[q[: n // 2], 1], cy[: n // 2])
    qx, qy = cx - lay.C[q, 0], cy - lay.C[q, 1]
    a = np.arctan2(qy, qx) - lay.TH0[q]
    a = (a + np.pi) % (2.0 * np.pi) - np.pi
    want = (lay.R[q] * a * lay.SGN[q], lay.SGN[q] * (np.hypot(qx, qy) - lay.R[q]))
    got = arc_project_rows(q, cx, cy, lay.C, lay.TH0, lay.R, lay.SGN)
    for g, w in zip(got, want):
        assert g.tobytes() == w.tobytes()
    got2 = lay.arc_project(q, cx, cy)
    for g, w in zip(got2, want):
        assert g.tobytes() == w.tobytes()


def _numpy_lane_change_starts(expert, world, index, active, lane, desired, member):
    """FormationExpert.compute's "start lane changes" as array code (what
    policies/_kernels.lane_change_starts replaced), frozen here as its
    reference: ``(start rows, target lanes, curve lengths, blocked)``."""
    from icv_envs._ufuncs import clip as uclip
    from icv_envs.sim.traffic import followers, idm_acceleration, leaders

    p = expert.p
    tr, road = world.traffic, world.road
    n = tr.n
    cx, cy = tr.center()
    v = tr.speed
    W = road.lane_width
    n_tot = road.total_lanes
    settled = ~active & (np.abs(cy - lane * W) < 0.6)
    blocked = np.zeros(n, dtype=bool)
    want = settled & (desired >= 0) & (desired != lane)
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), blocked, 0)
    if not want.any():
        return empty
    w_rows = np.flatnonzero(want)
    nxt = lane[w_rows] + np.sign(desired[w_rows] - lane[w_rows])
    vw = v[w_rows]
    length = uclip(vw * p.lc_duration, p.lc_min_length, p.lc_max_length)
    xw = cx[w_rows]
    ok = (nxt >= 0) & (nxt < n_tot)
    nxt = uclip(nxt, 0, n_tot - 1)
    ok &= road.available(nxt, xw)
    end_own = road.interval_end(lane[w_rows], xw)
    end_nxt = road.interval_end(nxt, xw)
    k_after = np.abs(desired[w_rows] - nxt)
    room_own = 2.0 * (end_own - xw - 0.5 * tr.length[w_rows])
    room_nxt = end_nxt - xw - 0.5 * p.idm_s0 - k_after * p.lc_min_length
    length = np.minimum(length, np.minimum(room_own, room_nxt))
    ok &= length >= np.maximum(expert._lc_length_min, vw * expert._lc_time_min)
    if road.has_ramp_lane:
        into_ramp = nxt == road.ramp_lane
        from_ramp = lane[w_rows] == road.ramp_lane
        ok &= ~into_ramp | road.in_diverge(xw)
        ok &= ~from_ramp | road.in_merge(xw)
    lead, lx = leaders(index, w_rows, nxt, cx, return_x=True)
    foll, fx = followers(index, w_rows, nxt, cx, return_x=True)
    lw = tr.length[w_rows]
    gap_f = np.where(lead >= 0, lx - xw - 0.5 * (tr.length[lead] + lw), np.inf)
    gap_r = np.where(foll >= 0, xw - fx - 0.5 * (tr.length[foll] + lw), np.inf)
    vl = np.where(lead >= 0, v[lead], vw)
    vf = np.where(foll >= 0, v[foll], 0.0)
    Tw = np.where(member[w_rows], p.member_time_gap, p.idm_T)
    Tf = np.where(member[np.maximum(foll, 0)] & (foll >= 0), p.member_time_gap, p.idm_T)
    own = idm_acceleration(vw, p.v_max, gap_f, vw - vl, p.a_max, p.idm_b, Tw, p.idm_s0, free_term=False)
    fol = idm_acceleration(vf, p.v_max, gap_r, vf - vw, p.a_max, p.idm_b, Tf, p.idm_s0, free_term=False)
    possible = ok.copy()
    min_r = np.where(vf < 0.5, 0.5 * p.idm_s0, p.lc_min_gap)
    ok &= (gap_f > p.lc_min_gap) & (gap_r > min_r) & (own > -p.b_safe) & (fol > -p.b_safe)
    lo, lox = leaders(index, w_rows, lane[w_rows], cx, return_x=True)
    t_half = 0.5 * length / np.maximum(vw, 1.0)
    gap_o = np.where(lo >= 0, lox - xw - 0.5 * (tr.length[lo] + lw), np.inf)
    gap_o = gap_o + np.where(lo >= 0, v[lo], 0.0) * t_half - np.maximum(vw, 1.0) * t_half
    ok &= gap_o >= p.idm_s0
    cand = np.flatnonzero(ok)
    dropped = 0
    if len(cand) > 1:
        o = cand[np.lexsort((-xw[cand], nxt[cand]))]
        dx = road.wrap(xw[o][:-1] - xw[o][1:])
        gap_p = dx - 0.5 * (lw[o][:-1] + lw[o][1:])
        v_rear = vw[o][1:]
        T_rear = np.where(member[w_rows[o][1:]], p.member_time_gap, p.idm_T)
        acc_rear = idm_acceleration(v_rear, p.v_max, np.maximum(gap_p, 1e-3), v_rear - vw[o][:-1], p.a_max,
                                    p.idm_b, T_rear, p.idm_s0, free_term=False)
        near = dx < lw[o][1:] + p.lc_min_gap + 2.0 * p.idm_s0 + v_rear * p.member_time_gap
        same = (nxt[o][1:] == nxt[o][:-1]) & (near | (gap_p <= p.lc_min_gap) | (acc_rear <= -p.b_safe))
        drop = np.zeros(len(o), dtype=bool)
        for k in np.flatnonzero(same):
            if not drop[k]:
                drop[k + 1] = True
        if drop.any():
            last = {}
            for i in range(len(o)):
                if drop[i]:
                    continue
                j = last.get(int(nxt[o[i]]))
                if j is not None:
                    d = road.wrap(xw[o[j]] - xw[o[i]])
                    g = d - 0.5 * (lw[o[j]] + lw[o[i]])
                    Ti = p.member_time_gap if member[w_rows[o[i]]] else p.idm_T
                    a_i = idm_acceleration(vw[o[i]], p.v_max, max(g, 1e-3), vw[o[i]] - vw[o[j]], p.a_max,
                                           p.idm_b, Ti, p.idm_s0, free_term=False)
                    if (d < lw[o[i]] + p.lc_min_gap + 2.0 * p.idm_s0 + vw[o[i]] * p.member_time_gap
                            or g <= p.lc_min_gap or a_i <= -p.b_safe):
                        drop[i] = True
                        continue
                last[int(nxt[o[i]])] = i
        ok[o[drop]] = False
        dropped = int(drop.sum())
    blocked[w_rows[possible & ~ok]] = True
    return w_rows[ok], nxt[ok], length[ok], blocked, dropped


@pytest.mark.parametrize("module, config, random_share, steps", [
    ("highway_formation_v0", {"vehicles_count": 20}, 0.5, 150),
    ("highway_formation_v0", {"scenario": "lane-drop"}, 0.0, 200),
    ("highway_formation_v0", {"scenario": "on-ramp"}, 0.0, 300),
    ("highway_formation_v0", {"scenario": "off-ramp"}, 0.0, 300),
    ("highway_formation_v0", {"vehicles_count": 8, "obstacle": {"lane": 1, "position": 300.0}}, 0.3, 300),
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 80.0}, 0.0, 400),  # the ring (pairs into one lane)
])
def test_expert_lane_change_starts_equal_the_array_code(module, config, random_share, steps):
    """FormationExpert's lane-change decision (compiled) gives the array
    code's starts, target lanes, curve lengths and blocked vehicles bit for
    bit on every call of a run: lane drops, ramps both ways, obstacles,
    random actions, and on the ring several vehicles starting into one lane."""
    import importlib

    from icv_envs.policies.formation_expert import FormationExpert

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    env = mod.parallel_env(**config)
    env.reset(seed=5)
    rng = np.random.default_rng(5)
    seen = {"calls": 0, "starts": 0, "blocked": 0, "dropped": 0}
    orig = FormationExpert._lane_change_starts

    def checked(self, world, index, active, lane, desired, member):
        got = orig(self, world, index, active, lane, desired, member)
        want = _numpy_lane_change_starts(self, world, index, active, lane, desired, member)
        for g, w in zip(got, want[:4]):
            np.testing.assert_array_equal(g, w)
        assert got[0].dtype == np.int64 and got[2].dtype == np.float64 and got[3].dtype == bool
        seen["calls"] += 1
        seen["starts"] += len(got[0])
        seen["blocked"] += int(got[3].sum())
        seen["dropped"] += want[4]
        return got

    _drive_patched(env, rng, steps, random_share, _lane_change_starts=checked)
    assert seen["calls"] > 50 and seen["starts"] > 0
    if module == "highway_ramps_v0":
        assert seen["blocked"] > 0 and seen["dropped"] > 0


def _random_dense_state(seed, scenario):
    """A highway world put into a random dense state (the runs rarely reach
    some of the expert's rules): 60 vehicles more, queued per lane with
    bumper gaps from 0 to 5..45 m (some lanes nearly empty), some standing,
    some slower than 1 m/s, some changing lanes, some off their lane
    centre; with random exits where the road has them."""
    from icv_envs.envs import highway_formation_v0, highway_ramps_v0

    rng = np.random.default_rng(seed)
    if scenario == "ring":
        env = highway_ramps_v0.parallel_env(vgr=0.5, duration=20.0)
    else:
        env = highway_formation_v0.parallel_env(scenario=scenario)
    env.reset(seed=int(seed % 1000))
    core = env.core
    world, expert = core.world, core.expert
    tr, road = world.traffic, world.road
    tr.add(np.zeros(60), np.zeros(60), np.zeros(60))
    n = tr.n
    W = road.lane_width
    x0 = float(rng.uniform(0.0, road.length - 400.0)) if not road.periodic else float(rng.uniform(0, road.length))
    lane = rng.choice(road.total_lanes, n, p=rng.dirichlet(np.full(road.total_lanes, 0.7)))  # some lanes nearly empty
    gaps = rng.uniform(5.0, 10.0 + 40.0 * rng.random(), n)
    xs = np.empty(n)
    for ln in range(road.total_lanes):
        k = np.flatnonzero(lane == ln)
        xs[k] = x0 + rng.uniform(0.0, 20.0) + np.cumsum(gaps[k])
    tr.x = xs
    tr.y = lane * W + rng.choice([0.0, 0.0, 0.3, -0.4, 0.8], n)
    tr.heading = np.zeros(n)
    tr.speed = np.where(rng.random(n) < 0.3, rng.uniform(0.0, 1.5, n), rng.uniform(0.0, 30.0, n))
    tr.lc_lane = np.where(rng.random(n) < 0.15, rng.integers(0, road.total_lanes, n), -1)
    if road.n_exits:
        tr.exit = np.where(rng.random(n) < 0.5, rng.integers(0, road.n_exits, n), -1)
    world.invalidate()
    cx, cy = tr.center()
    lane_now = road.lane_of(cy)
    member = rng.random(n) < 0.5
    return rng, world, expert, lane_now, member


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), scenario=st.sampled_from(["on-ramp", "off-ramp", "lane-drop", "ring"]))
def test_lane_change_starts_on_random_dense_states(seed, scenario):
    """The compiled lane-change decision against the array code on random
    dense states (:func:`_random_dense_state`), with random desired lanes
    (several lane changes away, into and out of the ramp lane), so pairs
    and chains of vehicles start into one lane and the second drop pass
    decides."""
    rng, world, expert, lane_now, member = _random_dense_state(seed, scenario)
    tr, road = world.traffic, world.road
    n = tr.n
    desired = np.where(rng.random(n) < 0.7, rng.integers(-1, road.total_lanes, n), lane_now)
    active = tr.lc_lane >= 0
    index = world.lane_index()
    got = expert._lane_change_starts(world, index, active, lane_now, desired, member)
    want = _numpy_lane_change_starts(expert, world, index, active, lane_now, desired, member)
    for g, w in zip(got, want[:4]):
        np.testing.assert_array_equal(g, w)


def _numpy_exit_lanes(expert, world, lane, lane_ref, member):
    """FormationExpert.compute's desired lanes before the hook, as array code
    (what policies/_kernels.exit_lanes replaced), frozen as its reference."""
    p = expert.p
    tr, road = world.traffic, world.road
    n = tr.n
    cx, _ = tr.center()
    desired = np.where(member, lane_ref, lane)
    if road.has_ramp_lane:
        ramp = road.ramp_lane
        exiting = np.zeros(n, dtype=bool)
        has = (tr.exit >= 0) & ~member
        has_any = tr.exit >= 0
        if has_any.any() and road.n_exits:
            ha = np.flatnonzero(has_any)
            ds_a = road.diverge_start(tr.exit[ha])
            past_a = road.wrap(cx[ha] - ds_a)
            exiting[ha] = (lane[ha] == ramp) & (past_a >= 0) & (past_a <= road.exit_position(tr.exit[ha]) - ds_a)
        if has.any() and road.n_exits:
            dist = road.exit_ahead(tr.exit[has], cx[has])
            dlen = road.diverge_end(tr.exit[has]) - road.diverge_start(tr.exit[has])
            ds = road.diverge_start(tr.exit[has])
            past_ds = road.wrap(cx[has] - ds)
            on_its_off_ramp = (lane[has] == ramp) & (past_ds >= 0) & (past_ds <= road.exit_position(tr.exit[has]) - ds)
            la = road.exit_lookahead(lane[has], p.exit_lookahead, p.exit_lookahead_per_lane)
            exiting[has] |= ((dist < la) & (dist >= -dlen)) | on_its_off_ramp
        desired = np.where(exiting, ramp, desired)
        on_ramp = (lane == ramp) & ~exiting & ~member
        desired = np.where(on_ramp, road.n_lanes - 1, desired)
    else:
        exiting = np.zeros(n, dtype=bool)
    return desired, exiting


def _numpy_lane_end_escape(expert, world, desired, lane, member, exiting):
    """The free vehicles' lane-end escape of FormationExpert.compute as array
    code (what policies/_kernels.lane_end_escape replaced), frozen."""
    p = expert.p
    tr, road = world.traffic, world.road
    cx, _ = tr.center()
    desired = np.array(desired, copy=True)
    free = ~member & ~exiting & (desired == lane) & (lane < road.n_lanes)
    moved = 0
    if free.any():
        end = road.interval_end(lane, cx)
        f_rows = np.flatnonzero(free & np.isfinite(end))
        if len(f_rows):
            lanes_all = np.arange(road.n_lanes)
            ends = road.interval_end(lanes_all[None, :], cx[f_rows][:, None])
            dist = np.abs(lanes_all[None, :] - lane[f_rows][:, None]).astype(np.float64)
            dist = np.where(ends > end[f_rows][:, None] + 50.0, dist, np.inf)
            best = np.argmin(dist + 1e-3 * lanes_all[None, :], axis=1)
            k = dist[np.arange(len(f_rows)), best]
            go = np.isfinite(k) & (end[f_rows] - cx[f_rows] < (k + 1.0) * p.lc_max_length)
            desired[f_rows[go]] = best[go]
            moved = int(go.sum())
    return desired, moved


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), scenario=st.sampled_from(["on-ramp", "off-ramp", "lane-drop", "ring"]))
def test_exit_lanes_and_lane_end_escape_on_random_dense_states(seed, scenario):
    """The compiled desired-lane rules (exits, ramps, lane ends) against the
    array code on random dense states with random exits and target lanes."""
    rng, world, expert, lane_now, member = _random_dense_state(seed, scenario)
    road = world.road
    n = world.traffic.n
    lane_ref = rng.integers(0, road.n_lanes, n)
    got = expert._exit_lanes(world, lane_now, lane_ref, member)
    want = _numpy_exit_lanes(expert, world, lane_now, lane_ref, member)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    desired = np.where(rng.random(n) < 0.3, rng.integers(0, road.total_lanes, n), want[0])
    got_d = expert._lane_end_escape(world, desired, lane_now, member, want[1])
    np.testing.assert_array_equal(got_d, _numpy_lane_end_escape(expert, world, desired, lane_now, member, want[1])[0])


@pytest.mark.parametrize("module, config, random_share, steps", [
    ("highway_formation_v0", {"scenario": "lane-drop"}, 0.0, 200),
    ("highway_formation_v0", {"scenario": "on-ramp"}, 0.0, 300),
    ("highway_formation_v0", {"scenario": "off-ramp"}, 0.0, 300),
    ("highway_formation_v0", {"vehicles_count": 8, "obstacle": {"lane": 1, "position": 300.0}}, 0.3, 300),
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 80.0}, 0.0, 400),
])
def test_expert_desired_lanes_equal_the_array_code(module, config, random_share, steps):
    """On every call of a run, the compiled desired-lane rules give the array
    code's lanes and exiting flags bit for bit; the runs reach exits, ramps
    and lane ends."""
    import importlib

    from icv_envs.policies.formation_expert import FormationExpert

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    env = mod.parallel_env(**config)
    env.reset(seed=6)
    rng = np.random.default_rng(6)
    seen = {"calls": 0, "exiting": 0, "moved": 0}
    orig_x, orig_e = FormationExpert._exit_lanes, FormationExpert._lane_end_escape

    def checked_x(self, world, lane, lane_ref, member):
        got = orig_x(self, world, lane, lane_ref, member)
        want = _numpy_exit_lanes(self, world, lane, lane_ref, member)
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
        seen["calls"] += 1
        seen["exiting"] += int(got[1].sum())
        return got

    def checked_e(self, world, desired, lane, member, exiting):
        got = orig_e(self, world, desired, lane, member, exiting)
        want, moved = _numpy_lane_end_escape(self, world, desired, lane, member, exiting)
        np.testing.assert_array_equal(got, want)
        seen["moved"] += moved
        return got

    _drive_patched(env, rng, steps, random_share, _exit_lanes=checked_x, _lane_end_escape=checked_e)
    assert seen["calls"] > 50
    if config.get("scenario") == "off-ramp" or module == "highway_ramps_v0":
        assert seen["exiting"] > 0
    # (the expert's runs keep their vehicles in formation, so the lane-end
    # escape of free vehicles is reached by the random dense states above)


def _numpy_eligible_free(fm, traffic, road, cx):
    """The free vehicles that may join (FormationManager._eligible_free before
    it was compiled) as array code (what sim/_kernels/formation.eligible_free_rows
    replaced), frozen."""
    free = np.flatnonzero((traffic.group < 0) & ~traffic.crashed)
    _, cy = traffic.center()
    if len(free) and road.has_ramp_lane:
        free = free[(road.lane_of(cy[free]) < road.n_lanes) & (traffic.lc_lane[free] != road.ramp_lane)]
    if len(free) and road.n_exits:
        ex = traffic.exit[free]
        has = ex >= 0
        soon = np.zeros(len(free), dtype=bool)
        if has.any():
            d = road.exit_ahead(ex[has], cx[free[has]])
            dlen = road.diverge_end(ex[has]) - road.diverge_start(ex[has])
            la = road.exit_lookahead(road.lane_of(cy[free[has]]), fm.exit_lookahead, fm.exit_lookahead_per_lane)
            soon[has] = (d < la + 100.0) & (d >= -dlen)
            if not road.periodic:
                soon[has] |= d < -dlen
        free = free[~soon]
    return free


def _numpy_leaving(fm, traffic, road, cx):
    """The members leaving for their exit in FormationManager.update, as
    array code (what sim/_kernels/formation.leaving_rows replaced), frozen."""
    _, cy = traffic.center()
    rows = np.flatnonzero((traffic.exit >= 0) & (traffic.group >= 0))
    if not len(rows):
        return rows
    d = road.exit_ahead(traffic.exit[rows], cx[rows])
    lane_r = road.lane_of(cy[rows])
    la = road.exit_lookahead(lane_r, fm.exit_lookahead, fm.exit_lookahead_per_lane)
    leave = rows[d < la]
    if road.has_ramp_lane:
        on_ramp = (lane_r == road.ramp_lane) | (traffic.lc_lane[rows] == road.ramp_lane)
        leave = rows[(d < la) | on_ramp]
    return leave


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), scenario=st.sampled_from(["on-ramp", "off-ramp", "lane-drop", "ring"]),
       per_lane=st.sampled_from([0.0, 150.0]))
def test_eligible_free_and_leaving_rows_on_random_dense_states(seed, scenario, per_lane):
    """The formation layer's free-vehicle and exit-leaving rules, compiled,
    against the array code on random dense states with random exits,
    memberships and crashes, on straight roads and the ring."""
    from icv_envs.sim._kernels.formation import eligible_free_rows, leaving_rows

    rng, world, _, _, _ = _random_dense_state(seed, scenario)
    tr, road = world.traffic, world.road
    n = tr.n
    fm = world.manager
    fm.exit_lookahead_per_lane = per_lane
    tr.group = np.where(rng.random(n) < 0.5, rng.integers(0, 3, n), -1)
    tr.crashed = rng.random(n) < 0.1
    if road.n_exits:  # some vehicles past their exit (straight road: never rejoin)
        tr.x = tr.x + np.where(rng.random(n) < 0.2, rng.uniform(-800.0, 800.0, n), 0.0)
    cx, cy = tr.center()
    got = eligible_free_rows(tr.group, tr.crashed, cx, cy, tr.lc_lane, tr.exit, float(road.lane_width),
                             int(road.total_lanes), int(road.n_lanes), bool(road.has_ramp_lane), int(road.n_exits),
                             road._diverge_iv, float(road.length) if road.periodic else -1.0,
                             float(fm.exit_lookahead), float(fm.exit_lookahead_per_lane))
    np.testing.assert_array_equal(got, _numpy_eligible_free(fm, tr, road, cx))
    assert got.dtype == np.int64
    if road.n_exits:
        got = leaving_rows(tr.group, tr.exit, cx, cy, tr.lc_lane, float(road.lane_width), int(road.total_lanes),
                           int(road.n_lanes), bool(road.has_ramp_lane), road._diverge_iv,
                           float(road.length) if road.periodic else -1.0, float(fm.exit_lookahead),
                           float(fm.exit_lookahead_per_lane))
        np.testing.assert_array_equal(got, _numpy_leaving(fm, tr, road, cx))


@settings(max_examples=300, deadline=None)
@given(a=st.floats(allow_nan=True, allow_infinity=True, width=64),
       b=st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64).filter(lambda v: v != 0.0),
                   st.sampled_from([10_000.0, 1e-300, -3.5, np.inf])),
       near=st.floats(-2.0, 2.0))
def test_npy_mod_is_numpy_mod_bit_for_bit(a, b, near):
    """``npy_mod`` (its ``0 < a < b`` shortcut and NumPy's ``npy_divmod``
    otherwise) gives ``numpy.mod``'s bits, the sign of a zero and NaN
    included, on arbitrary floats and near the period's multiples."""
    from icv_envs.sim._kernels import npy_mod

    for x in (a, near * b if np.isfinite(b) else near, -0.0, 0.0):
        with np.errstate(all="ignore"):
            want = np.mod(np.float64(x), np.float64(b))
        got = npy_mod(float(x), float(b))
        assert np.float64(got).tobytes() == want.tobytes() or (np.isnan(got) and np.isnan(want)), (x, b, got, want)


_ACTION_VALUES = st.one_of(st.floats(-3.0, 3.0, allow_nan=False, width=64),
                           st.sampled_from([-1.0, 1.0, -0.0, 0.0, np.nextafter(1.0, 2.0), np.nextafter(-1.0, -2.0),
                                            5e-324, -5e-324, float("nan"), float("inf"), float("-inf")]))


@settings(max_examples=300, deadline=None)
@given(rows=st.lists(st.tuples(_ACTION_VALUES, _ACTION_VALUES), max_size=12),
       a_min=st.sampled_from([-6.0, -20.0, -0.5]), a_max=st.sampled_from([3.0, 20.0, 0.5]),
       steer=st.sampled_from([np.radians(30.0), np.radians(5.0), 1.0]))
def test_controls_rows_is_action_to_controls_bit_for_bit(rows, a_min, a_max, steer):
    """The compiled action -> control map (the envs' ``_controls``) against
    :func:`icv_envs.envs.actions.action_to_controls`, the array code it
    replaced: clip ties, signed zeros, the branch at 0, subnormals, NaN/inf."""
    from icv_envs.envs.actions import action_to_controls
    from icv_envs.sim._kernels import controls_rows

    acts = np.array(rows, dtype=np.float64).reshape(-1, 2)
    want_a, want_phi = action_to_controls(acts, a_min, a_max, steer)
    got_a, got_phi = controls_rows(acts, a_min, a_max, steer)
    assert got_a.tobytes() == np.asarray(want_a, dtype=np.float64).tobytes()
    assert got_phi.tobytes() == np.asarray(want_phi, dtype=np.float64).tobytes()


@settings(max_examples=300, deadline=None)
@given(rows=st.lists(st.tuples(_ACTION_VALUES, _ACTION_VALUES), max_size=12), data=st.data())
def test_expert_match_rows_is_the_array_test(rows, data):
    """The compiled expert-driven test (``IcvAgentsEnv._before_physics``)
    against the numpy expression it replaced, on actions equal to the
    expert's float32 labels, within and beyond the tolerance by an ulp, and
    NaN/inf on either side."""
    from icv_envs.envs._kernels import expert_match_rows

    acts = np.array(rows, dtype=np.float64).reshape(-1, 2)
    how = data.draw(st.lists(st.sampled_from(["same", "tol", "beyond", "other"]), min_size=len(acts),
                             max_size=len(acts)))
    ex = np.empty((len(acts), 2), dtype=np.float32)
    for i, h in enumerate(how):
        base = acts[i].astype(np.float32)
        if h == "tol":
            base = (acts[i] + 1e-6).astype(np.float32)
        elif h == "beyond":
            base = np.nextafter((acts[i] + 1e-6).astype(np.float32), np.float32(np.inf))
        elif h == "other":
            base = np.array(data.draw(st.tuples(_ACTION_VALUES, _ACTION_VALUES)), dtype=np.float32)
        ex[i] = base
    with np.errstate(invalid="ignore"):
        want = np.all(np.abs(acts - ex) <= 1e-6, axis=1)
    assert np.array_equal(expert_match_rows(acts, ex, 1e-6), want)


@settings(max_examples=100, deadline=None)
@given(K=st.integers(1, 6), B=st.integers(1, 3), data=st.data())
def test_scatter_world_rows_is_the_slot_assignments(K, B, data):
    """``BatchedWorlds``' compiled scatter against the numpy assignments it
    replaced: world ``b`` cleared, its rows written to their (distinct)
    slots, the mask set where the agent neither terminated nor truncated;
    the other worlds untouched."""
    from icv_envs.envs._kernels import scatter_expert_rows, scatter_world_rows

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    b = data.draw(st.integers(0, B - 1))
    k = np.array(data.draw(st.permutations(range(K)))[:data.draw(st.integers(0, K))], dtype=np.int64)
    n = len(k)
    shape = (3, 2)
    o_obs = rng.normal(size=(n,) + shape).astype(np.float32)
    o_rew, o_term, o_trunc = rng.normal(size=n), rng.random(n) < 0.3, rng.random(n) < 0.3
    start = (rng.normal(size=(B, K) + shape).astype(np.float32), rng.random((B, K)) < 0.5, rng.normal(size=(B, K)),
             rng.random((B, K)) < 0.5, rng.random((B, K)) < 0.5)
    want = [a.copy() for a in start]
    obs, mask, rew, term, trunc = want
    obs[b] = 0.0
    mask[b] = False
    obs[b, k] = o_obs
    rew[b, k] = o_rew
    term[b, k] = o_term
    trunc[b, k] = o_trunc
    mask[b, k[~(o_term | o_trunc)]] = True
    got = [a.copy() for a in start]
    scatter_world_rows(got[0].reshape(B, K, -1), got[1], got[2], got[3], got[4], b, k, o_obs.reshape(n, 6), o_rew,
                       o_term, o_trunc)
    for g, w in zip(got, want):
        assert g.tobytes() == w.tobytes()
    ex_start = rng.normal(size=(B, K, 2)).astype(np.float32)
    ex = rng.normal(size=(n, 2)).astype(np.float32)
    want_ex = ex_start.copy()
    want_ex[b] = 0.0
    want_ex[b, k] = ex
    got_ex = ex_start.copy()
    scatter_expert_rows(got_ex, b, k, ex)
    assert got_ex.tobytes() == want_ex.tobytes()


@settings(max_examples=200, deadline=None)
@given(a=st.lists(st.integers(-2**63, 2**63 - 1), max_size=8), b=st.lists(st.integers(-2**63, 2**63 - 1), max_size=8),
       same=st.booleans())
def test_same_ids_is_array_equal_for_id_arrays(a, b, same):
    """``dict_edge.same_ids`` (the step's nobody-came-or-went test) gives
    ``np.array_equal``'s answer on int64 id arrays, and False across dtypes."""
    from icv_envs.envs.dict_edge import same_ids

    x = np.array(a, dtype=np.int64)
    y = x.copy() if same else np.array(b, dtype=np.int64)
    assert same_ids(x, y) == np.array_equal(x, y)
    assert not same_ids(x, y.astype(np.int32))  # another dtype: never the same


@settings(max_examples=200, deadline=None)
@given(k=st.integers(0, 6), n=st.integers(0, 500), dt=st.sampled_from([0.04, 0.1, 1.0 / 15.0, 0.02]),
       start=st.tuples(st.integers(0, 10**9), st.floats(0, 1e9), st.floats(0, 1e9), st.floats(0, 1e9),
                       st.integers(0, 10**9)), seed=st.integers(0, 2**32 - 1))
def test_motion_sums_add_is_add_row_by_row(k, n, dt, start, seed):
    """``motion_sums_add`` over ``MotionStats.totals`` / ``set_totals`` (what
    the compiled substeps do with their per-substep sums) leaves the
    accumulators :meth:`MotionStats.add` row by row leaves, bit for bit."""
    from icv_envs.sim._kernels import motion_sums_add
    from icv_envs.sim.metrics import MotionStats

    rng = np.random.default_rng(seed)
    sums = rng.uniform(0, 1e4, (k, 3)) * rng.choice([1.0, 1e-9, 1e9], (k, 3))
    stopped = rng.integers(0, n + 1, k)
    a, b = MotionStats(), MotionStats()
    for m in (a, b):
        (m.vehicle_steps, m.speed_sum, m.realised_abs_accel_sum, m.commanded_abs_accel_sum, m.stopped_steps) = start
    for (sv, sdv, sa), ns in zip(sums.tolist(), stopped.tolist()):
        a.add(n, sv, sdv, sa, ns, dt)
    b.set_totals(*motion_sums_add(k, n, sums, stopped, dt, *b.totals()))
    for name in ("vehicle_steps", "speed_sum", "realised_abs_accel_sum", "commanded_abs_accel_sum", "stopped_steps"):
        x, y = getattr(a, name), getattr(b, name)
        assert type(x) is type(y) and np.float64(x).tobytes() == np.float64(y).tobytes(), name


@pytest.mark.parametrize("module, config, random_share", [
    ("highway_formation_v0", {"vehicles_count": 20}, 0.3),  # collisions, free vehicles
    ("highway_formation_v0", {"scenario": "off-ramp"}, 0.1),  # exits
    ("highway_formation_v0", {"scenario": "on-ramp"}, 0.1),  # a ramp lane
    ("highway_formation_v0", {"scenario": "lane-drop"}, 0.1),  # lane ends
    ("highway_ramps_v0", {"vgr": 0.5, "duration": 60.0}, 0.1),  # the ring: lane speed table, exits
    ("highway_formation_v0", {"vehicles_count": 8, "spawns": [  # from standstill: the envelope's a_max clip binds
        {"time": 1.0, "position": 30.0, "lane": 0, "speed": 0.0},
        {"time": 2.0, "position": 60.0, "lane": 3, "speed": 1.0}]}, 0.0),
])
def test_formation_expert_one_call_runs_equal_the_separate_calls(module, config, random_share):
    """``FormationExpert.compute``'s one-call runs (desired lanes; lane
    speeds and the free term's base; longitudinal law, safety envelope and
    normalised actions) give the separate hooks' actions bit for bit: two
    envs of one seed in lockstep, one forced onto the separate calls by
    hooks set on its expert (which the one-call path must notice), the same
    actions fed to both; the fused kernels are counted on the other."""
    import importlib

    import icv_envs.policies.formation_expert as fe

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    a, b = mod.parallel_env(**config), mod.parallel_env(**config)
    a.reset(seed=11)
    b.reset(seed=11)
    ex_b = b.core.expert
    for name in ("_exit_lanes", "_safety_cap"):  # one hook of each run, set on the instance
        setattr(ex_b, name, getattr(type(ex_b), name).__get__(ex_b))
    # the one-call kernels (env a) and the separate ones (env b: called from Python only there)
    calls = {"desired_lane_rows": 0, "expert_control_rows": 0, "free_speed_pow_rows": 0, "exit_lanes": 0,
             "safety_cap": 0, "expert_lane_speeds": 0}
    saved = {k: getattr(fe, k) for k in calls}

    def counting(k):
        def f(*args):
            calls[k] += 1
            return saved[k](*args)
        return f

    rng = np.random.default_rng(11)
    steps = 0
    try:
        for k in calls:
            setattr(fe, k, counting(k))
        for _ in range(150):
            if not a.agents:
                break
            ea, eb = a.core.expert_actions(), b.core.expert_actions()
            assert a.agents == b.agents and ea.tobytes() == eb.tobytes()
            ex = a.expert_actions()
            acts = {g: (rng.uniform(-1, 1, 2) if rng.random() < random_share else ex[g]) for g in a.agents}
            oa, *_ = a.step(acts)
            ob, *_ = b.step(dict(acts))
            assert all(oa[g].tobytes() == ob[g].tobytes() for g in oa)
            steps += 1
    finally:
        for k, f in saved.items():
            setattr(fe, k, f)
    assert steps > 30 and all(c >= steps for c in calls.values()), calls  # (one expert step per policy step, at least)


def _scenario_road(scenario: str):
    from icv_envs.envs.highway_formation_v0 import parallel_env

    env = parallel_env(scenario=scenario)
    env.reset(seed=0)
    return env.core.world.road


_ROADS = {}


@settings(max_examples=200, deadline=None)
@given(lanes=st.lists(st.integers(-3, 8), max_size=20), table=st.one_of(st.none(), st.lists(
       st.floats(1.0, 40.0), min_size=1, max_size=6)), scenario=st.sampled_from(["lane-change", "on-ramp"]))
def test_lane_speeds_equal_the_array_code(lanes, table, scenario):
    """``FormationExpert._lane_speeds`` (compiled: ``lane_speed_rows``, which
    the one-call tail of ``compute`` also calls) against the numpy rule it
    replaced: the table at the clipped lane, else the ramp speed in a ramp
    lane (the on-ramp road has one) and the desired speed elsewhere."""
    from icv_envs._ufuncs import clip as uclip
    from icv_envs.policies.formation_expert import ExpertParams, FormationExpert

    p = ExpertParams(lane_speeds=None if table is None else tuple(table))
    road = _ROADS.get(scenario) or _ROADS.setdefault(scenario, _scenario_road(scenario))
    lane = np.array(lanes, dtype=np.int64)
    if p.lane_speeds is not None:
        t = np.asarray(p.lane_speeds, dtype=np.float64)
        want = t[uclip(lane, 0, len(t) - 1)]
    else:
        want = np.where((lane == road.n_lanes) & road.has_ramp_lane, p.ramp_speed, p.desired_speed)
    got = FormationExpert(p)._lane_speeds(road, lane)
    assert got.tobytes() == np.asarray(want, dtype=np.float64).tobytes()


@settings(max_examples=200, deadline=None)
@given(lanes=st.integers(1, 7), width=st.sampled_from([3.5, 4.0, 3.75, 0.1]),
       ys=st.lists(st.floats(-1e4, 1e4, allow_nan=False), max_size=40),
       halves=st.lists(st.integers(-3, 9), max_size=10))
def test_lane_of_rows_is_lane_of(lanes, width, ys, halves):
    """``RoadLayout.lane_of_rows`` (the expert's lanes of a state in one
    call) gives ``lane_of``'s int64 lanes, on random positions, lane
    centres' halves (``rint``'s ties to even) and beyond both edges."""
    road = RoadLayout(lanes, 1_000.0, width, np.full(lanes, np.inf), [], [], [])
    y = np.array(ys + [(h + 0.5) * width for h in halves] + [h * width for h in halves], dtype=np.float64)
    got = road.lane_of_rows(y)
    want = road.lane_of(y)
    assert got.dtype == want.dtype == np.int64
    np.testing.assert_array_equal(got, want)


@settings(max_examples=200, deadline=None)
@given(ids=st.lists(st.integers(-2**40, 2**40), min_size=1, max_size=60))
def test_id_range_is_min_and_max(ids):
    """``sim/_kernels.id_range`` (the slot lookup's bounds of a world's ids,
    the join plans' table size) is ``(min, max)``."""
    from icv_envs.sim._kernels import id_range

    vid = np.array(ids, dtype=np.int64)
    assert id_range(vid) == (vid.min(), vid.max())


def test_heading_cos_sin_is_numpys_kept_per_heading_array():
    """``Traffic.heading_cos_sin``: NumPy's cos and sin of the headings,
    the same arrays while ``heading`` is, new ones once it is replaced; the
    headings read-only from the first call (an in-place write would leave
    them stale); the expert's pure pursuit with them is the pursuit without."""
    from icv_envs.formation.bezier import _pure_pursuit_rows
    from icv_envs.sim.traffic import Traffic

    rng = np.random.default_rng(3)
    tr = Traffic()
    tr.add(rng.uniform(0, 500, 12), rng.uniform(0, 12, 12), rng.uniform(10, 30, 12))
    tr.heading = rng.uniform(-0.3, 0.3, tr.n)
    c, s = tr.heading_cos_sin()
    np.testing.assert_array_equal(c, np.cos(tr.heading))
    np.testing.assert_array_equal(s, np.sin(tr.heading))
    assert tr.heading_cos_sin()[0] is c
    with pytest.raises(ValueError):
        tr.heading[0] = 1.0
    px, py = tr.x + 20.0, tr.y + rng.uniform(-2, 2, tr.n)
    np.testing.assert_array_equal(_pure_pursuit_rows(tr.x, tr.y, tr.heading, px, py, 2.5, 0.5, (c, s)),
                                  _pure_pursuit_rows(tr.x, tr.y, tr.heading, px, py, 2.5, 0.5))
    tr.heading = tr.heading + 0.1
    c2, _ = tr.heading_cos_sin()
    assert c2 is not c
    np.testing.assert_array_equal(c2, np.cos(tr.heading))


@settings(max_examples=200, deadline=None)
@given(n=st.integers(1, 40), periodic=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_plan_inputs_rows_is_the_array_code(n, periodic, seed):
    """``plan_inputs_rows`` (``FormationManager._plan``'s inputs in one
    call) against the array code it replaced, bit for bit: members on a
    ring (offsets folded across the seam) or a straight road, accelerations
    beyond both profile limits."""
    from icv_envs.sim._kernels.formation import plan_inputs_rows

    rng = np.random.default_rng(seed)
    road = RoadLayout(3, 2_000.0, 4.0, np.full(3, np.inf), [], [], [], periodic=periodic)
    anchors = np.append(rng.uniform(0, 2_000, 6), np.nan)
    group = rng.integers(0, 6, n)
    behind = rng.uniform(0, 120, n) * rng.choice([1.0, 0.0], n)
    cx, speed = rng.uniform(0, 2_000, n), rng.uniform(0, 40, n)
    accel = rng.uniform(-9, 5, n) * rng.choice([1.0, 1e-9], n)
    rows = np.sort(rng.choice(n, rng.integers(1, n + 1), replace=False)).astype(np.int64)
    lo, hi, v_form = -3.0, 1.5, 25.0
    want = (road.wrap(cx[rows] - (anchors[group[rows]] - behind[rows])), speed[rows] - v_form,
            np.clip(accel[rows], lo, hi))
    got = plan_inputs_rows(rows, group, behind, anchors, cx, speed, accel, v_form, lo, hi,
                           road.length if periodic else -1.0)
    for g, w in zip(got, want):
        assert g.tobytes() == w.tobytes()


@settings(max_examples=300, deadline=None)
@given(n=st.integers(1, 40), K=st.integers(0, 12), grid=st.booleans(), pd=st.sampled_from([0.5, 3.0, 30.0, 100.0, np.inf]),
       nan=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_nearest_euclidean_is_a_sort_by_distance_then_row(n, K, grid, pd, nan, seed):
    """The intersection observation's neighbours: per query row the first
    ``K`` others by (np.hypot distance, row) within ``pd``; a grid of
    integer positions makes exact ties common (formations spawn symmetric
    about a vehicle); NaN positions are never neighbours."""
    from icv_envs.sim._kernels import nearest_euclidean

    rng = np.random.default_rng(seed)
    x = rng.integers(-3, 4, n).astype(float) if grid else rng.uniform(-50, 50, n)
    y = rng.integers(-3, 4, n).astype(float) if grid else rng.uniform(-50, 50, n)
    if nan:
        x[rng.integers(0, n)] = np.nan
    K = min(K, n - 1)
    rows = rng.permutation(n)[:rng.integers(0, n + 1)].astype(np.int64)
    sel, present = nearest_euclidean(x, y, rows, K, pd)
    assert sel.shape == present.shape == (len(rows), K)
    for r, o in enumerate(rows):
        d = np.hypot(x - x[o], y - y[o])
        ok = (np.arange(n) != o) & (d <= pd)
        cand = np.flatnonzero(ok)
        want = cand[np.lexsort((cand, d[cand]))][:K]
        assert present[r].sum() == len(want)
        assert not present[r, len(want):].any()
        np.testing.assert_array_equal(sel[r, :len(want)], want)


def _numpy_corridor_leaders(lead, rows, coord, length, speed, n):
    """The intersection env's ``_leaders`` array code (before stop 40)."""
    gap = np.full(n, np.inf)
    dv = np.zeros(n)
    e = np.flatnonzero(lead >= 0)
    if len(e):
        me = rows[e]
        ld = rows[lead[e]]
        g = coord[lead[e]] - coord[e] - 0.5 * (length[me] + length[ld])
        np.minimum.at(gap, me, g)
        o = np.lexsort((g, me))
        me_o, first = me[o], np.ones(len(o), dtype=bool)
        first[1:] = me_o[1:] != me_o[:-1]
        pick = o[first]
        dv[me[pick]] = speed[me[pick]] - speed[ld[pick]]
    return gap, dv


@settings(max_examples=300, deadline=None)
@given(n=st.integers(1, 30), m=st.integers(0, 80), grid=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_corridor_leaders_is_the_array_code(n, m, grid, seed):
    """Random corridor entries (several per vehicle, leaders anywhere, -1
    for none); integer coordinates and lengths make equal gaps common."""
    from icv_envs.sim._kernels import corridor_leaders

    rng = np.random.default_rng(seed)
    rows = rng.integers(0, n, m)
    lead = np.where(rng.random(m) < 0.7, rng.integers(0, max(m, 1), m), -1) if m else np.zeros(0, dtype=np.int64)
    coord = rng.integers(-5, 5, m).astype(float) if grid else rng.normal(0, 30, m)
    length = rng.integers(4, 6, n).astype(float) if grid else rng.uniform(3, 12, n)
    speed = rng.uniform(0, 15, n)
    got = corridor_leaders(lead.astype(np.int64), rows.astype(np.int64), coord, length, speed, n)
    want = _numpy_corridor_leaders(lead, rows, coord, length, speed, n)
    for a, b in zip(got, want):
        assert a.tobytes() == b.tobytes()


@settings(max_examples=300, deadline=None)
@given(sizes=st.lists(st.integers(1, 6), min_size=0, max_size=12), grid=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_node_heads_is_the_stable_sorts_choice(sizes, grid, seed):
    """``node_heads`` against the array code of ``VirtualPlatoon.tree`` it
    replaced: per node the member of least distance and the one of largest X
    by two stable lexsorts (integer values make ties common; rows -1 for
    members no longer on the road read the last vehicle, as numpy's indexing
    does, before the kernel is called)."""
    from icv_envs.policies._kernels import node_heads

    rng = np.random.default_rng(seed)
    sizes = np.asarray(sizes, dtype=np.int64)
    m = int(sizes.sum())
    n = max(m, 1) + 3
    rows = rng.integers(-1, n, m).astype(np.int64)
    Xs = rng.integers(-3, 3, n).astype(float) if grid else rng.normal(0, 50, n)
    ds = rng.integers(0, 4, n).astype(float) if grid else rng.uniform(0, 300, n)
    X, dist = Xs[rows], ds[rows]
    seg = np.repeat(np.arange(len(sizes)), sizes)
    i0 = np.lexsort((dist, seg))
    i1 = np.lexsort((-X, seg))
    head = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.int64) if len(sizes) else np.zeros(0, dtype=np.int64)
    i0, i1 = i0[head], i1[head]
    (first, rear_row), (xf, rear) = node_heads(rows, sizes, X, dist)
    np.testing.assert_array_equal(first, rows[i0])
    np.testing.assert_array_equal(rear_row, rows[i1])
    assert xf.tobytes() == X[i0].tobytes() and rear.tobytes() == X[i1].tobytes()


@settings(max_examples=200, deadline=None)
@given(periodic=st.booleans(), data=st.data())
def test_ramp_spawns_blocked_is_the_array_test(periodic, data):
    """``HighwayRampsEnv._spawn_due``'s compiled test of the spawn points
    (from stop 56) against the NumPy expression it replaced, per ramp:
    a vehicle in the ramp lane (``lane_of``) strictly within (-10, 25) m of
    the spawn point along the road (``wrap``), on a ring and on a straight
    road, with vehicles placed on the bounds and around the seam."""
    from icv_envs.envs._kernels import ramp_spawns_blocked

    length = 2000.0
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    road = _random_road(rng, ramps=((500.0, 700.0),), periodic=periodic)
    n_ramps = data.draw(st.integers(1, 5))
    x0s = np.sort(rng.uniform(0.0, length, n_ramps)).astype(np.float64)
    n = data.draw(st.integers(0, 30))
    k = rng.integers(0, n_ramps, n) if n_ramps else np.zeros(n, dtype=np.int64)
    edge = np.array([-10.0, 25.0, -10.000001, 24.999999, 0.0, length / 2, -length / 2], dtype=np.float64)
    off = np.where(rng.random(n) < 0.3, edge[rng.integers(0, len(edge), n)], rng.uniform(-60.0, 60.0, n))
    cx = x0s[k] + off if n else np.zeros(0)
    ramp_lane = int(road.ramp_lane)
    cy = rng.integers(0, 5, n).astype(np.float64) * road.lane_width + rng.uniform(-2.0, 2.0, n)
    want = np.zeros(n_ramps, dtype=bool)
    for r in range(n_ramps):
        on_ramp = road.lane_of(cy) == ramp_lane if n else np.zeros(0, dtype=bool)
        d = road.wrap(cx[on_ramp] - x0s[r]) if on_ramp.any() else np.zeros(0)
        want[r] = bool(((d > -10.0) & (d < 25.0)).any())
    got = ramp_spawns_blocked(cx, cy, float(road.lane_width), int(road.total_lanes), ramp_lane, x0s,
                              length if periodic else -1.0, -10.0, 25.0)
    assert np.array_equal(got, want)


@settings(max_examples=400, deadline=None)
@given(n=st.integers(0, 13), kind=st.sampled_from(["uniform", "integers", "constant", "rounded", "signed"]),
       seed=st.integers(0, 2**32 - 1))
def test_min_cost_assignment_is_scipys(n, kind, seed):
    """The compiled assignment of the re-forming (from stop 56) gives SciPy's
    ``linear_sum_assignment`` answer, the one it replaced, on random,
    integer-valued (many ties), constant (every assignment ties),
    rounded-square (ties up to rounding) and signed matrices."""
    from scipy.optimize import linear_sum_assignment

    from icv_envs.formation._kernels import min_cost_assignment

    rng = np.random.default_rng(seed)
    if kind == "uniform":
        c = rng.random((n, n)) * 100.0
    elif kind == "integers":
        c = rng.integers(0, 4, (n, n)).astype(np.float64)
    elif kind == "constant":
        c = np.full((n, n), float(rng.integers(0, 3)))
    elif kind == "rounded":
        c = np.round(rng.normal(size=(n, n)) * 3.0, 1) ** 2
    else:
        c = rng.normal(size=(n, n)) * 1e3
    rows, cols = linear_sum_assignment(c)
    want = np.empty(n, dtype=np.int64)
    want[rows] = cols
    assert np.array_equal(min_cost_assignment(c), want)


def test_min_cost_assignment_refuses_what_scipy_refuses():
    """A NaN or -inf entry, or no finite assignment: SciPy raises, the
    kernel answers -1 for every row and ``reform_members`` raises; a +inf
    entry with a finite assignment elsewhere is an ordinary cost."""
    from scipy.optimize import linear_sum_assignment

    from icv_envs.formation._kernels import min_cost_assignment

    for c in ([[np.nan, 1.0], [1.0, 2.0]], [[-np.inf, 1.0], [1.0, 2.0]], [[np.inf, np.inf], [1.0, 2.0]]):
        c = np.array(c)
        with pytest.raises(ValueError):
            linear_sum_assignment(c)
        assert min_cost_assignment(c).tolist() == [-1, -1]
    c = np.array([[np.inf, 1.0], [1.0, 2.0]])
    assert min_cost_assignment(c).tolist() == linear_sum_assignment(c)[1].tolist() == [1, 0]
