"""The intersection expert's compiled steering
(:func:`icv_envs.policies._kernels.box_steering`, behind
``PlatoonControl._steering``) and the leader part of its safety envelope
(:func:`icv_envs.policies._kernels.envelope_pairs`) against the array code
they replaced, frozen here as the oracles, on the states of real runs: every
method, expert-driven and with random drivers (vehicles off their lane, at
odd headings, standing), bit for bit; the envelope's pass of signal-only
leaders alongside, which the runs do not reach, on random corridor entries."""

from __future__ import annotations

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.formation.bezier import _lane_change_lateral, _pure_pursuit_steering
from pinned_numpy import at_pinned_level


def _frozen_steering(expert, world, rs) -> np.ndarray:
    """``PlatoonControl._steering`` as array code (before it was compiled)."""
    p = expert.p
    f = world.fleet
    lay = world.layout
    v = f.speed
    ld = np.maximum(p.preview_min, v * p.preview_time)
    s_prev = rs.s + ld
    appr = rs.phase == 0
    klane = np.clip(f.klane, 0, 2)
    pid = np.where(appr, 3 * f.mv + klane, rs.pid)
    px, py, _ = lay.route_points(pid, s_prev)
    pre = appr & (s_prev < 0)
    if pre.any():
        k = np.flatnonzero(pre)
        lat = (klane[k] + 0.5) * lay.lane_width
        act = f.lc_lane[k] >= 0
        if act.any():
            a = k[act]
            lat_a, _ = _lane_change_lateral(rs.u[a] + ld[a], f.lc_u0[a], f.lc_lat0[a], f.lc_lat1[a], f.lc_len[a])
            lat = lat.astype(np.float64)
            lat[act] = lat_a
        leg = f.leg[k]
        o = lay.box_half * lay.out[leg]
        d = lay.app_dir[leg]
        r = lay.app_right[leg]
        up = rs.u[k] + ld[k]
        px[k] = o[:, 0] + up * d[:, 0] + lat * r[:, 0]
        py[k] = o[:, 1] + up * d[:, 1] + lat * r[:, 1]
    return _pure_pursuit_steering(f.x, f.y, f.heading, px, np.asarray(py, dtype=np.float64), float(p.wheelbase),
                                  float(p.steer_max))


@pytest.mark.parametrize("method,throughput,seed,random_share", [
    ("multi-vp", 3000.0, 0, 0.0),
    ("single-vp", 2500.0, 1, 0.3),
    ("fcfs", 3500.0, 2, 0.3),
])
@at_pinned_level  # libm's sin, cos, arctan against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
def test_box_steering_equals_the_array_code(method, throughput, seed, random_share):
    env = parallel_env(method=method, throughput=throughput, duration=150.0, missing_action="expert")
    obs, infos = env.reset(seed=seed)
    core = env.core
    ex, w = core.expert, core.world
    rng = np.random.default_rng(seed)
    checked = lane_changes = arcs = departed = 0
    while not env.episode_over:
        if w.fleet.n:
            rs = w.route()
            got = ex._steering(w, rs)
            want = _frozen_steering(ex, w, rs)
            assert got.dtype == want.dtype and np.array_equal(got, want)
            checked += w.fleet.n
            lane_changes += int(((w.fleet.lc_lane >= 0) & (rs.phase == 0)).sum())
            arcs += int(((rs.phase == 1) & w.layout.arc[rs.pid]).sum())
            departed += int((rs.phase == 2).sum())
        acts = core.expert_actions().copy()  # (read-only from stop 45: this test mutated the env's cache)
        rand = rng.random(len(acts)) < random_share
        acts[rand] = rng.uniform(-1.0, 1.0, (int(rand.sum()), 2))
        obs, rew, term, trunc, infos = env.step(dict(zip(env.agents, acts.astype(np.float32))))
    assert checked > 5000 and arcs > 40 and departed > 200 and lane_changes > 300


