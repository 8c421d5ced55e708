"""The compiled corridor index (:func:`icv_envs.policies._kernels.corridor_index`, behind
:class:`~icv_envs.policies.platoon_common.Corridors`) and its neighbour search against the numpy code they replaced, on states of
real intersection runs with random signal lanes: the same entries, bit for bit."""

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.policies.platoon_common import Corridors


def _numpy_index(world, rs, signal_lane, diverge=10.0):
    BIG = 1.0e5
    f = world.fleet
    lay = world.layout
    w = lay.lane_width
    n = f.n
    rows, corr, coord, sigflag = [], [], [], []
    appr = rs.phase == 0
    idx = np.arange(n)
    # half the footprint's lateral extent, heading included: a vehicle
    # stopped at an angle in the middle of a lane change reaches further
    # into the lane it leaves than its width says (single-vp, 4500 veh/h,
    # seed 0: the follower in that lane, no longer seeing it with the
    # former 0.3 m slack on the width, hit its rear corner)
    ad = lay.app_dir[f.leg]
    dh = f.heading - np.arctan2(ad[:, 1], ad[:, 0]) if n else np.zeros(0)
    reach = 0.5 * w + 0.5 * (f.length * np.abs(np.sin(dh)) + f.width * np.abs(np.cos(dh)))
    for dl in (-1, 0, 1):
        ln = rs.lane + dl
        ok = appr & (ln >= 0) & (ln < 3) & (np.abs(rs.lat_leg - (ln + 0.5) * w) < reach)
        rows.append(idx[ok])
        corr.append((3 * f.leg + ln)[ok])
        coord.append(rs.s[ok])
        sigflag.append(np.zeros(int(ok.sum()), dtype=bool))
    sig = appr & (signal_lane >= 0)
    if sig.any():
        rows.append(idx[sig])
        corr.append((3 * f.leg + signal_lane)[sig])
        coord.append(rs.s[sig])
        sigflag.append(np.ones(int(sig.sum()), dtype=bool))
    box = rs.phase == 1
    if box.any():
        rows.append(idx[box])
        corr.append(24 + rs.pid[box])
        coord.append(rs.s[box])
        sigflag.append(np.zeros(int(box.sum()), dtype=bool))
        early = box & (rs.s < diverge)
        rows.append(idx[early])
        corr.append((3 * f.leg + np.maximum(f.plane, 0))[early])
        coord.append(rs.s[early])
        sigflag.append(np.zeros(int(early.sum()), dtype=bool))
    dep = (rs.phase == 2) | (box & (rs.s > rs.L - diverge))
    if dep.any():
        ex = np.where(f.exit_leg >= 0, f.exit_leg, lay.exit_of[f.mv])
        rows.append(idx[dep])
        corr.append((12 + 3 * ex + lay.dlane[rs.pid])[dep])
        coord.append((rs.s - rs.L)[dep])
        sigflag.append(np.zeros(int(dep.sum()), dtype=bool))
    rows = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
    corr = np.concatenate(corr) if corr else np.zeros(0, dtype=np.int64)
    coord = np.concatenate(coord) if coord else np.zeros(0)
    sigflag = np.concatenate(sigflag) if sigflag else np.zeros(0, dtype=bool)
    if len(rows):
        # first occurrence wins: a vehicle whose body covers its signal
        # lane is listed there physically, not as a signal only
        pair = rows * 64 + corr
        _, first = np.unique(pair, return_index=True)
        first = np.sort(first)
        rows, corr, coord, sigflag = rows[first], corr[first], coord[first], sigflag[first]
    keys = corr * BIG + coord
    order = np.lexsort((rows, keys))
    rows_ = rows[order].astype(np.int64)
    corr_ = corr[order].astype(np.int64)
    coord_ = coord[order]
    keys_ = keys[order]
    sig_ = sigflag[order]
    m = len(rows_)
    lead = np.full(m, -1, dtype=np.int64)
    if m > 1:
        same = corr_[1:] == corr_[:-1]
        lead[:-1][same] = np.arange(1, m)[same]
    return rows_, corr_, coord_, keys_, sig_, lead


