"""``FormationManager.update`` (membership, front targets, lane windows and
stalls compiled in ``sim/_kernels/formation_step.membership_pass`` and
``hold_pass``; the re-forming's frame, costs and slots in ``reform_costs``
and ``reform_slots``; the re-plan test in ``off_reference_rows``) against
the array code it replaced, frozen below: on every
policy step of runs that exercise each rule (members leaving for their exit,
joins, new formations, braked front targets, lane-set changes at a lane drop,
stalls), both are applied to copies of the same state and every piece of the
formation state must come out bit for bit the same."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from icv_envs.formation.assignment import _solve
from pinned_numpy import at_pinned_level
from icv_envs.sim._kernels import drivable_lane_bits, hold_targets
from icv_envs.sim._kernels.formation import eligible_free_rows, leaving_rows, room_ahead
from icv_envs.sim.formations import FormationManager, _obstacles


# ----------------------------------------------------------------------------
# the replaced code (icv_envs/sim/formations.py at ca6947d), frozen
def _old_update(self, traffic, road, dt, events):
    cx, cy = traffic.center()
    wrap = road.wrap
    changed: set[int] = set()
    self._version += 1
    self.time += dt
    g_arr = self._gids()
    gids = g_arr.tolist()
    if gids:
        self._A[g_arr] = road.mod(self._A[g_arr] + self.speed * dt)
    if traffic.n and road.n_exits:
        leave = leaving_rows(traffic.group, traffic.exit, cx, cy, traffic.lc_lane, float(road.lane_width),
                             int(road.total_lanes), int(road.n_lanes), bool(road.has_ramp_lane), road._diverge_iv,
                             float(road.length) if road.periodic else -1.0, float(self.exit_lookahead),
                             float(self.exit_lookahead_per_lane))
        if len(leave):
            events["leave"] += len(leave)
            for gid in np.unique(traffic.group[leave]):
                changed.add(int(gid))
            traffic.group[leave] = -1
            traffic.tgt_lane[leave] = -1
            self._plans.grow(int(traffic.vid[leave].max()) + 1)
            self._plans.slot_gid[traffic.vid[leave]] = -1
    counts = np.bincount(traffic.group[traffic.group >= 0], minlength=self.next_gid) if traffic.n else np.zeros(
        self.next_gid, dtype=np.int64)
    changed.update(g_arr[counts[g_arr] != self._cnt[g_arr]].tolist())
    free = _old_eligible_free(self, traffic, road, cx) if traffic.n else np.zeros(0, dtype=np.int64)
    if len(free) and gids:
        sizes = counts[g_arr]
        open_ = (sizes > 0) & (sizes < self.max_size)
        if open_.any():
            ko = np.flatnonzero(open_)
            A = self._A[g_arr[ko]]
            Lf = self._L[g_arr[ko]]
            rel = wrap(cx[free][None, :] - A[:, None])
            reach = (rel >= -Lf[:, None] - self.join_distance) & (rel <= self.join_distance)
            still = np.ones(len(free), dtype=bool)
            for q in np.flatnonzero(reach.any(axis=1)).tolist():
                gid = gids[int(ko[q])]
                take = np.flatnonzero(reach[q] & still)[: self.max_size - int(sizes[ko[q]])]
                if len(take):
                    events["join"] += len(take)
                    traffic.group[free[take]] = gid
                    changed.add(gid)
                    still[take] = False
                    if not still.any():
                        break
            free = free[still]
    if self.create_new and len(free):
        on_main = free[road.lane_of(cy[free]) < road.n_lanes]
        for r in on_main[np.argsort(-cx[on_main], kind="stable")]:
            if traffic.group[r] >= 0:
                continue
            clear = True
            live = self._gids()
            if len(live):
                rel = wrap(cx[r] - self._A[live])
                Lf = self._L[live]
                clear = not bool(np.any((-Lf - self.new_formation_gap < rel) & (rel < self.new_formation_gap)))
            if clear:
                events["create"] += 1
                gid = self._new_gid(float(cx[r]))
                traffic.group[r] = gid
                changed.add(gid)
    g_arr = self._gids()
    room = np.full(len(g_arr), np.nan)
    if len(g_arr) > 1:
        nearest = room_ahead(self._A[g_arr], self._L[g_arr], float(road.length) if road.periodic else -1.0)
        fin = np.isfinite(nearest)
        room[fin] = nearest[fin] - self.formation_gap
    _old_hold_targets(self, traffic, road, g_arr, changed, room, cx, dt, events)
    for gid in sorted(changed):
        _old_reform(self, traffic, road, gid, cx)
    m = np.flatnonzero(traffic.group >= 0) if traffic.n else np.zeros(0, dtype=np.int64)
    if len(m):
        d, _, _ = self._profile(traffic, m)
        off = np.abs(wrap(cx[m] - (self._slot_x(traffic, m) + d))) > self.replan_error
        if off.any():
            self._plan(traffic, road, m[off], cx)
    g_arr = self._gids()
    for gid in g_arr[self._cnt[g_arr] == 0].tolist():
        self._A[gid] = np.nan
        self._lanes.pop(gid, None)
        self._live = None
    self._version += 1
    return sorted(changed)


def _old_reform(self, traffic, road, gid, cx):
    rows = np.flatnonzero(traffic.group == gid)
    n = len(rows)
    self._cnt[gid] = n
    if n == 0:
        return
    anchor = float(self._A[gid])
    lanes, tx, tl = self._reform_lanes(road, gid, n)  # (not replaced: the lane set and targets)
    _, cy = traffic.center()
    # the frame and the cost matrix (below), then SciPy's assignment
    cost = _old_frame_costs(rows, cx, cy, anchor, road.lane_width, lanes, tx, tl, self.w1, self.w2,
                            float(road.length) if road.periodic else -1.0)
    slot = _solve(cost)
    traffic.tgt_behind[rows] = tx[slot]
    traffic.tgt_lane[rows] = np.asarray(lanes, dtype=np.int64)[tl[slot] - 1]
    self.reforms += 1
    vid = traffic.vid[rows]
    jp = self._plans
    jp.grow(int(vid.max()) + 1)
    new = (jp.slot_gid[vid] != gid) | (jp.slot_behind[vid] != traffic.tgt_behind[rows])
    if new.any():
        r = rows[new]
        T = self._plan(traffic, road, r, cx)
        jp.slot_gid[traffic.vid[r]] = gid
        jp.slot_behind[traffic.vid[r]] = traffic.tgt_behind[r]
        jp.deadline[traffic.vid[r]] = self.time + T


def _old_eligible_free(self, traffic, road, cx):
    """``FormationManager._eligible_free`` (removed: ``membership_pass`` calls its kernel)."""
    _, cy = traffic.center()
    return eligible_free_rows(traffic.group, traffic.crashed, cx, cy, traffic.lc_lane, traffic.exit,
                              float(road.lane_width), int(road.total_lanes), int(road.n_lanes),
                              bool(road.has_ramp_lane), int(road.n_exits), road._diverge_iv,
                              float(road.length) if road.periodic else -1.0, float(self.exit_lookahead),
                              float(self.exit_lookahead_per_lane))


def _old_hold_targets(self, traffic, road, g_arr, changed, room, cx, dt, events):
    if not traffic.n or not len(g_arr):
        return
    grp = traffic.group
    m = np.flatnonzero(grp >= 0)
    if not len(m):
        return
    G = len(g_arr)
    A = self._A[g_arr]
    chg = np.zeros(self.next_gid, dtype=bool)
    if changed:
        chg[list(changed)] = True
    chg = chg[g_arr]
    slot_of_gid = np.full(int(g_arr[-1]) + 1, -1, dtype=np.int64)
    slot_of_gid[g_arr] = np.arange(G)
    d_ref = self._profile(traffic, m)[0]
    has, brake, late = hold_targets(grp, slot_of_gid, A, chg, room, traffic.tgt_behind, cx, d_ref, traffic.vid,
                                    self._plans.deadline, float(self.time), float(self.max_anchor_lead),
                                    -self.anchor_brake * dt, float(self.stall_error),
                                    float(road.length) if road.periodic else -1.0)
    if not has.any():
        return
    if brake.any():
        events["brake"] += int(brake.sum())
        self._A[g_arr[brake]] = A[brake]
    check = np.flatnonzero(has & ~chg)
    if len(check):
        g = g_arr[check]
        bits = _old_lane_bits(self, road, A[check], self._L[g])
        events["lanes"] += int((bits != self._bits[g]).sum())
        changed.update(g[bits != self._bits[g]].tolist())
    g = g_arr[has]
    inch = np.zeros(self.next_gid, dtype=bool)
    inch[list(changed)] = True
    lt = late[has] & ~inch[g]
    stall = np.where(lt, self._stall[g] + dt, 0.0)
    due = lt & (stall >= self.stall_time)
    if due.any():
        events["stall"] += int(due.sum())
        changed.update(g[due].tolist())
        stall[due] = 0.0
    self._stall[g] = stall


def _old_lane_bits(self, road, anchors, lengths):
    x0 = anchors - lengths - 10.0
    x1 = anchors + self.lookahead
    L = float(road.length)
    span = np.minimum(np.maximum(x1 - x0, 0.0), L)
    a = np.mod(x0, L)
    allowed = self._allowed(road.n_lanes)
    return drivable_lane_bits(a, span, x0, x1, bool(road.periodic), L, road.lane_ends, *_obstacles(road), allowed)


# ----------------------------------------------------------------------------
_STATE = ("_A", "_L", "_cnt", "_bits", "_stall")
_TRAFFIC = ("group", "tgt_lane", "tgt_behind")


def _same(a, b) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _check_against_old(monkeypatch, events):
    real = FormationManager.update
    calls = []

    def checked(self, traffic, road, dt):
        m2, t2 = copy.deepcopy((self, traffic))
        got = real(self, traffic, road, dt)
        want = _old_update(m2, t2, road, dt, events)
        assert got == want
        assert self.next_gid == m2.next_gid and self.reforms == m2.reforms and self.time == m2.time
        k = self.next_gid + 1  # the arrays' capacity may differ (grown ahead); their ids' entries may not
        for name in _STATE:
            assert _same(getattr(self, name)[:k], getattr(m2, name)[:k]), name
        assert self._lanes == m2._lanes
        assert np.array_equal(self._gids(), m2._gids())
        for name in _TRAFFIC:
            assert _same(getattr(traffic, name), getattr(t2, name)), name
        p, q = self._plans, m2._plans
        assert p.count == q.count
        for name in ("slot_gid",) + p.FLOATS:
            a, b = getattr(p, name), getattr(q, name)
            k2 = min(len(a), len(b))
            assert _same(a[:k2], b[:k2]), name
        calls.append(len(got))
        return got

    monkeypatch.setattr(FormationManager, "update", checked)
    return calls


def _drive(env, steps):
    obs, infos = env.reset(seed=3)
    for _ in range(steps):
        if not env.agents:
            break
        ex = env.unwrapped.expert_actions()
        obs, rew, term, trunc, infos = env.step(ex)


@pytest.mark.parametrize("case", ["ramps", "lane-drop", "lane-change", "off-ramp"])
def test_update_equals_the_replaced_array_code(monkeypatch, case):
    events = dict.fromkeys(("leave", "join", "create", "brake", "lanes", "stall"), 0)
    calls = _check_against_old(monkeypatch, events)
    if case == "ramps":
        from icv_envs.envs import highway_ramps_v0

        env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=200.0)
        _drive(env, 1000)
        # the rules of this road happened, so the comparison is not vacuous
        # (seed 3: 355 leaving, 441 joining, 144 new formations, 165 braked
        # front targets, 33 stalls)
        for key in ("leave", "join", "create", "brake", "stall"):
            assert events[key] > 0, (key, events)
        assert len(calls) == 1000 and sum(calls) > 500
    else:
        from icv_envs.envs import highway_formation_v0

        env = highway_formation_v0.parallel_env(scenario=case, vehicles_count=12, duration=60.0)
        _drive(env, 300)
        key = {"lane-drop": "lanes", "lane-change": "lanes", "off-ramp": "leave"}[case]
        assert events[key] > 0, events
        assert len(calls) == 300


def _compare(m1, t1, road, dt, events):
    """The new and the replaced update on copies of one state; every piece equal."""
    m2, t2 = copy.deepcopy((m1, t1))
    got = FormationManager.update(m1, t1, road, dt)
    want = _old_update(m2, t2, road, dt, events)
    assert got == want
    assert m1.next_gid == m2.next_gid and m1.reforms == m2.reforms
    k = m1.next_gid + 1
    for name in _STATE:
        assert _same(getattr(m1, name)[:k], getattr(m2, name)[:k]), name
    assert m1._lanes == m2._lanes
    for name in _TRAFFIC:
        assert _same(getattr(t1, name), getattr(t2, name)), name
    assert _same(m1._plans.t0[:len(m2._plans.t0)], m2._plans.t0)


def _perturbed(man, tr, road, rng):
    """A copy of ``(man, tr)`` moved onto the rules' boundaries: stall
    clocks one step short of ``stall_time`` with every member late; front
    targets on a coarse grid (lane windows that start or end at an
    obstacle's or a lane's end); free vehicles sharing a position (ties in
    the front-most-first order of new formations)."""
    m, t = copy.deepcopy((man, tr))
    g = m._gids()
    pick = g[rng.random(len(g)) < 0.5]
    m.stall_time = 1.0
    m.stall_error = 0.0
    m._stall[pick] = 0.8  # 0.8 + 0.2 == 1.0 exactly
    m._plans.deadline[:] = -1.0
    if rng.random() < 0.5:
        m._A[pick] = np.round(m._A[pick] / 4.0) * 4.0 + rng.choice([-0.5, 0.0, 0.5], len(pick))
    # windows that start at or beside an obstacle's front end, or end at or
    # beside a lane's end, once the front target has advanced (speed * dt)
    # and braked (1 m: it now leads its members by far)
    u = rng.choice(np.arange(-2.0, 2.25, 0.25), len(g)) + 1.0 - m.speed * 0.2
    if len(road._ob_hi) and len(g):
        m._A[g] = road._ob_hi[0] + m._L[g] + 10.0 + u
    elif len(g) and np.isfinite(road.lane_ends).any():
        m._A[g] = road.lane_ends[np.isfinite(road.lane_ends)][0] - m.lookahead + u
    cx, cy = (a.copy() for a in t.center())
    free = np.flatnonzero((t.group < 0) & (road.lane_of(cy) < road.n_lanes) & ~t.crashed)
    if len(free) >= 2:
        # two free vehicles side by side where no formation is near: they tie
        # for founding one
        L = float(road.length) if road.periodic else float(cx.max())
        ok = [p for p in np.arange(0.0, L, 5.0)
              if not np.any((-m._L[g] - 65.0 < road.wrap(p - m._A[g])) & (road.wrap(p - m._A[g]) < 65.0))]
        if ok:
            pair = rng.choice(free, size=2, replace=False)
            cx[pair] = ok[rng.integers(len(ok))]
            cy[pair[1]] = cy[pair[0]]
    t.x = t.x.copy()
    t.set_center(cx, cy)
    return m, t


@pytest.mark.parametrize("case", ["ramps", "lane-change", "lane-drop"])
def test_update_equals_the_replaced_code_on_boundary_states(case):
    events = dict.fromkeys(("leave", "join", "create", "brake", "lanes", "stall"), 0)
    rng = np.random.default_rng(7)
    if case == "ramps":
        from icv_envs.envs import highway_ramps_v0

        env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=200.0)
    else:
        from icv_envs.envs import highway_formation_v0

        env = highway_formation_v0.parallel_env(scenario=case, vehicles_count=12, duration=60.0)
    env.reset(seed=5)
    w = env.core.world
    for step in range(150):
        ex = env.unwrapped.expert_actions()
        env.step(ex)
        if step % 10 == 9:
            for _ in range(3):
                m, t = _perturbed(w.manager, w.traffic, w.road, rng)
                _compare(m, t, w.road, 0.2, events)
    assert events["stall"] > 0, events
    if case == "ramps":  # (only the ring founds formations)
        assert events["create"] > 0, events
    else:
        assert events["lanes"] > 0, events


def _old_eval(jp, vid, time):
    """``JoinPlans._eval`` as array code (icv_envs/sim/join_plans.py at
    ca6947d), frozen, with the quintic's arithmetic that its kernel
    (``quintic_rows``, removed at stop 49) shared with ``_quintic``, term by
    term, from the stored coefficients and numpy's powers."""
    t = time - jp.t0[vid]
    T = jp.T[vid]
    run = np.flatnonzero(t < T)
    d, v, a = jp.fd[vid], jp.fv[vid], jp.fa[vid]
    if len(run):
        tc = np.minimum(np.maximum(t[run], 0.0), T[run])
        k = vid[run]
        t2, t3, t4, t5 = tc * tc, tc ** 3, tc ** 4, tc ** 5
        d0, v0, a0, c3, c4, c5 = jp.d0[k], jp.v0[k], jp.a0[k], jp.c3[k], jp.c4[k], jp.c5[k]
        d[run] = d0 + v0 * tc + 0.5 * a0 * t2 + c3 * t3 + c4 * t4 + c5 * t5
        v[run] = v0 + a0 * tc + 3.0 * c3 * t2 + 4.0 * c4 * t3 + 5.0 * c5 * t4
        a[run] = a0 + 6.0 * c3 * tc + 12.0 * c4 * t2 + 20.0 * c5 * t3
    return d, v, a