def _frozen_envelope_pairs(ex, world, rs, cor, in_box):
    """The leader part of ``PlatoonControl._envelope`` as array code (before it was compiled):
    ``(cap, cap_other, signal-only leaders passed)``."""
    from icv_envs.sim.traffic import idm_acceleration

    p = ex.p
    f = world.fleet
    n = f.n
    cap = np.full(n, np.inf)
    cap_other = np.full(n, np.inf)
    passed = 0
    e = np.flatnonzero(cor.lead >= 0)
    le = cor.lead[e]
    if len(e):
        for _ in range(3):
            gap0 = cor.coord[le] - cor.coord[e] - 0.5 * (f.length[cor.rows[e]] + f.length[cor.rows[le]])
            skip = cor.signal_only[le] & (gap0 < 0.0)
            if not skip.any():
                break
            nxt = cor.lead[le[skip]]
            le = le.copy()
            le[skip] = nxt
            keep = le >= 0
            e, le = e[keep], le[keep]
            passed += int(skip.sum())
    if len(e):
        me = cor.rows[e]
        ld = cor.rows[le]
        gap = cor.coord[le] - cor.coord[e] - 0.5 * (f.length[me] + f.length[ld])
        grp = ex._group(f)
        member = (grp[me] == grp[ld]) & (grp[me] >= 0)
        co = ex._coordinated(f) | (rs.phase == 2)
        member |= co[me] & co[ld] & (rs.phase[ld] >= 1)
        T = np.where(member, p.member_T, p.idm_T)
        s0 = np.where(member, p.member_s0, p.idm_s0)
        v = f.speed[me]
        dv = v - f.speed[ld]
        safe = idm_acceleration(v, p.v_max, gap, dv, p.a_max, p.idm_b, T, s0, free_term=False)
        safe = np.minimum(safe, ex._gipps(v, f.speed[ld], gap - p.member_s0))
        if not in_box:
            safe = np.where(rs.phase[me] == 1, np.inf, safe)
        np.minimum.at(cap, me, safe)
        same = (grp[me] == grp[ld]) & (grp[me] >= 0)
        np.minimum.at(cap_other, me[~same], safe[~same])
    return cap, cap_other, passed


@pytest.mark.parametrize("method,throughput,seed,random_share", [
    ("multi-vp", 3000.0, 0, 0.0),
    ("single-vp", 3000.0, 0, 0.2),
    ("fcfs", 3500.0, 2, 0.3),
])
def test_envelope_pairs_equal_the_array_code(method, throughput, seed, random_share):
    """``envelope_pairs`` (the envelope's leader part, compiled) against the
    array code it replaced on every state of a run, the box's envelope on
    and off, with the corridor index of the control (turn signals in)."""
    from icv_envs.policies.platoon_common import Corridors

    env = parallel_env(method=method, throughput=throughput, duration=150.0, missing_action="expert")
    obs, infos = env.reset(seed=seed)
    core = env.core
    ex, w = core.expert, core.world
    rng = np.random.default_rng(seed)
    pairs = passed_total = binding = 0
    while not env.episode_over:
        f = w.fleet
        if f.n:
            rs = w.route()
            cor = Corridors(w, rs, ex._signals(f))
            for in_box in (False, True):
                want = _frozen_envelope_pairs(ex, w, rs, cor, in_box)
                cap, cap_other = np.full(f.n, np.inf), np.full(f.n, np.inf)
                got = ex._envelope_pairs(f, rs, cor, in_box, cap, cap_other)
                assert np.array_equal(cap, want[0]) and np.array_equal(cap_other, want[1]) and got == want[2]
            pairs += int((cor.lead >= 0).sum())
            passed_total += want[2]
            binding += int((cap < 0).sum())
        acts = core.expert_actions().copy()  # (read-only from stop 45: this test mutated the env's cache)
        rand = rng.random(len(acts)) < random_share
        acts[rand] = rng.uniform(-1.0, 1.0, (int(rand.sum()), 2))
        obs, rew, term, trunc, infos = env.step(dict(zip(env.agents, acts.astype(np.float32))))
    assert pairs > 5000 and binding > 100


def test_envelope_pairs_pass_signal_only_leaders_alongside_as_the_array_code():
    """The rule the runs above do not reach (a leader listed only by its turn
    signal and already alongside is passed, up to three times): random
    corridor entries over the vehicles of a real state, chains of
    signal-only leaders with negative gaps among them."""
    import types

    env = parallel_env(method="multi-vp", throughput=3000.0, duration=60.0)
    obs, infos = env.reset(seed=1)
    for _ in range(200):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    ex, w = env.core.expert, env.core.world
    f, rs = w.fleet, w.route()
    rng = np.random.default_rng(0)
    passed = 0
    for _ in range(300):
        m = int(rng.integers(1, 40))
        coord = np.sort(rng.uniform(-20.0, 20.0, m))
        lead = np.where(rng.random(m) < 0.8, np.arange(1, m + 1), -1)
        lead[-1] = -1
        cor = types.SimpleNamespace(lead=lead.astype(np.int64), coord=coord,
                                    rows=rng.integers(0, f.n, m).astype(np.int64),
                                    signal_only=rng.random(m) < 0.5)
        for in_box in (False, True):
            want = _frozen_envelope_pairs(ex, w, rs, cor, in_box)
            cap, cap_other = np.full(f.n, np.inf), np.full(f.n, np.inf)
            got = ex._envelope_pairs(f, rs, cor, in_box, cap, cap_other)
            assert np.array_equal(cap, want[0]) and np.array_equal(cap_other, want[1]) and got == want[2]
            passed += got
    assert passed > 100