def _numpy_neighbours(cor, q_rows, q_corr, q_coord):
    """The numpy neighbour search the kernel replaced."""
    k = len(q_rows)
    lr, lc = np.full(k, -1, dtype=np.int64), np.full(k, np.inf)
    fr, fc = np.full(k, -1, dtype=np.int64), np.full(k, -np.inf)
    m = len(cor.keys)
    if not m or not k:
        return lr, lc, fr, fc
    pos = np.searchsorted(cor.keys, q_corr * cor.BIG + q_coord, side="right")
    for out_r, out_c, steps in ((lr, lc, range(4)), (fr, fc, range(-1, -5, -1))):
        todo = np.ones(k, dtype=bool)
        for j in steps:
            p = pos + j
            valid = todo & (p < m) & (p >= 0)
            pc = np.clip(p, 0, m - 1)
            valid &= cor.corr[pc] == q_corr
            hit = valid & (cor.rows[pc] != q_rows)
            out_r[hit] = cor.rows[pc[hit]]
            out_c[hit] = cor.coord[pc[hit]]
            todo &= ~hit & valid
    return lr, lc, fr, fc


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 0), ("single-vp", 4000.0, 1), ("fcfs", 2000.0, 2)])
def test_corridor_index_matches_the_numpy_code(method, throughput, seed):
    env = parallel_env(method=method, throughput=throughput, duration=120.0)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    checked = 0
    for step in range(300):
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
        if step % 10:
            continue
        w = env.core.world
        rs = w.route()
        n = w.fleet.n
        for sig in (np.full(n, -1), rng.integers(-1, 3, n)):
            cor = Corridors(w, rs, sig)
            ref = _numpy_index(w, rs, sig)
            for got, want in zip((cor.rows, cor.corr, cor.coord, cor.keys, cor.signal_only, cor.lead), ref):
                assert got.dtype == want.dtype and np.array_equal(got, want)
            checked += len(ref[0])
            # every vehicle asked in its own approach lane and in a random one, at its coordinate and beside it
            q = np.arange(n)
            for qc, qx in ((3 * w.fleet.leg + rs.lane, rs.s), (rng.integers(0, 60, n), rs.s + rng.normal(0, 5, n))):
                for got, want in zip(cor.neighbours(q, qc, qx), _numpy_neighbours(cor, q, qc, qx)):
                    assert got.dtype == want.dtype and np.array_equal(got, want)
    assert checked > 1000


def test_plain_corridors_are_shared_within_one_state_and_rebuilt_after_it():
    """``Corridors.plain`` (no turn signals) is built once per route state:
    the same object while the world's route state is unchanged, a new one
    after a step, after a spawn-like invalidation and for another route
    state; and always equal to a fresh build. The per-vehicle inputs, kept
    per route state too, give an index with signals equal to one built from
    fresh inputs."""
    env = parallel_env(method="multi-vp", throughput=3000.0, duration=60.0)
    obs, infos = env.reset(seed=2)
    w = env.core.world
    names = ("rows", "corr", "coord", "keys", "signal_only", "lead")
    rng = np.random.default_rng(0)
    seen = 0
    for _ in range(120):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
        rs = w.route()
        a = Corridors.plain(w, rs)
        assert Corridors.plain(w, w.route()) is a
        fresh = Corridors(w, rs, np.full(w.fleet.n, -1))
        assert all(np.array_equal(getattr(a, k), getattr(fresh, k)) for k in names)
        # the per-vehicle inputs are reused for an index with signals of the same state
        sig = np.where(rng.random(w.fleet.n) < 0.3, rng.integers(0, 3, w.fleet.n), -1)
        cached = Corridors(w, rs, sig)
        assert w._corridor_cache[0] is rs and "inputs" in w._corridor_cache[2]
        del w._corridor_cache
        rebuilt = Corridors(w, rs, sig)
        assert all(np.array_equal(getattr(cached, k), getattr(rebuilt, k)) for k in names)
        # once the world moves on (here: headings turned, the route state
        # invalidated), inputs kept for ``rs`` are not served for it
        if w.fleet.n:
            heading = w.fleet.heading
            w.fleet.heading = heading + 0.5
            w.invalidate()
            moved = Corridors(w, rs, sig)
            del w._corridor_cache
            moved_fresh = Corridors(w, rs, sig)
            assert all(np.array_equal(getattr(moved, k), getattr(moved_fresh, k)) for k in names)
            w.fleet.heading = heading
            w.invalidate()
            rs = w.route()
            a = Corridors.plain(w, rs)
        w.invalidate()
        # the state it was built for is no longer the world's: rebuilt
        assert Corridors.plain(w, rs) is not a
        b = Corridors.plain(w, w.route())
        assert b is not a and all(np.array_equal(getattr(a, k), getattr(b, k)) for k in names)
        # a stale route state (not the world's current one) is never served from the cache
        assert Corridors.plain(w, rs) is not b
        seen += w.fleet.n > 0
    assert seen > 100


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 0), ("single-vp", 4000.0, 1), ("fcfs", 2600.0, 3)])
def test_an_index_with_signals_from_the_plain_one_is_the_full_build(method, throughput, seed):
    """``Corridors.with_signals`` (stop 41: the plain index with the signal
    entries merged in, ``corridor_add_signals``) gives the entries, order,
    flags and leaders of a full build with the same signals, bit for bit:
    on states of runs, with the expert's own signals and with random ones
    (vehicles signalling into the lane they are already in, into lanes off
    the road's three, or not at all)."""
    env = parallel_env(method=method, throughput=throughput, duration=120.0)
    obs, infos = env.reset(seed=seed)
    core = env.core
    w, ex = core.world, core.expert
    rng = np.random.default_rng(seed)
    names = ("rows", "corr", "coord", "keys", "signal_only", "lead")
    added = 0
    for step in range(400):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
        if step % 4 or not w.fleet.n:
            continue
        rs = w.route()
        n = w.fleet.n
        for sig in (ex._signals(w.fleet), ex._signals(w.fleet, want=False), rng.integers(-1, 3, n),
                    np.where(rng.random(n) < 0.5, rs.lane, -1)):
            got = Corridors.with_signals(w, rs, sig)
            want = Corridors(w, rs, sig)
            for k in names:
                g, x = getattr(got, k), getattr(want, k)
                assert g.dtype == x.dtype and g.tobytes() == x.tobytes(), k
            added += int(want.signal_only.sum())
    assert added > 100