@pytest.mark.parametrize("seed", range(4))
@at_pinned_level  # the kernel's powers are libm's, numpy's at AVX2 (tests/pinned_numpy.py)
def test_profile_evaluation_equals_the_replaced_array_code(seed):
    """Plans made at several times, evaluated before, at and after their
    ends (``t == T`` and ``t0 == time`` included), in any id order."""
    from icv_envs.sim.join_plans import JoinPlans

    rng = np.random.default_rng(seed)
    jp = JoinPlans(dict(accel=1.5, decel=2.0, jerk=1.0, t_min=2.0), (15.0, 29.0), 25.0)
    vid_all = rng.permutation(200)[:120]
    for t0 in (0.0, 0.2, 1.4, 3.0):
        vid = rng.choice(vid_all, size=30, replace=False)
        jp.plan(vid, rng.uniform(-80, 80, 30), rng.uniform(-5, 5, 30), rng.uniform(-1, 1, 30), t0)
    checked = 0
    for time in [0.0, 0.2, 1.4, 3.0, 5.0] + list(np.asarray(jp.t0[vid_all] + jp.T[vid_all])[:10]) + [1e3]:
        vid = rng.permutation(vid_all)
        got = jp._eval(vid, float(time))
        want = _old_eval(jp, vid, float(time))
        for x, y in zip(got, want):
            assert _same(x, y)
        checked += 1
    assert checked == 16