def _frozen_stop_line(stop, u, length, speed, stop_margin, a_max, b, T, cap, cap_other, phase, acc_ref):
    """The end of PlatoonControl._envelope at b4c2680 (the stop line's IDM cap, the box's binding counts)."""
    from icv_envs.sim.traffic import idm_acceleration

    st = np.flatnonzero(stop)
    if len(st):
        gap = -u[st] - 0.5 * length[st] - stop_margin
        a_st = idm_acceleration(speed[st], 15.0, gap, speed[st], a_max, b, T, 0.5, free_term=False)
        cap[st] = np.minimum(cap[st], a_st)
    box = (phase == 1) & (cap < acc_ref - 0.5)
    other = box & (cap_other < acc_ref - 0.5)
    return np.count_nonzero(other), np.count_nonzero(box & ~other)


@pytest.mark.parametrize("seed", range(40))
def test_stop_line_caps_equal_the_array_code(seed):
    """``stop_line_caps`` (stop 41) against the array code it replaced:
    caps equal bit for bit (ties with the current cap, gaps below 0.1 m,
    standing vehicles; NaN caps and positions stay NaN) and the same binding
    counts."""
    from icv_envs.policies._kernels import stop_line_caps

    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 30))
    stop = rng.random(n) < 0.5
    u = rng.choice([-40.0, -3.0, -2.5, -0.1, 1.0], n) + rng.choice([0.0, 0.0, 0.37], n)
    length = rng.choice([4.0, 5.0], n)
    speed = rng.choice([0.0, 0.0, 3.0, 10.0], n) + rng.uniform(0, 1, n) * (rng.random(n) < 0.5)
    cap = rng.choice([np.inf, 2.0, -1.0, -6.0, np.nan], n)
    cap_other = rng.choice([np.inf, 2.0, -1.0], n)
    phase = rng.integers(0, 3, n).astype(np.int64)
    acc_ref = rng.choice([0.0, 1.0, 2.0, -0.5], n)
    if n and seed % 4 == 0:
        u[rng.integers(0, n)] = np.nan
    margin, a_max, b, T = 1.0, 2.0, 3.0, 1.2
    # a cap equal to the stop line's cap: the tie
    if n:
        i = int(rng.integers(0, n))
        stop[i] = True
        g = max(-u[i] - 0.5 * length[i] - margin, 0.1)
        s_star = 0.5 + max(0.0, speed[i] * T + speed[i] * speed[i] / (2.0 * np.sqrt(a_max * b)))
        cap[i] = a_max * (1.0 - (s_star / g) ** 2)
    c1, c2 = cap.copy(), cap.copy()
    want = _frozen_stop_line(stop, u, length, speed, margin, a_max, b, T, c1, cap_other, phase, acc_ref)
    got = stop_line_caps(stop, u, length, speed, margin, a_max, float(np.sqrt(a_max * b)), T, 0.5, c2, cap_other,
                         phase, acc_ref)
    # (bit for bit where a number; a NaN stays a NaN, whose sign bit numpy's and the kernel's ops may set apart)
    num = ~np.isnan(c1)
    assert np.array_equal(np.isnan(c1), np.isnan(c2)) and c1[num].tobytes() == c2[num].tobytes()
    assert tuple(got) == want


def test_box_obstacle_rows_equal_the_array_expression():
    """``box_obstacle_rows`` (stop 42) against ``_path_obstacles``'
    expression at b40d6e3 on random states with every phase, speeds at
    ``v_stopped`` and positions 10 m past the exit and around it, NaN
    included."""
    from icv_envs.policies._kernels import box_obstacle_rows

    rng = np.random.default_rng(0)
    for _ in range(300):
        n = int(rng.integers(0, 30))
        phase = rng.integers(0, 3, n).astype(np.int64)
        L = rng.choice([20.0, 30.0], n)
        s = L + rng.choice([-5.0, 9.0, 10.0, np.nextafter(10.0, 0.0), 11.0, np.nan], n)
        speed = rng.choice([0.0, 0.5, 1.0, np.nextafter(1.0, 0.0), 3.0], n)
        want = np.flatnonzero(((phase == 1) | ((phase == 2) & (s - L < 10.0))) & (speed < 1.0))
        got = box_obstacle_rows(phase, s, L, speed, 1.0)
        assert got.dtype == np.int64 and np.array_equal(got, want)