def _old_frame_costs(rows, cx, cy, anchor, lane_width, lanes, tx, tl, w1, w2, period):
    """The frame and cost part of the replaced ``_reform`` (array code, with
    ``formation.assignment._assign_targets``' cost matrix), frozen."""
    lanes_arr = np.asarray(lanes, dtype=np.float64)
    ids = np.arange(1, len(lanes) + 1, dtype=np.float64)
    lane_pos = cy[rows] / lane_width
    if len(lanes) > 1:
        y_v = np.interp(lane_pos, lanes_arr, ids)
        y_v = np.where(lane_pos < lanes_arr[0], 1.0 - (lanes_arr[0] - lane_pos), y_v)
        y_v = np.where(lane_pos > lanes_arr[-1], len(lanes) + (lane_pos - lanes_arr[-1]), y_v)
    else:
        y_v = 1.0 + (lane_pos - lanes_arr[0])
    d = anchor - cx[rows]
    if period > 0:
        d = np.mod(d + 0.5 * period, period) - 0.5 * period
    gy = tl.astype(np.float64)
    dx = tx[None, :] - d[:, None]
    dy = gy[None, :] - y_v[:, None]
    return w1 * dx * dx + w2 * dy * dy


@pytest.mark.parametrize("seed", range(30))
def test_reform_costs_equal_the_replaced_array_code(seed):
    """Lane sets with gaps, single lanes, positions exactly on lane centres,
    between them and outside the set, on a ring and a straight road."""
    from icv_envs.formation.targets import formation_targets
    from icv_envs.sim._kernels.formation_step import reform_costs

    rng = np.random.default_rng(seed)
    n_all = int(rng.integers(1, 60))
    lw = float(rng.choice([3.5, 4.0, 3.75]))
    sets = [(0,), (2,), (0, 1, 2, 3), (0, 3), (1, 2, 5), (0, 2, 3), (0, 1, 4), (2, 5)]  # gaps of 3 and 5 lanes:
    # slopes 1/3 and 1/5, which a reordered interpolation would round differently
    lanes = sets[seed] if seed < len(sets) else tuple(sorted(rng.choice(6, size=int(rng.integers(1, 5)),
                                                                        replace=False).tolist()))
    cy = np.where(rng.random(n_all) < 0.4, rng.integers(-1, 7, n_all) * lw, rng.uniform(-lw, 7 * lw, n_all))
    period = float(rng.choice([-1.0, 10000.0, 3217.5]))
    cx = rng.uniform(0.0, period if period > 0 else 2000.0, n_all)
    rows = np.sort(rng.choice(n_all, size=int(rng.integers((n_all + 1) // 2, n_all + 1)), replace=False))
    tx, tl = formation_targets(len(rows), len(lanes), 20.0, "interlaced")
    anchor = float(rng.choice(cx))
    w1, w2 = float(rng.choice([1.0, 0.3])), float(rng.choice([10.0, 2.5]))
    got = reform_costs(rows, cx, cy, anchor, lw, np.asarray(lanes, dtype=np.float64), tx, tl, w1, w2, period)
    want = _old_frame_costs(rows, cx, cy, anchor, lw, lanes, tx, tl, w1, w2, period)
    assert _same(got, want)


def test_profile_with_a_known_top_equals_the_searched_one():
    """``JoinPlans.profile(vid, t, top)`` (the manager passes one past the
    last traffic id, from stop 43) grows the tables to ``top`` instead of
    searching ``vid`` for its largest id: the same profiles, and ids never
    seen before get the default plan either way."""
    from icv_envs.sim.join_plans import JoinPlans

    lim = dict(accel=1.5, decel=2.0, jerk=1.0, t_min=2.0)
    a, b = JoinPlans(lim, (15.0, 29.0), 25.0), JoinPlans(lim, (15.0, 29.0), 25.0)
    rng = np.random.default_rng(0)
    vid = np.sort(rng.choice(600, 40, replace=False))
    d0, v0, a0 = rng.uniform(-80, 80, 20), rng.uniform(-5, 5, 20), rng.uniform(-1, 1, 20)
    for jp in (a, b):
        jp.plan(vid[:20], d0, v0, a0, 0.0)
    for t in (0.4, 2.0, 50.0):
        for x, y in zip(a.profile(vid, t), b.profile(vid, t, int(vid[-1]) + 1)):
            np.testing.assert_array_equal(x, y)
    assert b._cap >= int(vid[-1]) + 1


@pytest.mark.parametrize("case", ["ramps", "learned"])
def test_the_updates_kept_answers_are_the_fresh_ones(case):
    """From stop 50 ``update`` makes the re-plans and the references in its
    one call and keeps them: the members' join profiles as
    ``JoinPlans.profile``'s answer and the references as ``references()``'.
    After every step both must equal a fresh evaluation from the tables and
    the state (the kept profiles dropped), bit for bit: a kept answer from
    before the step's re-plans would pass every comparison that reads it
    through the same cache. ``learned``: zero actions (as the batched
    bench's), which let members drift off their references, so many steps
    re-plan inside the call."""
    from icv_envs.envs import highway_formation_v0, highway_ramps_v0

    if case == "ramps":
        env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=120.0)
    else:
        env = highway_formation_v0.parallel_env(vehicles_count=16, duration=60.0, expert_driven_check=False)
    env.reset(seed=11)
    w = env.core.world
    man, jp = w.manager, w.manager._plans
    kept = inside = 0
    for _ in range(250):
        if not env.agents:
            break
        if case == "ramps":
            ex = env.unwrapped.expert_actions()
            acts = {a: ex[a] for a in env.agents}
        else:
            acts = {a: np.zeros(2, dtype=np.float32) for a in env.agents}
        count = jp.count
        reforms = man.reforms
        env.step(acts)
        tr = w.traffic
        key = (man.time, man._version, id(tr), tr.vid.tobytes())
        if man._refs_cache is not None and man._refs_cache[0] == key:
            kept += 1
            inside += int(jp.count > count and man.reforms == reforms)
        got = man.references(tr) + (man.reference_accel(tr),)
        m = np.flatnonzero(tr.group >= 0)
        got_p = jp.profile(tr.vid[m], man.time) if len(m) else None
        jp._cache = None
        man._refs_cache = None
        want = man.references(tr) + (man.reference_accel(tr),)
        for g, x in zip(got, want):
            assert g.dtype == x.dtype and g.tobytes() == x.tobytes()
        if got_p is not None:
            want_p = jp._eval(tr.vid[m], man.time)
            for g, x in zip(got_p, want_p):
                assert g.tobytes() == x.tobytes()
    assert kept > 50, kept  # (the update's kept answers were read, not recomputed)
    if case == "learned":
        assert inside > 20, inside  # (re-plans made inside the one call, then the references)


def _old_reform_lanes(self, road, gid, n):
    """``FormationManager._reform_lanes`` as it was until stop 53, frozen (the
    second window asked for even when it is the first; ``tx.max()`` twice)."""
    anchor = float(self._A[gid])
    old_length = float(self._L[gid])
    lanes = self._lane_set(road, anchor, old_length)
    if not lanes:
        lanes = (0,)
    for _ in range(2):
        tx, tl = self.targets(n, len(lanes))
        length = float(tx.max()) if n else 0.0
        new = self._lane_set(road, anchor, max(length, old_length)) or lanes
        if new == lanes:
            break
        lanes = new
    tx, tl = self.targets(n, len(lanes))
    self._lanes[gid] = lanes
    self._bits[gid] = self._lane_bitset(lanes)
    self._L[gid] = float(tx.max())
    return lanes, tx, tl


@pytest.mark.parametrize("seed", range(40))
def test_reform_lanes_equal_the_two_window_search(seed):
    """The re-forming's lane set, targets and recorded length (stop 53: the
    second window asked for only when the formation grew, the length
    memoised) against the frozen search, on roads whose drivable lanes
    change along them (lane ends, an obstacle, a ring), for formations that
    shrank, kept their size and grew, anchors near the changes, and
    managers restricted to some lanes."""
    from icv_envs.sim.road import Obstacle, RoadLayout

    rng = np.random.default_rng(seed)
    n_lanes = int(rng.integers(1, 6))
    periodic = bool(rng.random() < 0.3)
    length = float(rng.choice([1000.0, 2400.0]))
    ends = np.where(rng.random(n_lanes) < 0.5, rng.uniform(200.0, length, n_lanes), np.inf)
    if periodic:
        ends[:] = np.inf
    obstacles = [Obstacle(lane=int(rng.integers(0, n_lanes)), x=float(rng.uniform(100.0, length - 300.0)), length=30.0)
                 ] if rng.random() < 0.6 else []
    road = RoadLayout(n_lanes=n_lanes, length=length, lane_ends=ends, periodic=periodic, obstacles=obstacles)
    allowed = None if rng.random() < 0.6 else sorted(rng.choice(n_lanes, size=int(rng.integers(1, n_lanes + 1)),
                                                                replace=False).tolist())
    kw = {"allowed_lanes": allowed} if allowed is not None else {}
    new, old = FormationManager(**kw), FormationManager(**kw)
    for _ in range(6):
        # (anchors at random, near lane ends, and ahead of the obstacle by less than a grown formation's
        # length: the window that grows back over it loses that lane)
        anchor = float(rng.choice([rng.uniform(0.0, length), *(e + rng.uniform(-60.0, 60.0) for e in ends
                                                                if np.isfinite(e)),
                                   *(ob.x + rng.uniform(0.0, 150.0) for ob in obstacles)]))
        old_n = int(rng.integers(1, 16))
        n = int(max(1, old_n + rng.integers(-4, 13)))
        g1, g2 = new._new_gid(anchor), old._new_gid(anchor)
        for m, g in ((new, g1), (old, g2)):
            m._L[g] = m._target_length(old_n, int(rng.integers(1, n_lanes + 1))) if rng.random() < 0.8 else 0.0
        old._L[g2] = new._L[g1]
        got = new._reform_lanes(road, g1, n)
        want = _old_reform_lanes(old, road, g2, n)
        assert got[0] == want[0]
        assert got[1].tobytes() == want[1].tobytes() and got[2].tobytes() == want[2].tobytes()
        assert new._L[g1] == old._L[g2] and new._bits[g1] == old._bits[g2] and new._lanes[g1] == old._lanes[g2]


@pytest.mark.parametrize("seed", range(25))
def test_reform_members_is_the_separate_calls(seed):
    """``reform_members`` (``FormationManager._reform`` after the lane set,
    in one call from stop 56) against the calls it joined, bit for bit:
    ``reform_costs``, SciPy's ``linear_sum_assignment``, ``reform_slots``
    and, for the members whose slot changed, ``plan_pass`` and the stores
    of slot, place and deadline by vehicle id; members that keep their slot
    (no plan) and formations of one member included; with ``plan`` off it
    only writes the slots and returns the same rows."""
    from scipy.optimize import linear_sum_assignment

    from icv_envs.formation.control import _PROFILE_SAMPLES, JOIN_GROW, JOIN_SEARCH_CAP
    from icv_envs.formation.targets import formation_targets
    from icv_envs.sim._kernels.formation_step import plan_pass, reform_costs, reform_members, reform_slots
    from icv_envs.sim.join_plans import JOIN_MAX_DURATION

    rng = np.random.default_rng(seed)
    n_all = int(rng.integers(1, 40))
    lw = 4.0
    lanes = [(0,), (0, 1), (0, 1, 2), (1, 2, 3), (0, 2)][seed % 5]
    length = float(rng.choice([-1.0, 3000.0]))
    cx = rng.uniform(0.0, 3000.0, n_all)
    cy = rng.uniform(-lw, 4 * lw, n_all)
    vid = np.sort(rng.choice(3 * n_all + 5, n_all, replace=False)).astype(np.int64)
    gid = 2
    group = np.where(rng.random(n_all) < 0.7, gid, rng.integers(-1, 2, n_all)).astype(np.int64)
    rows = np.flatnonzero(group == gid).astype(np.int64)
    if not len(rows):
        group[0] = gid
        rows = np.array([0], dtype=np.int64)
    tx, tl = formation_targets(len(rows), len(lanes), 20.0, "interlaced")
    anchors = np.append(rng.uniform(0, 3000, 4), np.nan)
    anchor = float(anchors[gid])
    lanes_f, lanes_i = np.asarray(lanes, dtype=np.float64), np.asarray(lanes, dtype=np.int64)
    speed, accel = rng.uniform(0, 35, n_all), rng.uniform(-3, 2, n_all)
    v_form, time = 25.0, float(rng.uniform(0, 300))
    search = (1.5, 3.0, 2.0, 2.0, JOIN_GROW, JOIN_MAX_DURATION, 18.0 - v_form, 33.0 - v_form, JOIN_SEARCH_CAP,
              _PROFILE_SAMPLES)
    cap = int(vid[-1]) + 1
    names = ("t0", "T", "d0", "v0", "a0", "c3", "c4", "c5", "fd", "fv", "fa")
    tables = {k: rng.normal(size=cap) for k in names}
    # slots and places some members already hold (they keep them: no plan)
    slot_gid = np.where(rng.random(cap) < 0.5, gid, -1).astype(np.int64)
    behind0 = rng.uniform(0, 60, n_all)
    slot_behind = rng.uniform(0, 60, cap)
    slot_behind[vid] = np.where(rng.random(n_all) < 0.5, behind0, slot_behind[vid])
    deadline = rng.uniform(0, 300, cap)
    tgt_lane0 = rng.integers(-1, 3, n_all).astype(np.int64)
    # about half the members already hold the slot the assignment gives them
    # (the same formation, the same place): they keep their plan
    cost = reform_costs(rows, cx, cy, anchor, lw, lanes_f, tx, tl, 1.0, 10.0, length)
    r_rows, r_cols = linear_sum_assignment(cost)
    slot = np.empty(len(rows), dtype=np.int64)
    slot[r_rows] = r_cols
    keep = rows[rng.random(len(rows)) < 0.5]
    keep_slot = slot[np.searchsorted(rows, keep)]
    slot_gid[vid[keep]] = gid
    slot_behind[vid[keep]] = tx[keep_slot]

    def state():
        return ([behind0.copy(), tgt_lane0.copy(), slot_gid.copy(), slot_behind.copy(), deadline.copy()],
                {k: v.copy() for k, v in tables.items()})

    (tb_w, tlane_w, sg_w, sb_w, dl_w), tab_w = state()
    r_want = reform_slots(rows, slot, tx, tl, lanes_i, gid, vid, tb_w, tlane_w, sg_w, sb_w)
    if len(r_want):
        T = plan_pass(r_want, group, tb_w, anchors, cx, speed, accel, vid, v_form, length, time, *search,
                      *(tab_w[k] for k in names))
        sg_w[vid[r_want]] = gid
        sb_w[vid[r_want]] = tb_w[r_want]
        dl_w[vid[r_want]] = time + T
    for plan in (True, False):
        (tb, tlane, sg, sb, dl), tab = state()
        r = reform_members(rows, cx, cy, anchor, lw, lanes_f, lanes_i, tx, tl, 1.0, 10.0, length, gid, vid, tb, tlane,
                           plan, group, anchors, speed, accel, v_form, time, *search, sg, sb, dl,
                           *(tab[k] for k in names))
        assert r.tolist() == r_want.tolist()
        assert len(r) == len(rows) - len(keep)
        assert tb.tobytes() == tb_w.tobytes() and tlane.tolist() == tlane_w.tolist()
        if plan:
            assert sg.tolist() == sg_w.tolist() and sb.tobytes() == sb_w.tobytes() and dl.tobytes() == dl_w.tobytes()
            for k in names:
                assert tab[k].tobytes() == tab_w[k].tobytes(), k
        else:
            assert sg.tolist() == slot_gid.tolist() and dl.tobytes() == deadline.tobytes()
            for k in names:
                assert tab[k].tobytes() == tables[k].tobytes(), k
