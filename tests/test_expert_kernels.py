"""The highway expert's per-vehicle arithmetic, compiled (``formation/_kernels.lateral_rows``,
``pursuit_rows``, whose transcendental steps are libm's from stop 49, NumPy's
at AVX2: those tests run pinned there, ``tests/pinned_numpy.py``;
``policies/_kernels.lane_changes_ended``,
``preview_points``, ``expert_lane_speeds``, ``free_speed_pow`` (its power libm's from stop 50, compared pinned),
``expert_accelerations``), against the array code it replaced, frozen
below: block by block on random arrays pushed onto the rules' boundaries
(hypothesis), and the whole of ``FormationExpert.compute`` on every policy
step of runs on the ring with ramps, a lane drop and an off-ramp. Every
output must be the same bit for bit (the intersection's lane-change
progress uses the same curve: ``test_trajectory_hash``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pinned_numpy import at_pinned_level

from icv_envs.formation.bezier import (
    _lane_change_lateral,
    _lane_change_lateral_rows,
    _pure_pursuit_rows,
    _pure_pursuit_steering,
)
from icv_envs.formation.control import _longitudinal_feedback
from icv_envs.policies._kernels import (
    expert_accelerations,
    expert_lane_speeds,
    free_speed_pow,
    lane_changes_ended,
    preview_points,
)
from icv_envs.policies.formation_expert import FormationExpert
from icv_envs.sim.traffic import idm_acceleration


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()

def _drive_intersection(method: str, throughput: float, seed: int, duration: float, steps: int) -> None:
    """Run the intersection env under its expert (the infos' labels fed back)."""
    from icv_envs.envs import intersection_v0

    env = intersection_v0.parallel_env(method=method, throughput=throughput, duration=duration)
    obs, infos = env.reset(seed=seed)
    for _ in range(steps):
        if not env.agents:
            break
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})



# ----------------------------------------------------------------------------
# the replaced code (icv_envs/policies/formation_expert.py at 4d79153), frozen
def _old_ended(a_rows, x, y, cy, v, lc_x0, lc_y0, lc_y1, lc_len, lc_lane, tol):
    y_plan, _ = _lane_change_lateral(x[a_rows], lc_x0[a_rows], lc_y0[a_rows], lc_y1[a_rows], lc_len[a_rows])
    stray = np.abs(y_plan - y[a_rows]) > tol
    done = (x[a_rows] >= lc_x0[a_rows] + lc_len[a_rows]) & (np.abs(y[a_rows] - lc_y1[a_rows]) < 0.3)
    done |= (v[a_rows] < 0.5) & (np.abs(cy[a_rows] - lc_y1[a_rows]) < 0.3)
    lc_lane[a_rows[stray | done]] = -1


def _old_steering(x, y, heading, v, lane, W, active, lc_x0, lc_y0, lc_y1, lc_len, pmin, ptime, wb, ms):
    ld = np.maximum(pmin, v * ptime)
    px = x + ld
    py = lane * W
    if active.any():
        a_rows = np.flatnonzero(active)
        yp, _ = _lane_change_lateral(px[a_rows], lc_x0[a_rows], lc_y0[a_rows], lc_y1[a_rows], lc_len[a_rows])
        py = py.astype(np.float64)
        py[a_rows] = yp
    return _pure_pursuit_steering(x, y, heading, px, np.asarray(py, dtype=np.float64), wb, ms)


def _old_wrap(d, length):
    if length < 0:
        return d
    half = 0.5 * length
    return np.mod(d + half, length) - half


def _old_longitudinal(p, lane_speed, lane, n_lanes, exiting, blocked, member, v, cx, x_ref, v_ref, a_ref_all, length):
    n = len(v)
    lane_speed = np.where(exiting & (lane < n_lanes), p["exit_speed"], lane_speed)
    lane_speed = np.where(blocked & ~member, np.maximum(lane_speed - p["blocked_slowdown"], p["v_min"]), lane_speed)
    lane_speed = np.where(blocked & ~member & exiting, np.minimum(lane_speed, p["v_min"]), lane_speed)
    acc = np.empty(n)
    free = ~member
    if free.any():
        acc[free] = idm_acceleration(v[free], lane_speed[free], np.inf, 0.0, p["a_max"], p["idm_b"], p["idm_T"],
                                     p["idm_s0"], free_term=True)
    if member.any():
        m = np.flatnonzero(member)
        a_ref = a_ref_all[m]
        x_eff = cx[m] + _old_wrap(x_ref[m] - cx[m], length)
        acc[m] = _longitudinal_feedback(cx[m], x_eff, v[m], v_ref[m], p["kp"], p["kv"], p["lo"], p["hi"], a_ref)
        acc[m] = np.maximum(acc[m], 1.0 * (p["v_min"] - v[m]))
    return lane_speed, acc


def _new_longitudinal(p, lane_speed, lane, n_lanes, exiting, blocked, member, v, cx, x_ref, v_ref, a_ref_all, length):
    ls = expert_lane_speeds(lane_speed, lane, exiting, blocked, member, n_lanes, p["exit_speed"],
                            p["blocked_slowdown"], p["v_min"])
    free_rows, m = np.flatnonzero(~member), np.flatnonzero(member)
    free_pow = free_speed_pow(free_rows, v, ls)  # (the power libm's from stop 50: compared pinned)
    acc = expert_accelerations(len(v), free_rows, free_pow, v, p["a_max"], p["idm_b"], p["idm_T"], p["idm_s0"], m,
                               cx, x_ref, v_ref, a_ref_all, length, p["kp"], p["kv"], p["lo"], p["hi"], p["v_min"])
    return ls, acc


# ----------------------------------------------------------------------------
# block by block, on values pushed onto the rules' boundaries
def _pick(draw, n, values, rng_floats):
    """``n`` floats, each either one of ``values`` (boundaries, signed zeros) or a drawn float."""
    return np.array([draw(st.sampled_from(values)) if draw(st.booleans()) else draw(rng_floats) for _ in range(n)],
                    dtype=np.float64)


@st.composite
def _lane_change_states(draw):
    n = draw(st.integers(1, 24))
    lc_x0 = _pick(draw, n, [0.0, -0.0, 100.0], st.floats(-500, 500))
    lc_len = _pick(draw, n, [1e-3, 30.0, 60.0], st.floats(1e-3, 200))
    frac = _pick(draw, n, [0.0, -0.0, 0.5, 1.0, -0.1, 1.1], st.floats(-0.5, 1.5))
    x = lc_x0 + frac * lc_len
    x = np.where(frac == 1.0, lc_x0 + lc_len, x)  # exactly the curve's end
    lc_y0 = _pick(draw, n, [0.0, -0.0, 4.0], st.floats(-12, 12))
    lc_y1 = lc_y0 + _pick(draw, n, [4.0, -4.0, 0.0], st.floats(-8, 8))
    off = _pick(draw, n, [0.3, -0.3, 0.0, -0.0, 0.2999999999999999, 0.30000000000000004], st.floats(-2, 2))
    y = lc_y1 + off
    cy = lc_y1 + _pick(draw, n, [0.3, -0.3, 0.0], st.floats(-2, 2))
    v = _pick(draw, n, [0.5, 0.0, 0.4999999999999999, 30.0], st.floats(0, 40))
    rows = np.flatnonzero(np.array([draw(st.booleans()) for _ in range(n)]) | (np.arange(n) == 0)).astype(np.int64)
    return rows, x, y, cy, v, lc_x0, lc_y0, lc_y1, lc_len


@at_pinned_level  # libm's transcendental steps against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
@settings(max_examples=300, deadline=None)
@given(_lane_change_states(), st.sampled_from([0.0, 0.3, 1.0]))
def test_lane_change_end_equals_the_replaced_array_code(state, tol):
    rows, x, y, cy, v, lc_x0, lc_y0, lc_y1, lc_len = state
    lane_a = np.arange(len(x), dtype=np.int64)
    lane_b = lane_a.copy()
    _old_ended(rows, x, y, cy, v, lc_x0, lc_y0, lc_y1, lc_len, lane_a, tol)
    y_plan, slope = _lane_change_lateral_rows(rows, x, lc_x0, lc_y0, lc_y1, lc_len)
    lane_changes_ended(rows, y_plan, x, y, cy, v, lc_x0, lc_len, lc_y1, lane_b, tol)
    assert _same(lane_a, lane_b)
    want = _lane_change_lateral(x[rows], lc_x0[rows], lc_y0[rows], lc_y1[rows], lc_len[rows])
    assert _same(y_plan, want[0]) and _same(slope, want[1])


@at_pinned_level  # libm's transcendental steps against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
@settings(max_examples=300, deadline=None)
@given(_lane_change_states(), st.data())
def test_steering_equals_the_replaced_array_code(state, data):
    rows, x, y, cy, v, lc_x0, lc_y0, lc_y1, lc_len = state
    n = len(x)
    heading = np.array(data.draw(st.lists(st.floats(-4, 4), min_size=n, max_size=n)), dtype=np.float64)
    lane = np.array(data.draw(st.lists(st.integers(0, 4), min_size=n, max_size=n)), dtype=np.int64)
    active = np.zeros(n, dtype=bool)
    active[rows] = True
    # preview_min equal to some v * preview_time (the maximum's tie), and a
    # zero preview (the pursuit's l_d == 0 at the rear axle's own point)
    pmin, ptime = data.draw(st.sampled_from([(5.0, 1.0), (0.0, 0.0), (12.0, 0.4)]))
    if data.draw(st.booleans()):
        v = np.where(np.arange(n) % 2 == 0, pmin / ptime if ptime else 0.0, v)
    W, wb, ms = 4.0, 2.8, 0.6
    want = _old_steering(x, y, heading, v, lane, W, active, lc_x0, lc_y0, lc_y1, lc_len, pmin, ptime, wb, ms)
    px, py = preview_points(x, v, lane, W, pmin, ptime)
    if active.any():
        a_rows = np.flatnonzero(active)
        py[a_rows] = _lane_change_lateral_rows(a_rows, px, lc_x0, lc_y0, lc_y1, lc_len)[0]
    got = _pure_pursuit_rows(x, y, heading, px, py, wb, ms)
    assert _same(got, want)


@st.composite
def _longitudinal_states(draw):
    n = draw(st.integers(1, 24))
    p = {"exit_speed": 20.0, "blocked_slowdown": 3.0, "v_min": 15.0, "a_max": 3.0, "idm_b": 2.0, "idm_T": 1.2,
         "idm_s0": 2.0, "kp": draw(st.sampled_from([-0.3, -1.0])), "kv": -0.8, "lo": -3.0, "hi": 2.0}
    # lane speeds on the ties (v_min + slowdown, v_min, 0.1 for the IDM's floor), ints from a lane table
    lane_speed = _pick(draw, n, [18.0, 15.0, 0.1, 0.05, 30.0], st.floats(0, 40))
    lane = np.array([draw(st.integers(0, 4)) for _ in range(n)], dtype=np.int64)
    flags = [np.array([draw(st.booleans()) for _ in range(n)]) for _ in range(3)]
    v = _pick(draw, n, [15.0, 0.0, 30.0, 0.1], st.floats(0, 40))
    cx = _pick(draw, n, [0.0, 5000.0, 9999.0], st.floats(0, 10000))
    x_ref = _pick(draw, n, [0.0, 5000.0, 5000.0000000001, 10000.0], st.floats(-100, 10100))
    v_ref = _pick(draw, n, [15.0, 30.0], st.floats(0, 40))
    a_ref = _pick(draw, n, [0.0, -0.0, 2.0, -3.0], st.floats(-4, 4))
    length = draw(st.sampled_from([-1.0, 10000.0]))
    return p, lane_speed, lane, 4, flags[0], flags[1], flags[2], v, cx, x_ref, v_ref, a_ref, length


@at_pinned_level  # the free term's power is libm's, NumPy's at AVX2 (tests/pinned_numpy.py)
@settings(max_examples=300, deadline=None)
@given(_longitudinal_states())
def test_longitudinal_law_equals_the_replaced_array_code(state):
    want = _old_longitudinal(*state)
    got = _new_longitudinal(*state)
    assert _same(got[0], want[0]) and _same(got[1], want[1])


# ----------------------------------------------------------------------------
# the whole of compute() on every policy step of real runs
def _old_compute(self, world):
    """FormationExpert.compute at 4d79153, with the frozen blocks above."""
    p = self.p
    tr, road = world.traffic, world.road
    n = tr.n
    if n == 0:
        return np.zeros((0, 2))
    cx, cy = tr.center()
    v = tr.speed
    W = road.lane_width
    lane = road.lane_of(cy)
    index = world.lane_index()
    x_ref, lane_ref, v_ref, member = world.manager.references(tr)
    desired, exiting = self._exit_lanes(world, lane, lane_ref, member)
    desired = self._desired_lanes(world, desired, lane, member, exiting, cx, v, index)
    desired = self._lane_end_escape(world, desired, lane, member, exiting)
    active = tr.lc_lane >= 0
    if active.any():
        _old_ended(np.flatnonzero(active), tr.x, tr.y, cy, v, tr.lc_x0, tr.lc_y0, tr.lc_y1, tr.lc_len, tr.lc_lane,
                   p.replan_tolerance)
        active = tr.lc_lane >= 0
    start, s_lane, s_len, blocked = self._lane_change_starts(world, index, active, lane, desired, member)
    if len(start):
        tr.lc_lane[start] = s_lane
        tr.lc_x0[start] = tr.x[start]
        tr.lc_y0[start] = tr.y[start]
        tr.lc_y1[start] = s_lane * W
        tr.lc_len[start] = s_len
        active = tr.lc_lane >= 0
    phi = _old_steering(tr.x, tr.y, tr.heading, v, lane, W, active, tr.lc_x0, tr.lc_y0, tr.lc_y1, tr.lc_len,
                        p.preview_min, p.preview_time, float(p.wheelbase), float(p.steer_max))
    prm = {"exit_speed": p.exit_speed, "blocked_slowdown": p.blocked_slowdown, "v_min": p.v_min, "a_max": p.a_max,
           "idm_b": p.idm_b, "idm_T": p.idm_T, "idm_s0": p.idm_s0, "kp": float(p.kp), "kv": float(p.kv),
           "lo": float(max(p.a_min, p.comfort_accel[0])), "hi": float(min(p.a_max, p.comfort_accel[1]))}
    _, acc = _old_longitudinal(prm, self._lane_speeds(road, lane), lane, road.n_lanes, exiting, blocked, member, v,
                               cx, x_ref, v_ref, world.manager.reference_accel(tr),
                               float(road.length) if road.periodic else -1.0)
    acc = self._safety_cap(world, index, acc, lane, desired, member, exiting)
    return self._normalise(acc, phi)


_LC = ("lc_lane", "lc_x0", "lc_y0", "lc_y1", "lc_len")


@pytest.mark.parametrize("case", ["ramps", "lane-drop", "off-ramp"])
@at_pinned_level  # libm's transcendental steps against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
def test_compute_equals_the_replaced_array_code_on_runs(monkeypatch, case):
    real = FormationExpert.compute
    seen = {"calls": 0, "active": 0, "ended": 0, "members": 0, "free": 0}

    def checked(self, world):
        tr = world.traffic
        before = {k: getattr(tr, k).copy() for k in _LC}
        want = _old_compute(self, world)
        after_old = {k: getattr(tr, k).copy() for k in _LC}
        for k in _LC:  # the state again, for the new code
            getattr(tr, k)[:] = before[k]
        got = real(self, world)
        assert _same(got, want)
        for k in _LC:
            assert _same(getattr(tr, k), after_old[k]), k
        seen["calls"] += 1
        seen["active"] += int((before["lc_lane"] >= 0).sum())
        seen["ended"] += int(((before["lc_lane"] >= 0) & (after_old["lc_lane"] < 0)).sum())
        member = world.manager.references(tr)[3]
        seen["members"] += int(member.sum())
        seen["free"] += int((~member).sum())
        return got

    monkeypatch.setattr(FormationExpert, "compute", checked)
    if case == "ramps":
        from icv_envs.envs import highway_ramps_v0

        env = highway_ramps_v0.parallel_env(vgr=1 / 3, duration=120.0)
        steps = 600
    else:
        from icv_envs.envs import highway_formation_v0

        env = highway_formation_v0.parallel_env(scenario=case, vehicles_count=12, duration=60.0)
        steps = 300
    env.reset(seed=5)
    for _ in range(steps):
        if not env.agents:
            break
        env.step(env.unwrapped.expert_actions())
    # the rules ran (lane changes under way and ending, members; free
    # vehicles on the ring with ramps: its on-ramp vehicles before they join)
    assert seen["calls"] >= 100 and seen["active"] > 0 and seen["ended"] > 0 and seen["members"] > 0, seen
    if case == "ramps":
        assert seen["free"] > 0, seen


# ----------------------------------------------------------------------------
# the intersection experts' longitudinal law and normalisation
# (icv_envs/policies/platoon_control.py at 4d79153), frozen
def _old_platoon_longitudinal(self, world, rs):
    from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_TREE

    p = self.p
    f = world.fleet
    v = f.speed
    acc = idm_acceleration(v, p.v0, np.inf, 0.0, min(p.a_max, p.comfort[1]), p.idm_b, p.idm_T, p.idm_s0)
    m = self._mode
    fol = np.flatnonzero(m == MODE_FOLLOW)
    if len(fol):
        x = rs.u[fol]
        xr = x + np.clip(self._xref[fol] - x, -p.ref_error_clip, p.ref_error_clip)
        acc[fol] = _longitudinal_feedback(x, xr, v[fol], self._vref[fol], float(p.kp), float(p.kv),
                                          float(p.comfort[0]), float(p.comfort[1]), 0.0)
    tr = np.flatnonzero(m == MODE_TREE)
    binding = 0
    if len(tr):
        x = -rs.X[tr]
        xr = x + np.clip(-self._xref[tr] - x, -p.ref_error_clip, p.ref_error_clip)
        lo = np.where(self._tight[tr], p.a_min, p.comfort[0])
        a = _longitudinal_feedback(x, xr, v[tr], self._vref[tr], float(p.kp), float(p.kv), float(p.a_min),
                                   float(p.a_max), 0.0)
        a = np.clip(a, lo, p.a_max)
        vc = self._vcap[tr]
        binding = int((vc < a - 0.5).sum())
        acc[tr] = np.minimum(a, vc)
    return acc, binding


def _old_platoon_normalised(acc, cap, phi, a_min, a_max, steer_max):
    acc = np.clip(np.minimum(acc, cap), a_min, a_max)
    ua = np.where(acc >= 0, acc / a_max, -acc / a_min)
    return np.clip(np.stack([ua, phi / steer_max], axis=1), -1.0, 1.0)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_platoon_normalisation_equals_the_replaced_array_code(data):
    from icv_envs.policies._kernels import normalised_actions
    from icv_envs._ufuncs import clip as uclip

    n = data.draw(st.integers(1, 20))
    fl = st.floats(-10, 10)
    acc = np.array([data.draw(st.sampled_from([0.0, -0.0, 2.0, -6.0, 7.5]) | fl) for _ in range(n)])
    cap = np.array([data.draw(st.sampled_from([np.inf, 0.0, -0.0, 2.0, -6.0]) | fl) for _ in range(n)])
    phi = np.array([data.draw(st.sampled_from([0.0, -0.0, 0.6, -0.6, 0.7]) | st.floats(-1, 1)) for _ in range(n)])
    want = _old_platoon_normalised(acc, cap, phi, -6.0, 2.0, 0.6)
    got = normalised_actions(uclip(np.minimum(acc, cap), -6.0, 2.0), phi, 2.0, -6.0, 0.6)
    assert _same(got, want)


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 2600.0, 3), ("single-vp", 2200.0, 4),
                                                    ("fcfs", 2600.0, 5)])
@at_pinned_level  # the IDM's free term's power is libm's from stop 50, NumPy's at AVX2 (tests/pinned_numpy.py)
def test_platoon_longitudinal_equals_the_replaced_array_code_on_runs(monkeypatch, method, throughput, seed):
    from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_TREE
    from icv_envs.policies.platoon_control import PlatoonControl

    real = PlatoonControl._longitudinal
    seen = {"follow": 0, "tree": 0, "binding": 0}

    def checked(self, world, rs):
        want, binding = _old_platoon_longitudinal(self, world, rs)
        before = self.stats["virtual_cap_binding"]
        got = real(self, world, rs)
        assert _same(got, want)
        assert self.stats["virtual_cap_binding"] - before == binding
        seen["follow"] += int((self._mode == MODE_FOLLOW).sum())
        seen["tree"] += int((self._mode == MODE_TREE).sum())
        seen["binding"] += binding
        return got

    monkeypatch.setattr(PlatoonControl, "_longitudinal", checked)
    _drive_intersection(method, throughput, seed, 90.0, 450)
    assert seen["follow"] > 0, seen
    if method != "fcfs":
        assert seen["tree"] > 0, seen


def _old_virtual_cap(self, world, rs):
    """VirtualPlatoon._virtual_cap at 4d79153."""
    p = self.p
    f = world.fleet
    cap = np.full(f.n, np.inf)
    T = self._tree
    if T is None:
        return cap
    rows_all, kk = self._tree_rows
    if not len(rows_all):
        return cap
    U = T["U"]
    mask = U[:, kk].T
    if not mask.any():
        return cap
    b = abs(p.a_min)
    tau = p.cap_tau
    vr = f.speed[T["rear_row"]]
    G = rs.X[rows_all][:, None] - T["rear"][None, :] - p.D_safe
    vs = -b * tau + np.sqrt((b * tau) ** 2 + vr[None, :] ** 2 + 2.0 * b * np.maximum(G, 0.0))
    vs = np.where(mask, vs, np.inf).min(axis=1)
    cap[rows_all] = (vs - f.speed[rows_all]) / tau
    return cap


def _old_anticipate(self, world, rs, mode, xref, vref):
    """VirtualPlatoon._anticipate at 4d79153 (stats in a dict of its own)."""
    from icv_envs.policies.platoon_common import MODE_FREE, MODE_TREE

    stats = {"advised": 0, "anticipating": 0}
    anticipation = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64))
    advised = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))
    T = self._tree
    if T is None:
        return anticipation, advised, stats
    f = world.fleet
    lay = world.layout
    p = self.p
    cand = np.flatnonzero((mode == MODE_FREE) & (rs.phase == 0) & (f.node < 0) & (rs.dist > lay.R1)
                          & (rs.dist <= lay.R2) & ~f.cleared)
    if not len(cand):
        return anticipation, advised, stats
    ids = self.node_order
    depths, lens = T["depths"], T["lens"]
    C = lay.conflict[f.mv[cand][:, None], T["mvs"][None, :]]
    behind = ((lay.leg_of[T["mvs"]][None, :] == f.leg[cand][:, None])
              & (rs.dist[T["rear_row"]][None, :] >= rs.dist[cand][:, None]))
    first_behind = np.where(behind.any(axis=1), behind.argmax(axis=1), len(ids))
    C &= np.arange(len(ids))[None, :] < first_behind[:, None]
    dnew = 1 + np.where(C, depths[None, :], 0).max(axis=1, initial=0)
    layer_max = np.zeros(int(max(dnew.max(), depths.max(initial=0))) + 1)
    np.maximum.at(layer_max, depths, lens)
    before = np.concatenate([[0.0], np.cumsum(layer_max)])
    x0 = float(T["refs"][0])
    ref = x0 + dnew * p.D_t + before[dnew]
    lbc = np.where(C, T["rear"][None, :] + p.D_t, -np.inf)
    lb = lbc.max(axis=1, initial=-np.inf)
    pred = lbc.argmax(axis=1)
    R = np.maximum(ref, lb)
    room = f.speed[cand] ** 2 / (2.0 * abs(p.comfort[0]))
    H = R - rs.X[cand]
    hold = (H > 0) & (H <= room)
    slow = (H > room) & (p.advisory_speed_floor < p.v0)
    if not (hold.any() or slow.any()):
        return anticipation, advised, stats
    L = np.maximum(rs.dist[cand] - lay.R1, 0.0)
    v_adv = np.maximum(p.v0 * L / (L + np.maximum(H, 1e-9)), p.advisory_speed_floor)
    if slow.any():
        ks = cand[slow]
        mode[ks] = MODE_TREE
        xref[ks] = rs.X[ks]
        vref[ks] = v_adv[slow]
        advised = (ks, v_adv[slow], H[slow])
        stats["advised"] += len(ks)
    if not hold.any():
        return anticipation, advised, stats
    k = cand[hold]
    mode[k] = MODE_TREE
    xref[k] = R[hold]
    vref[k] = np.where(lb[hold] >= ref[hold], f.speed[T["rear_row"][pred[hold]]], p.v0)
    bound = np.where(lb[hold] >= ref[hold], np.asarray(ids, dtype=np.int64)[pred[hold]], -1)
    anticipation = (k, R[hold], bound)
    stats["anticipating"] += len(k)
    return anticipation, advised, stats


def _old_advise_in_zone(self, world, rs, xref, vref, tight):
    """VirtualPlatoon._advise_in_zone at b4c2680 (stats in a dict of its own)."""
    from icv_envs.sim.intersection_metrics import QUEUE_GAP

    p = self.p
    f = world.fleet
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(0))
    rows, _ = self._tree_rows
    if not len(rows):
        return empty, 0
    H = xref[rows] - rs.X[rows]
    room = f.speed[rows] ** 2 / (2.0 * abs(p.comfort[0]))
    L = np.maximum(-rs.u[rows] - 0.5 * f.length[rows] - p.stop_margin, 0.0)
    w = (rs.phase[rows] == 0) & (H > room) & (L - room > QUEUE_GAP)
    k = rows[w]
    if not len(k):
        return empty, 0
    v_tree = vref[k].copy()
    vref[k] = p.v0 * L[w] / (L[w] + H[w])
    xref[k] = rs.X[k]
    tight[k] = False
    return (k, vref[k].copy(), H[w], v_tree), len(k)


def _old_anticipation_core(cand, mv, leg, dist, X, speed, conflict, leg_of, mvs, rear_row, rear, depths, lens, x0,
                           D_t, comfort0):
    """The part of the frozen _anticipate that anticipated_references replaced."""
    K = len(mvs)
    C = conflict[mv[cand][:, None], mvs[None, :]]
    behind = (leg_of[mvs][None, :] == leg[cand][:, None]) & (dist[rear_row][None, :] >= dist[cand][:, None])
    first_behind = np.where(behind.any(axis=1), behind.argmax(axis=1), K)
    C &= np.arange(K)[None, :] < first_behind[:, None]
    dnew = 1 + np.where(C, depths[None, :], 0).max(axis=1, initial=0)
    layer_max = np.zeros(int(max(dnew.max(), depths.max(initial=0))) + 1)
    np.maximum.at(layer_max, depths, lens)
    before = np.concatenate([[0.0], np.cumsum(layer_max)])
    ref = x0 + dnew * D_t + before[dnew]
    lbc = np.where(C, rear[None, :] + D_t, -np.inf)
    lb = lbc.max(axis=1, initial=-np.inf)
    pred = lbc.argmax(axis=1)
    R = np.maximum(ref, lb)
    room = speed[cand] ** 2 / (2.0 * abs(comfort0))
    H = R - X[cand]
    return ref, lb, pred, R, room, H


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_anticipated_references_equal_the_replaced_array_code(data):
    from icv_envs.policies._kernels import anticipated_references

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n_mv, n = 12, data.draw(st.integers(1, 30))
    K = data.draw(st.integers(1, 10))
    conflict = rng.random((n_mv, n_mv)) < 0.5
    conflict = conflict | conflict.T
    leg_of = np.arange(n_mv, dtype=np.int64) // 3
    mv = rng.integers(0, n_mv, n).astype(np.int64)
    leg = leg_of[mv]
    # distances and rears with ties (the own-leg test's >=, the bound's argmax)
    dist = rng.choice([50.0, 120.0, 120.0, 300.0], n) + (rng.random(n) if data.draw(st.booleans()) else 0.0)
    X = rng.uniform(-300, 0, n)
    speed = rng.uniform(0, 15, n)
    mvs = rng.integers(0, n_mv, K).astype(np.int64)
    rear_row = rng.integers(0, n, K).astype(np.int64)
    rear = rng.choice([-40.0, -40.0, -10.5, 3.0], K) + (rng.uniform(-1, 1, K) if data.draw(st.booleans()) else 0.0)
    depths = rng.integers(1, 4, K).astype(np.int64)  # several nodes per layer
    lens = rng.choice([0.0, 5.0, 17.3], K) + rng.uniform(0, 30, K)
    cand = np.flatnonzero(rng.random(n) < 0.6).astype(np.int64)
    if not len(cand):
        cand = np.array([0], dtype=np.int64)
    x0, D_t, comfort0 = float(rng.uniform(-50, 0)), float(rng.choice([21.0, 19.7])), -3.3
    want = _old_anticipation_core(cand, mv, leg, dist, X, speed, conflict, leg_of, mvs, rear_row, rear, depths, lens,
                                  x0, D_t, comfort0)
    got = anticipated_references(cand, mv, leg, dist, X, speed, conflict, leg_of, mvs, rear_row, rear, depths, lens,
                                 x0, D_t, float(2.0 * abs(comfort0)))
    for g, w in zip(got, want):
        assert _same(g, w)


def _old_tree_layers(mvs, conflict, xf, lens, rear, D_t):
    """The end of VirtualPlatoon.tree at 4d79153."""
    from icv_envs.platoon._kernels import depths_of
    from icv_envs.platoon.tree import _reference_positions

    K = len(mvs)
    C = conflict[np.ix_(mvs, mvs)]
    depths = depths_of(C)
    refs = _reference_positions(np.maximum.accumulate(xf), lens, depths, float(D_t))
    U = np.triu(C, 1)
    cand = np.where(U, rear[:, None] + D_t, -np.inf)
    lb = cand.max(axis=0) if K else np.zeros(0)
    pred = cand.argmax(axis=0) if K else np.zeros(0, dtype=np.int64)
    return depths, refs, U, lb, pred


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_tree_layers_equal_the_replaced_array_code(data):
    from icv_envs.policies._kernels import tree_layers

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n_mv, K = 12, data.draw(st.integers(1, 12))
    conflict = rng.random((n_mv, n_mv)) < data.draw(st.sampled_from([0.2, 0.5, 0.9]))
    conflict = conflict | conflict.T
    mvs = rng.integers(0, n_mv, K).astype(np.int64)
    xf = np.sort(rng.uniform(-300, 0, K)) if data.draw(st.booleans()) else rng.uniform(-300, 0, K)
    lens = rng.choice([0.0, 5.0, 17.3], K) + (rng.uniform(0, 30, K) if data.draw(st.booleans()) else 0.0)
    rear = rng.choice([-40.0, -40.0, -10.5], K) + (rng.uniform(-1, 1, K) if data.draw(st.booleans()) else 0.0)
    D_t = float(rng.choice([21.0, 19.7]))
    want = _old_tree_layers(mvs, conflict, xf, lens, rear, D_t)
    got = tree_layers(mvs, conflict, xf, lens, rear, D_t)
    for g, w in zip(got, want):
        assert _same(g, w)


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 2), ("fcfs", 2600.0, 5)])
def test_prune_shortcut_changes_nothing(monkeypatch, method, throughput, seed):
    """PlatoonExpert._prune skips its rebuild when nothing left; every step
    its groups equal those of the full rebuild (the code before), applied to
    a copy."""
    import copy

    from icv_envs.policies.platoon_expert import PlatoonExpert

    real = PlatoonExpert._prune
    seen = {"skipped": 0, "removed": 0}

    def checked(self, f):
        ref = copy.deepcopy((self.formations, self.subs, self.nodes, self.vp_order))
        alive = set(f.vid.tolist())
        PlatoonExpert._keep_members(alive.__contains__, ref[:3])
        want_order = [k for k in ref[3] if k in ref[2]]
        before = sum(len(g["members"]) for st in (self.formations, self.subs, self.nodes) for g in st.values())
        real(self, f)
        assert (self.formations, self.subs, self.nodes) == ref[:3] and self.vp_order == want_order
        after = sum(len(g["members"]) for st in (self.formations, self.subs, self.nodes) for g in st.values())
        seen["removed"] += before - after
        seen["skipped"] += before == after

    monkeypatch.setattr(PlatoonExpert, "_prune", checked)
    _drive_intersection(method, throughput, seed, 120.0, 600)
    assert seen["removed"] > 0 and seen["skipped"] > 0, seen


# ----------------------------------------------------------------------------
# VirtualPlatoon._references (follow and tree references, the stop flags)
def _old_references(self, world, rs) -> None:
    """VirtualPlatoon._references at 4d79153 (from stop 41 one compiled
    call after the tree, ``vp_references``)."""
    from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_FREE, MODE_TREE
    p = self.p
    f = world.fleet
    lay = world.layout
    n = f.n
    mode = np.full(n, MODE_FREE, dtype=np.int64)
    xref = np.zeros(n)  # MODE_FOLLOW: u reference; MODE_TREE: X reference
    vref = np.full(n, p.v0)
    tight = np.zeros(n, dtype=bool)  # the safety bound binds: full braking allowed
    hold = np.zeros(n, dtype=bool)  # the bound is violated: stop before the box
    # formation following (approach / adjusting zones, and followers of nodes before R1)
    fol = (f.ref >= 0) & (f.node < 0)
    if fol.any():
        k = np.flatnonzero(fol)
        rr = f.rows(f.ref[k])
        # safety net: two vehicles referring to each other (must not happen)
        cyc = (rr >= 0) & (f.ref[np.maximum(rr, 0)] == f.vid[k]) & (rs.dist[k] < rs.dist[np.maximum(rr, 0)])
        if cyc.any():
            self.stats["ref_cycles_broken"] += int(cyc.sum())
            f.ref[k[cyc]] = -1
            rr[cyc] = -1
        ok = rr >= 0
        k, rr = k[ok], rr[ok]
        # a follower ahead of the vehicle it follows, in that vehicle's own
        # lane, is that vehicle's leader on the road: holding its slot
        # (ahead of the reference, in another lane) makes each wait for the
        # other once the lane change to the slot is blocked, a circular
        # wait (multi-vp, 3500 veh/h, seed 0: a member stood 1 m ahead of
        # its sub-formation's first vehicle in lane 2, waiting for a gap
        # in lane 1, for 150 s). Such a follower drives free until the
        # lane change separates the two.  The same holds in the lane that
        # vehicle waits to change into: it is listed there too (its turn
        # signal), brakes behind the follower alongside or ahead of it,
        # and the follower stood waiting to drop back to its slot behind
        # it (multi-vp, 3000 veh/h, seed 23: from 450 s to the end of the
        # run, 39 vehicles jammed behind the two)
        sig = self._signals(f)
        in_its_lanes = (f.klane[k] == f.klane[rr]) | (f.klane[k] == sig[rr])
        ahead = in_its_lanes & (rs.dist[k] < rs.dist[rr]) & (rs.phase[k] == 0)
        if ahead.any():
            self.stats["ahead_of_reference"] += int(ahead.sum())
            k, rr = k[~ahead], rr[~ahead]
        mode[k] = MODE_FOLLOW
        xref[k] = rs.u[rr] - f.xg[k]
        vref[k] = f.speed[rr]
    self.node_depth = {}
    self.node_order = []
    self._tree = None
    self._tree_rows = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    if self.nodes:
        ids, depths, T = self.tree(world, rs)
        self.node_order = ids
        for k, nid in enumerate(ids):
            self.node_depth[nid] = int(depths[k + 1])
        members = [self.nodes[nid]["members"] for nid in ids]  # (_member_rows(f, ids) until stop 40)
        rows_all = f.rows(np.concatenate([np.asarray(m, dtype=np.int64) for m in members]))
        kk = np.repeat(np.arange(len(ids)), [len(m) for m in members])
        live = ~f.cleared[rows_all]
        rows_all, kk = rows_all[live], kk[live]
        self._tree, self._tree_rows = T, (rows_all, kk)
        first = T["first"][kk]
        is_first = rows_all == first
        # a node's first vehicle never chases a reference ahead of it: it
        # then drives at v0 (the virtual platoon only holds vehicles back)
        # followers: their slot relative to the first vehicle's slot, which is
        # not slot 0 once the members ahead of it have left the road (with
        # the absolute slot, multi-vp, 3000 veh/h, seed 2: a member with
        # x_g = 72 m following the node's new first vehicle 9-11 m behind
        # got a reference 30-50 m behind it, braked to a stop in the box
        # and held the whole virtual platoon: 9 jammed at R1)
        paper = np.where(is_first, np.maximum(T["refs"][kk + 1], rs.X[rows_all]),
                         rs.X[first] + f.xg[rows_all] - f.xg[first])
        vpaper = np.where(is_first, p.v0, f.speed[first])
        lb = T["lb"][kk]
        bind = lb > paper
        pred_rear = T["rear_row"][T["pred"][kk]]
        mode[rows_all] = MODE_TREE
        # the hard spacing to an earlier conflicting node is already lost
        # (a node that entered late, close to the box): the virtual lane
        # cannot restore it, so the vehicle stops before the box until
        # that node's rear has moved D_safe ahead of it
        hold[rows_all] = rs.X[rows_all] < lb - (p.D_t - p.D_safe) - 1e-9
        xref[rows_all] = np.where(bind, lb, paper)
        vref[rows_all] = np.where(bind, f.speed[pred_rear], vpaper)
        tight[rows_all] = bind
    # (from stop 41 the advisory, the anticipation and the caps through their
    # frozen forms above, which these methods were until then)
    self._zone_advised = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(0))
    if p.zone_advisory:
        self._zone_advised, n_zone = _old_advise_in_zone(self, world, rs, xref, vref, tight)
        self.stats["advised_in_zone"] += n_zone
    advised = self._zone_advised[0]
    if p.anticipate:
        self._anticipation, self._advised, s2 = _old_anticipate(self, world, rs, mode, xref, vref)
        for k, v in s2.items():
            self.stats[k] += v
    self._mode, self._xref, self._vref, self._tight = mode, xref, vref, tight
    self._apply_yields(world, rs)
    self._vcap = _old_virtual_cap(self, world, rs)
    # may a vehicle enter the box? only from an allowed lane, lane change finished
    allowed = lay.allowed[f.mv, np.clip(f.klane, 0, 2)]
    self._stop = (rs.phase == 0) & (~allowed | (f.lc_lane >= 0) | (f.klane != f.tlane))
    # in the coordinating zone only coordinated vehicles (a node / a reservation) may enter
    self._stop |= (rs.phase == 0) & (rs.dist <= lay.R1) & ~self._coordinated(f)
    self._stop |= (rs.phase == 0) & hold
    self._stop[advised] = True  # the hold lasts: it waits at the stop line at most
    self.stats["held_at_line"] += int(((rs.phase == 0) & hold).sum())
    self._stop &= ~(rs.u > -0.5 * f.length)  # a vehicle already at the line goes on


@pytest.mark.parametrize("method,throughput,seed,steps", [("multi-vp", 3000.0, 2, 300), ("single-vp", 2600.0, 4, 300),
                                                          ("fcfs", 2600.0, 5, 300), ("multi-vp", 2600.0, 3, 600)])
def test_references_equal_the_replaced_array_code_on_runs(monkeypatch, method, throughput, seed, steps):
    """Step by step on runs, the modes, references, caps, stop flags, the
    cut references, the counters and the advisory's, anticipation's and
    tree's inspection arrays equal the frozen code's (from stop 41 one
    compiled call after the tree; a long multi-vp run for the advisories)."""
    import copy

    from icv_envs.policies.virtual_platoon import VirtualPlatoon

    real = VirtualPlatoon._references
    seen = {"follow": 0, "tree": 0, "stop": 0, "zone": 0, "ant": 0, "adv": 0}

    def checked(self, world, rs):
        me2, w2, rs2 = copy.deepcopy((self, world, rs))
        _old_references(me2, w2, rs2)
        real(self, world, rs)
        for name in ("_mode", "_xref", "_vref", "_tight", "_stop", "_vcap"):
            assert _same(getattr(self, name), getattr(me2, name)), name
        assert self.stats == me2.stats
        assert _same(world.fleet.ref, w2.fleet.ref)
        for name in ("_tree_rows", "_zone_advised", "_anticipation", "_advised"):
            got, want = getattr(self, name), getattr(me2, name)
            assert len(got) == len(want) and all(_same(a, b) for a, b in zip(got, want)), name
        assert self.node_order == me2.node_order and self.node_depth == me2.node_depth
        seen["follow"] += int((self._mode == 1).sum())
        seen["tree"] += int((self._mode == 2).sum())
        seen["stop"] += int(self._stop.sum())
        seen["zone"] += len(self._zone_advised[0])
        seen["ant"] += len(self._anticipation[0])
        seen["adv"] += len(self._advised[0])

    monkeypatch.setattr(VirtualPlatoon, "_references", checked)
    _drive_intersection(method, throughput, seed, steps / 5.0, steps)
    assert seen["follow"] > 0 and seen["stop"] > 0, seen
    if method != "fcfs":
        assert seen["tree"] > 0, seen
    if steps == 600:  # (the advisory inside R1 and the anticipation ran)
        assert seen["zone"] > 0 and seen["ant"] > 0 and seen["adv"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_reference_kernels_equal_the_replaced_array_code(data):
    """follow_references, tree_references and stop_flags against the
    fragments of the frozen _references they replaced, on random fleets
    pushed onto their boundaries (reference cycles, gone references, a
    follower in its reference's signal lane, equal distances, X exactly at
    the hold bound, dist exactly R1, u exactly at the line)."""
    from icv_envs.policies._kernels import follow_references, stop_flags, tree_references

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(2, 25))
    vid = np.sort(rng.choice(200, n, replace=False)).astype(np.int64)
    dist = rng.choice([100.0, 150.0, 150.0], n) + (rng.uniform(0, 50, n) if data.draw(st.booleans()) else 0.0)
    klane = rng.integers(-1, 4, n).astype(np.int64)
    sig = rng.integers(-1, 3, n).astype(np.int64)
    phase = rng.integers(0, 3, n).astype(np.int64)
    u = rng.uniform(-300, 10, n)
    xg = rng.choice([0.0, 7.5, 15.0], n) + (rng.uniform(0, 1, n) if data.draw(st.booleans()) else 0.0)
    speed = rng.uniform(0, 15, n)
    # 1. follow: followers k, their reference vehicles' rows rr (some gone, some mutual)
    k = np.flatnonzero(rng.random(n) < 0.6).astype(np.int64)
    rr = rng.integers(-1, n, len(k)).astype(np.int64)
    ref = np.full(n, -1, dtype=np.int64)
    ref[k] = np.where(rr >= 0, vid[np.maximum(rr, 0)], 999)
    if len(k) >= 2 and data.draw(st.booleans()):  # a mutual pair
        a, b = k[0], k[1]
        rr[0], rr[1] = b, a
        ref[a], ref[b] = vid[b], vid[a]
    if data.draw(st.booleans()):
        sig[np.maximum(rr, 0)] = klane[k]
    mode_a, xref_a, vref_a = np.zeros(n, dtype=np.int64), np.zeros(n), np.full(n, 15.0)
    mode_b, xref_b, vref_b = mode_a.copy(), xref_a.copy(), vref_a.copy()
    ref_a, ref_b = ref.copy(), ref.copy()
    # (the frozen fragment)
    ka, rra = k.copy(), rr.copy()
    cyc = (rra >= 0) & (ref_a[np.maximum(rra, 0)] == vid[ka]) & (dist[ka] < dist[np.maximum(rra, 0)])
    n_cyc = int(cyc.sum())
    ref_a[ka[cyc]] = -1
    rra[cyc] = -1
    ok = rra >= 0
    ka, rra = ka[ok], rra[ok]
    in_its_lanes = (klane[ka] == klane[rra]) | (klane[ka] == sig[rra])
    ahead = in_its_lanes & (dist[ka] < dist[rra]) & (phase[ka] == 0)
    n_ahead = int(ahead.sum())
    ka, rra = ka[~ahead], rra[~ahead]
    mode_a[ka] = 1
    xref_a[ka] = u[rra] - xg[ka]
    vref_a[ka] = speed[rra]
    got = follow_references(k, rr, ref_b, vid, dist, klane, sig, phase, u, xg, speed, 1, mode_b, xref_b, vref_b)
    assert got == (n_cyc, n_ahead)
    for x, y in ((mode_a, mode_b), (xref_a, xref_b), (vref_a, vref_b), (ref_a, ref_b)):
        assert _same(x, y)
    # 2. tree: live members of K nodes
    K = data.draw(st.integers(1, 5))
    kk = rng.integers(0, K, n).astype(np.int64)
    rows_all = np.flatnonzero(rng.random(n) < 0.7).astype(np.int64)
    kk = kk[rows_all]
    first_of = np.array([rows_all[kk == c][0] if (kk == c).any() else 0 for c in range(K)], dtype=np.int64)
    X = rng.uniform(-200, 0, n)
    refs = np.concatenate([[0.0], rng.uniform(-250, 0, K)])
    lb_of = np.where(rng.random(K) < 0.3, -np.inf, rng.uniform(-250, 0, K))
    D_t, D_safe = 21.0, 10.0
    if len(rows_all) and data.draw(st.booleans()):  # X exactly on the hold bound, paper exactly at the bound
        X[rows_all[0]] = lb_of[kk[0]] - (D_t - D_safe) - 1e-9
        refs[kk[0] + 1] = lb_of[kk[0]]
    pred_of = rng.integers(0, K, K).astype(np.int64)
    rear_row = rng.integers(0, n, K).astype(np.int64)
    arrs_a = (np.zeros(n, dtype=np.int64), np.zeros(n), np.full(n, 15.0), np.zeros(n, dtype=bool), np.zeros(n, bool))
    arrs_b = tuple(a.copy() for a in arrs_a)
    mode_a, xref_a, vref_a, tight_a, hold_a = arrs_a
    first = first_of[kk]
    is_first = rows_all == first
    paper = np.where(is_first, np.maximum(refs[kk + 1], X[rows_all]), X[first] + xg[rows_all] - xg[first])
    vpaper = np.where(is_first, 15.0, speed[first])
    lb = lb_of[kk]
    bind = lb > paper
    pred_rear = rear_row[pred_of[kk]]
    mode_a[rows_all] = 2
    hold_a[rows_all] = X[rows_all] < lb - (D_t - D_safe) - 1e-9
    xref_a[rows_all] = np.where(bind, lb, paper)
    vref_a[rows_all] = np.where(bind, speed[pred_rear], vpaper)
    tight_a[rows_all] = bind
    tree_references(rows_all, kk, first_of, refs, lb_of, pred_of, rear_row, X, xg, speed, 15.0, D_t - D_safe, 2,
                    *arrs_b)
    for x, y in zip(arrs_a, arrs_b):
        assert _same(x, y)
    # 3. the stop flags
    allowed = rng.random((12, 3)) < 0.6
    mv = rng.integers(0, 12, n).astype(np.int64)
    lc_lane = rng.integers(-1, 3, n).astype(np.int64)
    tlane = np.where(rng.random(n) < 0.7, klane, rng.integers(0, 3, n)).astype(np.int64)
    R1 = 150.0
    coordinated = rng.random(n) < 0.5
    hold = rng.random(n) < 0.3
    advised = np.flatnonzero(rng.random(n) < 0.2).astype(np.int64)
    length = rng.choice([4.5, 5.0], n)
    u = np.where(rng.random(n) < 0.3, -0.5 * length, u)
    want = (phase == 0) & (~allowed[mv, np.clip(klane, 0, 2)] | (lc_lane >= 0) | (klane != tlane))
    want |= (phase == 0) & (dist <= R1) & ~coordinated
    want |= (phase == 0) & hold
    want[advised] = True
    held = int(((phase == 0) & hold).sum())
    want &= ~(u > -0.5 * length)
    got, got_held = stop_flags(phase, allowed, mv, klane, lc_lane, tlane, dist, R1, coordinated, hold, advised, u,
                               length)
    assert _same(got, want) and got_held == held


# ----------------------------------------------------------------------------
# the intersection env's features and rewards (icv_envs/envs/intersection.py at 4d79153)
def _old_intersection_features(self):
    w = self.world
    f = w.fleet
    lay = self.layout
    rs = w.route()
    has, d, dv, go = self.expert.references(w)
    F = np.zeros((f.n, 14))
    F[:, 0] = 1.0
    F[:, 1] = rs.cx
    F[:, 2] = rs.cy
    F[:, 3] = f.speed * np.cos(f.heading)
    F[:, 4] = f.speed * np.sin(f.heading)
    F[:, 5] = np.cos(f.heading)
    F[:, 6] = np.sin(f.heading)
    F[:, 7] = rs.dist
    F[:, 8] = np.where(has, d, 0.0)
    F[:, 9] = np.where(has, dv, 0.0)
    appr = rs.phase == 0
    F[:, 10] = np.where(appr, rs.lat_leg - (np.clip(f.klane, 0, 2) + 0.5) * lay.lane_width, rs.lat)
    F[:, 11] = (f.mv % 3) - 1.0
    zone = np.where(rs.dist > lay.R2, 0.0, np.where(rs.dist > lay.R1, 1.0 / 3.0, 2.0 / 3.0))
    F[:, 12] = np.where(appr, zone, 1.0)
    F[:, 13] = go
    if getattr(self._obs_type, "extra", ()):
        pd = self._perception_distance()
        gap, dv = self._leaders()
        has = np.isfinite(gap)
        F = np.column_stack([F, np.where(has, np.minimum(gap, pd), pd), np.where(has, dv, 0.0)])
    return F


def _old_intersection_rewards(self, rows, crashed_now, F):
    c = self.config
    f = self.world.fleet
    wts = c["reward"]
    lo, hi = c["reward_speed_range"] or (0.0, c["speed_range"][1])
    progress = np.clip((f.speed[rows] - float(lo)) / (float(hi) - float(lo)), 0.0, 1.0)
    gap = self._leaders()[0]
    safety = -np.clip(1.0 - gap[rows] / (2.0 + f.speed[rows]), 0.0, 1.0)
    safety = np.where(crashed_now[rows], -1.0, safety)
    ua = self._last_actions[rows] if len(self._last_actions) == f.n else np.zeros((len(rows), 2))
    comfort = -0.5 * (ua[:, 0] ** 2 + ua[:, 1] ** 2)
    track = np.where(F[rows, 8] != 0.0, np.exp(-(F[rows, 8] / 10.0) ** 2), 0.0)
    total = wts["progress"] * progress + wts["safety"] * safety + wts["comfort"] * comfort + wts["tracking"] * track
    return total, {"progress": progress, "safety": safety, "comfort": comfort, "tracking": track}


@pytest.mark.parametrize("method,seed,extra", [("multi-vp", 3, False), ("fcfs", 5, True)])
@at_pinned_level  # libm's transcendental steps against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
def test_intersection_features_and_rewards_equal_the_replaced_array_code(monkeypatch, method, seed, extra):
    from icv_envs.envs import intersection_v0
    from icv_envs.envs.intersection import IntersectionEnv

    real_f, real_r = IntersectionEnv._features, IntersectionEnv._rewards_rows
    seen = {"calls": 0, "tracked": 0, "crashed": 0}

    def features(self):
        got = real_f(self)
        assert _same(got, _old_intersection_features(self))
        seen["calls"] += 1
        seen["tracked"] += int((got[:, 8] != 0.0).sum())
        return got

    def rewards(self, rows, crashed_now, F):
        got = real_r(self, rows, crashed_now, F)
        want = _old_intersection_rewards(self, rows, crashed_now, F)
        assert _same(got[0], want[0]) and got[1].keys() == want[1].keys()
        for k in want[1]:
            assert _same(got[1][k], want[1][k]), k
        seen["crashed"] += int(np.asarray(crashed_now)[rows].sum())
        return got

    monkeypatch.setattr(IntersectionEnv, "_features", features)
    monkeypatch.setattr(IntersectionEnv, "_rewards_rows", rewards)
    cfg = {"observation": {"type": "Kinematics", "features": ["presence", "x", "y", "lead_gap", "lead_dv"]}} \
        if extra else {}
    env = intersection_v0.parallel_env(method=method, throughput=2600.0, duration=60.0, **cfg)
    obs, infos = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(300):
        if not env.agents:
            break
        # a third of the agents act at random (collisions: the safety term's -1)
        acts = {a: (rng.uniform(-1, 1, 2).astype(np.float32) if rng.random() < 0.3 else infos[a]["expert_action"])
                for a in env.agents}
        obs, rew, term, trunc, infos = env.step(acts)
    assert seen["calls"] > 100 and seen["tracked"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_platoon_accelerations_equal_the_replaced_array_code(data):
    """platoon_accelerations against the frozen _longitudinal's array code on
    random fleets: every mode, tight and not, errors beyond the clip, hard
    braking below the comfort range, caps above and below the law."""
    from icv_envs.policies._kernels import platoon_accelerations

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(1, 30))
    v = rng.choice([0.0, 5.0, 12.0], n) + rng.uniform(0, 3, n)
    mode = rng.integers(0, 4, n).astype(np.int64)
    u, X = rng.uniform(-300, 0, n), rng.uniform(-300, 0, n)
    xref = np.where(rng.random(n) < 0.5, u + rng.uniform(-80, 80, n), -X + rng.uniform(-80, 80, n))
    vref = rng.uniform(0, 15, n)
    tight = rng.random(n) < 0.5
    vcap = np.where(rng.random(n) < 0.5, np.inf, rng.uniform(-8, 3, n))
    p = dict(v0=15.0, a_max=2.0, comfort=(-3.0, 1.5), idm_b=2.0, idm_T=1.2, idm_s0=2.0, clip=20.0,
             kp=float(rng.choice([-0.3, -1.0])), kv=-0.8, a_min=-7.0)
    # the frozen array code
    acc = idm_acceleration(v, p["v0"], np.inf, 0.0, min(p["a_max"], p["comfort"][1]), p["idm_b"], p["idm_T"],
                           p["idm_s0"])
    fol = np.flatnonzero(mode == 1)
    if len(fol):
        x = u[fol]
        xr = x + np.clip(xref[fol] - x, -p["clip"], p["clip"])
        acc[fol] = _longitudinal_feedback(x, xr, v[fol], vref[fol], p["kp"], p["kv"], p["comfort"][0],
                                          p["comfort"][1], 0.0)
    tr = np.flatnonzero(mode == 2)
    binding = 0
    if len(tr):
        x = -X[tr]
        xr = x + np.clip(-xref[tr] - x, -p["clip"], p["clip"])
        lo = np.where(tight[tr], p["a_min"], p["comfort"][0])
        a = _longitudinal_feedback(x, xr, v[tr], vref[tr], p["kp"], p["kv"], p["a_min"], p["a_max"], 0.0)
        a = np.clip(a, lo, p["a_max"])
        binding = int((vcap[tr] < a - 0.5).sum())
        acc[tr] = np.minimum(a, vcap[tr])
    free_pow = (v / np.maximum(p["v0"], 0.1)) ** 4.0
    got, got_binding = platoon_accelerations(
        v, free_pow, float(min(p["a_max"], p["comfort"][1])), p["idm_b"], p["idm_T"], p["idm_s0"], mode, 1, 2, u, X,
        xref, vref, tight, vcap, p["clip"], p["kp"], p["kv"], p["comfort"][0], p["comfort"][1], p["a_min"],
        p["a_max"])
    assert _same(got, acc) and got_binding == binding


def _old_tree_glue(rows, seg, sizes, ids, vp_order, mvs, lens, X, dist, phase, lane, cleared, leg_of, conflict, D_t):
    """VirtualPlatoon.tree at b4c2680 (its calls of node_heads, the ranks'
    stable argsort, _repair_order's repair_order and tree_layers) and
    _references' ordered member rows of the not yet cleared members."""
    from icv_envs.policies._kernels import node_heads, repair_order, tree_layers

    (first, rear_row), (xf, rear) = node_heads(rows, sizes, X[rows], dist[rows])
    rank = {k: i for i, k in enumerate(vp_order)}
    o = np.argsort([rank.get(k, len(rank) + k) for k in ids], kind="stable")
    at, moves = repair_order(np.asarray(o, dtype=np.int64), len(ids), rows, seg, phase, lane, dist, leg_of[mvs])
    xf, rear, first, rear_row, mvs, lens = xf[at], rear[at], first[at], rear_row[at], mvs[at], lens[at]
    depths, refs, U, lb, pred = tree_layers(mvs, conflict, xf, lens, rear, D_t)
    members = np.split(rows, np.cumsum(sizes)[:-1])
    r_all = np.concatenate([members[g] for g in at])
    kk = np.repeat(np.arange(len(at)), sizes[at])
    live = ~cleared[r_all]
    return moves, at, first, rear_row, pred, mvs, xf, rear, lb, lens, depths, refs, U, r_all[live], kk[live]


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_vp_tree_is_the_tree_it_replaced(data):
    """``vp_tree`` (stop 41) against the composition it replaced: the same
    order, moves, heads, layers, references, bounds and live members, on
    nodes of shared lanes and legs (integer distances make ties and repairs
    common), ids listed in ``vp_order`` or not, twice or in another order."""
    from icv_envs.policies._kernels import vp_tree

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n_mv, K = 12, data.draw(st.integers(1, 10))
    conflict = rng.random((n_mv, n_mv)) < data.draw(st.sampled_from([0.2, 0.5, 0.9]))
    conflict = conflict | conflict.T
    leg_of = np.repeat(np.arange(4), 3).astype(np.int64)
    sizes = rng.integers(1, 5, K).astype(np.int64)
    n = int(sizes.sum()) + 4
    rows = rng.permutation(n)[: int(sizes.sum())].astype(np.int64)
    seg = np.repeat(np.arange(K), sizes).astype(np.int64)
    ids = np.sort(rng.choice(40, K, replace=False)).astype(np.int64)
    pool = np.concatenate([ids, rng.integers(40, 50, 3)])
    vp_order = rng.choice(pool, data.draw(st.integers(0, K + 3)), replace=data.draw(st.booleans())).astype(np.int64)
    mvs = rng.integers(0, n_mv, K).astype(np.int64)
    lens = rng.choice([0.0, 5.0, 17.3], K)
    grid = data.draw(st.booleans())
    X = rng.integers(-30, 0, n).astype(float) if grid else rng.uniform(-300, 0, n)
    dist = rng.integers(0, 30, n).astype(float) if grid else rng.uniform(0, 300, n)
    phase = (rng.random(n) < 0.2).astype(np.int64)
    lane = rng.integers(0, 3, n).astype(np.int64)
    cleared = rng.random(n) < 0.2
    D_t = float(rng.choice([21.0, 19.7]))
    want = _old_tree_glue(rows, seg, sizes, ids.tolist(), vp_order.tolist(), mvs, lens, X, dist, phase, lane, cleared,
                          leg_of, conflict, D_t)
    moves, I, F, depths, refs, U, live_rows, live_node = vp_tree(rows, seg, sizes, ids, vp_order, mvs, lens, X, dist,
                                                                 phase, lane, cleared, leg_of, conflict, D_t)
    got = (moves, I[0], I[1], I[2], I[3], I[4], F[0], F[1], F[2], F[3], depths, refs, U, live_rows, live_node)
    for g, w in zip(got, want):
        assert _same(np.asarray(g), np.asarray(w))


# ----------------------------------------------------------------------------
# VirtualPlatoon._detach_inverted (its test compiled from stop 41), frozen
def _old_detach_inverted(self, world, rs) -> None:
    """VirtualPlatoon._detach_inverted at b4c2680. A node member whose leader in its approach lane is a vehicle of
    another group (still before the box) would be ordered before it but
    cannot pass it: that member and every member of its node further
    from the centre leave the node and form a node of their own (ordered
    after the foreign vehicle)."""
    f = world.fleet
    rows = np.flatnonzero((f.node >= 0) & (rs.phase == 0))
    if not len(rows):
        return
    from icv_envs.formation.targets import formation_length, interlaced_targets
    from icv_envs.policies.platoon_common import Corridors

    cor = Corridors.plain(world, rs)
    lr, _, _, _ = cor.neighbours(rows, 3 * f.leg[rows] + rs.lane[rows], rs.s[rows])
    lr0 = np.maximum(lr, 0)
    bad = (lr >= 0) & (f.node[lr0] != f.node[rows]) & (rs.phase[lr0] == 0)
    if not np.count_nonzero(bad):
        return
    # only a foreign vehicle between the node's first vehicle and this member counts
    ids, mr, seg, _ = self._member_rows(f)
    dmin = np.full(len(ids), np.inf)
    np.minimum.at(dmin, seg, rs.dist[mr])
    first_d = dict(zip(ids, dmin.tolist()))
    fd = np.array([first_d.get(int(nd), np.inf) for nd in f.node[rows]])
    bad &= (rs.dist[lr0] > fd + 1e-9) & (rs.dist[rows] > fd + 1e-9)
    if not np.count_nonzero(bad):
        return
    for nid in sorted(set(f.node[rows[bad]].tolist())):
        N = self.nodes.get(nid)
        if N is None:
            continue
        mrows = f.rows(N["members"])
        cut = float(rs.dist[rows[bad & (f.node[rows] == nid)]].min())
        first = mrows[np.argmin(rs.dist[mrows])]
        out = mrows[(rs.dist[mrows] >= cut) & (mrows != first)]
        if not len(out):
            continue
        keep = [int(v) for v in f.vid[mrows] if v not in set(f.vid[out].tolist())]
        N["members"] = keep
        N["length"] = formation_length(len(keep), N["n_lanes"], self.p.gap_in)
        n_out = len(out)
        out = out[np.argsort(rs.dist[out])]
        tx, _ = interlaced_targets(n_out, N["n_lanes"], self.p.gap_in)
        f.ref[out] = f.vid[out[0]]
        f.xg[out] = tx
        f.ref[out[0]] = -1
        self._new_node(world, [int(v) for v in f.vid[out]], N["mv"], N["n_lanes"],
                       formation_length(n_out, N["n_lanes"], self.p.gap_in))
        self.stats["detached"] += n_out


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 2), ("multi-vp", 3500.0, 0)])
def test_detach_equals_the_replaced_array_code_on_runs(monkeypatch, method, throughput, seed):
    """``_detach_inverted`` (its test one compiled call from stop 41,
    ``detach_candidates``) against the frozen code, step by step: the same
    nodes, members, order, fleet fields and counters."""
    import copy

    from icv_envs.policies.virtual_platoon import VirtualPlatoon

    real = VirtualPlatoon._detach_inverted
    seen = {"calls": 0, "detached": 0}

    def checked(self, world, rs):
        me2, w2, rs2 = copy.deepcopy((self, world, rs))
        _old_detach_inverted(me2, w2, rs2)
        real(self, world, rs)
        assert self.nodes == me2.nodes and self.vp_order == me2.vp_order and self.stats == me2.stats
        for name in ("node", "ref", "xg", "stage"):
            assert _same(getattr(world.fleet, name), getattr(w2.fleet, name)), name
        seen["calls"] += 1
        seen["detached"] = self.stats["detached"]

    monkeypatch.setattr(VirtualPlatoon, "_detach_inverted", checked)
    _drive_intersection(method, throughput, seed, 120.0, 600)
    assert seen["calls"] >= 500 and seen["detached"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_detach_candidates_equal_the_replaced_array_code(data):
    """``detach_candidates`` against the array code of ``_detach_inverted``
    it replaced, on random corridor indices with integer distances (ties with
    the first vehicle's distance), leaders in the box, unlisted nodes and
    vehicles of no node."""
    from icv_envs.policies._kernels import corridor_neighbours, detach_candidates

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(1, 25))
    big = 1.0e5
    K = data.draw(st.integers(1, 5))
    ids = np.sort(rng.choice(20, K, replace=False)).astype(np.int64)
    node = np.where(rng.random(n) < 0.7, rng.choice(np.concatenate([ids, [30]]), n), -1).astype(np.int64)
    phase = (rng.random(n) < 0.2).astype(np.int64)
    leg = rng.integers(0, 2, n).astype(np.int64)
    lane = rng.integers(0, 2, n).astype(np.int64)
    s = rng.integers(-20, 0, n).astype(float)
    dist = rng.integers(0, 8, n).astype(float)
    m = data.draw(st.integers(0, 2 * n))
    e_rows = rng.integers(0, n, m).astype(np.int64)
    e_corr = np.where(rng.random(m) < 0.7, 3 * leg[e_rows] + lane[e_rows], rng.integers(0, 6, m)).astype(np.int64)
    e_coord = s[e_rows] + rng.choice([0.0, 0.0, 1.0], m)
    o = np.lexsort((e_rows, e_corr * big + e_coord))
    keys, corr, crows, coord = (e_corr * big + e_coord)[o], e_corr[o], e_rows[o], e_coord[o]
    members = [np.flatnonzero(node == k) for k in ids]
    mr = np.concatenate(members).astype(np.int64)
    seg = np.repeat(np.arange(K), [len(x) for x in members]).astype(np.int64)
    # the array code (b4c2680)
    rows = np.flatnonzero((node >= 0) & (phase == 0))
    want = np.zeros(len(rows), dtype=bool)
    if len(rows):
        q_corr = 3 * leg[rows] + lane[rows]
        lr, _, _, _ = corridor_neighbours(keys, corr, crows, coord, rows.astype(np.int64), q_corr,
                                          q_corr * big + s[rows])
        lr0 = np.maximum(lr, 0)
        want = (lr >= 0) & (node[lr0] != node[rows]) & (phase[lr0] == 0)
        dmin = np.full(K, np.inf)
        np.minimum.at(dmin, seg, dist[mr])
        first_d = dict(zip(ids.tolist(), dmin.tolist()))
        fd = np.array([first_d.get(int(nd), np.inf) for nd in node[rows]])
        want &= (dist[lr0] > fd + 1e-9) & (dist[rows] > fd + 1e-9)
    got_rows, got = detach_candidates(node, phase, leg, lane, s, dist, keys, corr, crows, coord, big, mr, seg, ids)
    assert _same(got_rows, rows.astype(np.int64)) and _same(got, want)


def _old_lane_change_ready(klane, tlane, lc_lane, phase, stage, st_lc, vid, yv, ref_rows, u, xg, dist, speed, R1,
                           slot_tolerance, want):
    """The first part of Regrouping._start_lane_changes at b4c2680 (the yield
    bookkeeping before it stays Python), with its _slot_error."""
    want[:] = -1
    need = (klane != tlane) & (lc_lane < 0) & (phase == 0) & (stage >= st_lc)
    rows = np.flatnonzero(need)
    yielding = np.fromiter((v in yv for v in vid[rows].tolist()), dtype=bool, count=len(rows))
    ready = np.ones(len(rows), dtype=bool)
    dv = stage[rows] == st_lc
    if np.count_nonzero(dv):
        r2 = rows[dv]
        ref = ref_rows[r2]
        ok = ref >= 0
        err = np.zeros(len(r2))
        err[ok] = u[r2[ok]] - (u[ref[ok]] - xg[r2[ok]])
        ready[dv] = (np.abs(err) < slot_tolerance) | (yielding[dv] & (err < slot_tolerance))
    nxt = klane[rows] + np.sign(tlane[rows] - klane[rows])
    sig = ready & ((dist[rows] <= R1) | (speed[rows] < 2.0)) & ~yielding
    want[rows[sig]] = nxt[sig]
    return rows[ready], nxt[ready]


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_lane_change_ready_equals_the_replaced_array_code(data):
    """``lane_change_ready`` (stop 41) against the array code it replaced:
    the same ready rows, next lanes and signals, with slot errors on a grid
    (ties with the tolerance), yielding vehicles and missing references."""
    from icv_envs.policies._kernels import lane_change_ready

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(0, 25))
    klane = rng.integers(0, 3, n).astype(np.int64)
    tlane = rng.integers(0, 3, n).astype(np.int64)
    lc_lane = np.where(rng.random(n) < 0.2, rng.integers(0, 3, n), -1).astype(np.int64)
    phase = (rng.random(n) < 0.2).astype(np.int64)
    stage = rng.integers(0, 4, n).astype(np.int64)
    vid = rng.permutation(50)[:n].astype(np.int64)
    yv = np.unique(np.concatenate([vid[rng.random(n) < 0.4], rng.choice(50, 2)])).astype(np.int64)
    ref_rows = np.where(rng.random(n) < 0.7, rng.integers(0, max(n, 1), n), -1).astype(np.int64)
    u = rng.integers(-40, 0, n).astype(float)
    xg = rng.choice([0.0, 5.0, -5.0, 3.0], n)
    dist = rng.choice([100.0, 285.0, 300.0], n)
    speed = rng.choice([0.0, 1.9, 2.0, 8.0], n)
    w1, w2 = rng.integers(-1, 3, n).astype(np.int64), None
    w2 = w1.copy()
    want = _old_lane_change_ready(klane, tlane, lc_lane, phase, stage, 1, vid, set(yv.tolist()), ref_rows, u, xg,
                                  dist, speed, 285.0, 3.0, w1)
    got = lane_change_ready(klane, tlane, lc_lane, phase, stage, 1, vid, yv, ref_rows, u, xg, dist, speed, 285.0,
                            3.0, w2)
    assert _same(got[0], want[0].astype(np.int64)) and _same(got[1], want[1]) and _same(w2, w1)


# ----------------------------------------------------------------------------
# Regrouping._adjusting and ._approach_and_division (their tests and slots
# compiled from stop 41), frozen at b4c2680
def _old_adjusting(self, world, rs) -> None:
    from icv_envs.policies.platoon_common import ST_ADJUSTED

    f = world.fleet
    for sid, S in self.subs.items():
        if S["state"] != "lc":
            continue
        rows = f.rows(S["members"])
        self._swap_crossed_targets(S, f, rows)
        if np.all((f.klane[rows] == f.tlane[rows]) & (f.lc_lane[rows] < 0)):
            S["state"] = "adjusted"
            f.stage[rows] = np.maximum(f.stage[rows], ST_ADJUSTED)
            self._set_sub_targets(world, S)


def _old_approach_and_division(self, world, rs) -> None:
    f = world.fleet
    for fid, F in list(self.formations.items()):
        if F["divided"]:
            continue
        rows = f.rows(F["members"])
        front = rows[np.argmax(rs.u[rows])]
        if rs.dist[front] <= world.layout.R2:
            self._divide(world, rs, F, rows)
            continue
        f.ref[rows] = f.vid[front]
        f.xg[rows] = f.fslot[rows] - f.fslot[front]
        f.ref[front] = -1
        f.xg[front] = 0.0


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 2), ("single-vp", 4000.0, 0)])
def test_regrouping_steps_equal_the_replaced_code_on_runs(monkeypatch, method, throughput, seed):
    """``_adjusting`` and ``_approach_and_division`` (stop 41) against the
    frozen methods, step by step on runs: the same groups, counters and
    fleet fields (the crossed-targets swap and divisions included)."""
    import copy

    from icv_envs.policies.regrouping import Regrouping

    fields = ("ref", "xg", "stage", "tlane", "tidx", "sub")
    seen = {"adjusted": 0, "divisions": 0, "swaps": 0}

    def check(real, old, tally):
        def checked(self, world, rs):
            me2, w2, rs2 = copy.deepcopy((self, world, rs))
            old(me2, w2, rs2)
            real(self, world, rs)
            assert self.subs == me2.subs and self.formations == me2.formations and self.stats == me2.stats
            for name in fields:
                assert _same(getattr(world.fleet, name), getattr(w2.fleet, name)), name
            tally(self)
        return checked

    def t_adj(self):
        seen["adjusted"] = sum(S["state"] == "adjusted" for S in self.subs.values()) + seen["adjusted"]
        seen["swaps"] = self.stats["crossed_targets_swapped"]

    def t_app(self):
        seen["divisions"] = self.stats["divisions"]

    monkeypatch.setattr(Regrouping, "_adjusting", check(Regrouping._adjusting, _old_adjusting, t_adj))
    monkeypatch.setattr(Regrouping, "_approach_and_division",
                        check(Regrouping._approach_and_division, _old_approach_and_division, t_app))
    _drive_intersection(method, throughput, seed, 90.0, 450)
    assert seen["adjusted"] > 0 and seen["divisions"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_approach_fronts_and_lane_change_state_equal_the_array_code(data):
    """``approach_fronts`` and ``lane_change_state`` against the per-group
    array code they replaced, with tied ``u`` (the first maximum is the
    front), fronts on ``R2`` and groups of one."""
    from icv_envs.policies._kernels import approach_fronts, lane_change_state

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(1, 30))
    sizes = []
    left = n
    while left:
        sizes.append(int(rng.integers(1, left + 1)))
        left -= sizes[-1]
    sizes = np.array(sizes, dtype=np.int64)
    rows = rng.permutation(n).astype(np.int64)
    u = rng.integers(-5, 0, n).astype(float)
    dist = rng.choice([200.0, 500.0, 600.0], n)
    vid = rng.permutation(100)[:n].astype(np.int64)
    fslot = rng.integers(0, 5, n) * 6.0
    ref, xg = rng.integers(-1, 50, n).astype(np.int64), rng.normal(size=n)
    ref2, xg2 = ref.copy(), xg.copy()
    start = np.cumsum(sizes) - sizes
    want = np.zeros(len(sizes), dtype=bool)
    for k in range(len(sizes)):
        r = rows[start[k]:start[k] + sizes[k]]
        front = r[np.argmax(u[r])]
        if dist[front] <= 500.0:
            want[k] = True
            continue
        ref[r] = vid[front]
        xg[r] = fslot[r] - fslot[front]
        ref[front] = -1
        xg[front] = 0.0
    got = approach_fronts(rows, sizes, u, dist, 500.0, vid, fslot, ref2, xg2)
    assert _same(got, want) and _same(ref2, ref) and _same(xg2, xg)
    klane, tlane = rng.integers(0, 3, n).astype(np.int64), rng.integers(0, 3, n).astype(np.int64)
    lc_lane = np.where(rng.random(n) < 0.3, rng.integers(0, 3, n), -1).astype(np.int64)
    pend, settled = lane_change_state(rows, sizes, klane, tlane, lc_lane)
    for k in range(len(sizes)):
        r = rows[start[k]:start[k] + sizes[k]]
        assert pend[k] == len(np.flatnonzero((klane[r] != tlane[r]) & (lc_lane[r] < 0)))
        assert settled[k] == np.all((klane[r] == tlane[r]) & (lc_lane[r] < 0))


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_lane_change_progress_equals_the_array_code(data):
    """``lane_change_progress`` (stop 41) against the end of
    ``Regrouping._lane_change_progress`` at b4c2680: the same kept and
    changing lanes, with ends on the curve's end and the 0.4 m band,
    strays on the tolerance, vehicles in the box."""
    from icv_envs.policies._kernels import lane_change_progress

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(1, 25))
    lc_lane = np.where(rng.random(n) < 0.7, rng.integers(0, 3, n), -1).astype(np.int64)
    klane = rng.integers(0, 3, n).astype(np.int64)
    act = np.flatnonzero(lc_lane >= 0).astype(np.int64)
    phase = (rng.random(n) < 0.2).astype(np.int64)
    lane = rng.integers(0, 3, n).astype(np.int64)
    u = rng.integers(-30, -20, n).astype(float)
    lc_u0 = rng.integers(-40, -30, n).astype(float)
    lc_len = rng.choice([5.0, 10.0, 15.0], n)
    lc_lat1 = rng.choice([1.75, 5.25, 0.0], n)  # (0.0: lat_leg - lc_lat1 is exactly 0.4 or -0.4)
    lat_leg = lc_lat1 + rng.choice([0.0, 0.4, -0.4, 0.2, 1.0], n)
    lat_plan = lat_leg[act] + rng.choice([0.0, 0.5, -0.5, 2.0], len(act))
    tol = 0.5
    k1, c1 = klane.copy(), lc_lane.copy()
    entered = phase[act] > 0
    stray = np.abs(lat_plan - lat_leg[act]) > tol
    done = (u[act] >= lc_u0[act] + lc_len[act]) & (np.abs(lat_leg[act] - lc_lat1[act]) < 0.4)
    fin = act[done | entered]
    k1[fin] = c1[fin]
    bad = act[stray & ~done & ~entered]
    k1[bad] = lane[bad]
    c1[fin] = -1
    c1[bad] = -1
    lane_change_progress(act, lat_plan, lat_leg, u, phase, lane, lc_u0, lc_len, lc_lat1, tol, klane, lc_lane)
    assert _same(klane, k1) and _same(lc_lane, c1)


def _old_observation_references(self, world):
    """PlatoonExpert.references at b4c2680 (after its update check)."""
    from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_FREE, MODE_TREE

    f = world.fleet
    rs = world.route()
    has = self._mode != MODE_FREE
    d = np.zeros(f.n)
    k = self._mode == MODE_FOLLOW
    d[k] = self._xref[k] - rs.u[k]
    k = self._mode == MODE_TREE
    d[k] = rs.X[k] - self._xref[k]
    dv = np.where(has, self._vref - f.speed, self.p.v0 - f.speed)
    adv, _, H, v_tree = self._zone_advised
    d[adv] = -H
    dv[adv] = v_tree - f.speed[adv]
    go = (f.node >= 0) & ~self._stop
    return has, d, dv, go


@pytest.mark.parametrize("method,throughput,seed,steps", [("multi-vp", 2600.0, 3, 600), ("fcfs", 2600.0, 5, 300)])
def test_observation_references_equal_the_replaced_array_code_on_runs(monkeypatch, method, throughput, seed, steps):
    """``PlatoonExpert.references`` (stop 41: ``observation_references``)
    against the array code it replaced, on every step of runs (followers,
    tree vehicles, the advisory inside R1; FCFS's plans after it)."""
    from icv_envs.policies.platoon_expert import PlatoonExpert

    real = PlatoonExpert.references
    seen = {"calls": 0, "adv": 0}

    def checked(self, world):
        got = real(self, world)
        want = _old_observation_references(self, world)
        for g, w in zip(got, want):
            assert _same(g, w)
        seen["calls"] += 1
        seen["adv"] += len(self._zone_advised[0])
        return got

    monkeypatch.setattr(PlatoonExpert, "references", checked)
    _drive_intersection(method, throughput, seed, steps / 5.0, steps)
    assert seen["calls"] >= steps, seen
    if method == "multi-vp":
        assert seen["adv"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(sizes=st.lists(st.integers(1, 6), min_size=1, max_size=10), grid=st.booleans(), nan=st.booleans(),
       seed=st.integers(0, 2**32 - 1))
def test_segment_bounds_are_the_reduceat_bounds(sizes, grid, nan, seed):
    """``segment_bounds`` (stop 41, ``Regrouping._sub_distances``) against
    the ``minimum.reduceat`` / ``maximum.reduceat`` pair it replaced: the
    same doubles, signed zeros and NaN included (a NaN stays a NaN)."""
    from icv_envs.policies._kernels import segment_bounds

    rng = np.random.default_rng(seed)
    sizes = np.asarray(sizes, dtype=np.int64)
    m = int(sizes.sum())
    dist = rng.choice([0.0, -0.0, 1.0, 2.0], m + 2) if grid else rng.uniform(0, 300, m + 2)
    if nan:
        dist[rng.integers(0, m + 2)] = np.nan
    rows = rng.integers(0, m + 2, m).astype(np.int64)
    d = dist[rows]
    start = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    want = np.stack([np.minimum.reduceat(d, start), np.maximum.reduceat(d, start)])
    got = segment_bounds(rows, sizes, dist)
    num = ~np.isnan(want)
    assert np.array_equal(np.isnan(got), np.isnan(want)) and got[num].tobytes() == want[num].tobytes()


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_zone_orphans_and_nodes_cleared_equal_the_array_code(data):
    """``zone_orphans`` and ``nodes_cleared`` (stop 41) against the array
    code of ``VirtualPlatoon._coordinate`` they replaced (distances on
    ``R1``, vehicles past the stop line, nodes of one member)."""
    from icv_envs.policies._kernels import nodes_cleared, zone_orphans

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(0, 30))
    R1 = 285.0
    dist = rng.choice([100.0, 285.0, 300.0], n)
    node = np.where(rng.random(n) < 0.4, rng.integers(0, 5, n), -1).astype(np.int64)
    sub = np.where(rng.random(n) < 0.4, rng.integers(0, 5, n), -1).astype(np.int64)
    phase = rng.integers(0, 3, n).astype(np.int64)
    cleared = rng.random(n) < 0.3
    klane, tlane = rng.integers(0, 3, n).astype(np.int64), rng.integers(0, 3, n).astype(np.int64)
    lc_lane = np.where(rng.random(n) < 0.3, rng.integers(0, 3, n), -1).astype(np.int64)
    orphan = np.flatnonzero((dist <= R1) & (node < 0) & (sub < 0) & (phase < 2) & ~cleared)
    if len(orphan):
        orphan = orphan[(klane[orphan] == tlane[orphan]) & (lc_lane[orphan] < 0) | (phase[orphan] > 0)]
    assert _same(zone_orphans(dist, R1, node, sub, phase, cleared, klane, tlane, lc_lane), orphan.astype(np.int64))
    sizes = rng.integers(1, 4, data.draw(st.integers(1, 6))).astype(np.int64)
    rows = rng.integers(0, max(n, 1), int(sizes.sum())).astype(np.int64)
    cl = rng.random(max(n, 1)) < data.draw(st.sampled_from([0.3, 0.9]))
    seg = np.repeat(np.arange(len(sizes)), sizes)
    want = np.bincount(seg, weights=~cl[rows], minlength=len(sizes)) == 0
    assert _same(nodes_cleared(rows, sizes, cl), want)


# ----------------------------------------------------------------------------
# Regrouping._start_lane_changes at b40d6e3 (stop 41), frozen: its gap test
# became policies/_kernels.lane_change_gaps at stop 42
def _old_gap_block(rows, nxt, leg, speed, u_all, dist, vlen, neighbours, p, R1):
    """The array code of the gap test (lengths, gaps, IDM, yields' pairs, the side-by-side drop)."""
    from icv_envs._ufuncs import clip as uclip
    from icv_envs._ufuncs import flatnonzero

    v = speed[rows]
    length = uclip(v * p["lc_duration"], p["lc_min_length"], p["lc_max_length"])
    u = u_all[rows]
    room = -u - p["lc_stop_room"]
    length = np.minimum(length, room)
    ok = length >= p["lc_min_length"] * 0.75
    lr, lc_, fr, fc = neighbours(rows, 3 * leg[rows] + nxt, u)
    ln = vlen[rows]
    gap_f = np.where(lr >= 0, lc_ - u - 0.5 * (vlen[np.maximum(lr, 0)] + ln), np.inf)
    gap_r = np.where(fr >= 0, u - fc - 0.5 * (vlen[np.maximum(fr, 0)] + ln), np.inf)
    vl = np.where(lr >= 0, speed[np.maximum(lr, 0)], v)
    vf = np.where(fr >= 0, speed[np.maximum(fr, 0)], 0.0)
    own = idm_acceleration(v, p["v_max"], gap_f, v - vl, p["a_max"], p["idm_b"], p["member_T"], p["member_s0"],
                           free_term=False)
    fol = idm_acceleration(vf, p["v_max"], gap_r, vf - v, p["a_max"], p["idm_b"], p["member_T"], p["member_s0"],
                           free_term=False)
    possible = ok.copy()
    ok &= (gap_f > p["lc_min_gap"]) & (gap_r > p["lc_min_gap"]) & (own > -p["b_safe"]) & (fol > -p["b_safe"])
    refused = possible & ~ok
    side_r = refused & (fr >= 0) & (gap_r <= p["lc_min_gap"])
    side_f = refused & (lr >= 0) & (gap_f <= p["lc_min_gap"]) & ~side_r
    moving = (dist[rows] > R1) & (speed[rows] >= 2.0)
    yk = flatnonzero((side_r | side_f) & moving)
    yo = np.where(side_r[yk], fr[yk], lr[yk])
    cand = flatnonzero(ok)
    if len(cand) > 1:
        key = 3 * leg[rows[cand]] + nxt[cand]
        o = cand[np.lexsort((-u[cand], key))]
        ko = 3 * leg[rows[o]] + nxt[o]
        close = (ko[1:] == ko[:-1]) & (np.abs(u[o][1:] - u[o][:-1]) < 12.0)
        drop = np.zeros(len(o), dtype=bool)
        for k in flatnonzero(close):
            if not drop[k]:
                drop[k + 1] = True
        ok[o[drop]] = False
    return length, ok, yk, yo


def _gap_params(p) -> dict:
    return {k: getattr(p, k) for k in ("lc_duration", "lc_min_length", "lc_max_length", "lc_stop_room", "v_max",
                                       "a_max", "idm_b", "member_T", "member_s0", "lc_min_gap", "b_safe")}


def _new_gap_block(rows, nxt, leg, speed, u_all, dist, vlen, cor, p, R1):
    from icv_envs.policies._kernels import lane_change_gaps

    return lane_change_gaps(rows, nxt, leg, speed, u_all, dist, vlen, cor.keys, cor.corr, cor.rows, cor.coord,
                            float(cor.BIG), float(p["lc_duration"]), float(p["lc_min_length"]),
                            float(p["lc_max_length"]), float(p["lc_stop_room"]), float(p["lc_min_length"] * 0.75),
                            float(p["lc_min_gap"]), float(p["b_safe"]), float(p["a_max"]),
                            float(2.0 * np.sqrt(p["a_max"] * p["idm_b"])), float(p["member_T"]),
                            float(p["member_s0"]), float(R1))


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 2), ("single-vp", 3500.0, 0),
                                                    ("fcfs", 2600.0, 5)])
def test_lane_change_gaps_equal_the_replaced_array_code_on_runs(monkeypatch, method, throughput, seed):
    """``lane_change_gaps`` (stop 42) against the frozen array block on every
    call of ``_start_lane_changes`` with ready vehicles on runs: the same
    lengths, accepted changes and yield pairs; the runs reach refusals,
    yields and dropped side-by-side starts."""
    import icv_envs.policies.lane_changes_regrouping as RG  # (its module since stop 47)

    real = RG.lane_change_gaps
    seen = {"calls": 0, "refused": 0, "yields": 0, "started": 0}

    def checked(rows, nxt, leg, speed, u, dist, vlen, keys, corr, crow, coord, big, *rest):
        out = real(rows, nxt, leg, speed, u, dist, vlen, keys, corr, crow, coord, big, *rest)
        from icv_envs.policies.platoon_common import Corridors

        cor = Corridors.__new__(Corridors)
        cor.keys, cor.corr, cor.rows, cor.coord = keys, corr, crow, coord
        (lcd, lmin, lmax, stop_room, _, min_gap, b_safe, a_max, _, mT, ms0, R1) = rest
        # (a_max and idm_b back from the expert's params; the kernel takes 2 sqrt(a_max b))
        p = {"lc_duration": lcd, "lc_min_length": lmin, "lc_max_length": lmax, "lc_stop_room": stop_room,
             "v_max": 0.0, "a_max": a_max, "idm_b": params.idm_b, "member_T": mT, "member_s0": ms0,
             "lc_min_gap": min_gap, "b_safe": b_safe}
        ref = _old_gap_block(rows, nxt, leg, speed, u, dist, vlen, cor.neighbours, p, R1)
        for a, b in zip(out, ref):
            assert _same(np.asarray(a), np.asarray(b, dtype=np.asarray(a).dtype))
        seen["calls"] += 1
        seen["refused"] += int(np.count_nonzero(~out[1]))
        seen["yields"] += len(out[2])
        seen["started"] += int(np.count_nonzero(out[1]))
        return out

    from icv_envs.policies.platoon_expert import PlatoonParams

    params = PlatoonParams()
    monkeypatch.setattr(RG, "lane_change_gaps", checked)
    _drive_intersection(method, throughput, seed, 120.0, 600)
    assert seen["calls"] > 20 and seen["refused"] > 0 and seen["started"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_lane_change_gaps_equal_the_array_code(data):
    """``lane_change_gaps`` against the frozen array block on random states
    pushed onto its boundaries: lengths at the clip's and the room's
    bounds, gaps at ``lc_min_gap``, vehicles side by side in one corridor
    at 12 m and closer (ties in ``u``), leaders and followers missing."""
    from icv_envs.policies.platoon_common import Corridors

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(1, 14))
    leg = rng.integers(0, 2, n).astype(np.int64)
    lane = rng.integers(0, 3, n).astype(np.int64)
    u = -rng.choice([20.0, 25.0, 30.0, 37.0, 42.0, 80.0, 300.0], n) - rng.choice([0.0, 0.0, 4.0, 12.0, 6.5], n)
    speed = rng.choice([0.0, 1.0, 2.0, 4.0, 10.0, 15.0], n)
    vlen = rng.choice([4.0, 5.0], n)
    dist = -u + 10.0
    # a plain corridor index of these vehicles: each listed in its lane at u
    corr = 3 * leg + lane
    order = np.lexsort((np.arange(n), u, corr))
    cor = Corridors.__new__(Corridors)
    cor.rows = order.astype(np.int64)
    cor.corr = corr[order].astype(np.int64)
    cor.coord = u[order].astype(np.float64)
    cor.keys = cor.corr * Corridors.BIG + cor.coord
    k = data.draw(st.integers(1, n))
    rows = np.sort(rng.choice(n, k, replace=False)).astype(np.int64)
    nxt = np.clip(lane[rows] + rng.choice([-1, 1], k), 0, 2).astype(np.int64)
    p = {"lc_duration": 3.0, "lc_min_length": 20.0, "lc_max_length": 40.0, "lc_stop_room": 10.0, "v_max": 15.0,
         "a_max": 3.0, "idm_b": 2.0, "member_T": 0.6, "member_s0": 2.0,
         "lc_min_gap": float(data.draw(st.sampled_from([1.0, 3.0, 4.0]))), "b_safe": 4.0}
    R1 = float(data.draw(st.sampled_from([30.0, 285.0])))
    got = _new_gap_block(rows, nxt, leg, speed, u, dist, vlen, cor, p, R1)
    ref = _old_gap_block(rows, nxt, leg, speed, u, dist, vlen, cor.neighbours, p, R1)
    for a, b in zip(got, ref):
        assert _same(np.asarray(a), np.asarray(b, dtype=np.asarray(a).dtype))


def _old_merging(self, world, rs) -> None:
    """Regrouping._merging at b40d6e3 (stop 41), frozen: its loop became
    policies/_kernels.merge_pairs at stop 42."""
    p = self.p
    f = world.fleet
    lay = world.layout
    if not self.subs:
        return
    sids, subs, dmin, dmax = self._sub_distances(f, rs)
    info = [(sid, S["leg"], S["mv"], a, b, S["state"]) for sid, S, a, b in zip(sids, subs, dmin, dmax)]
    info.sort(key=lambda t: (t[1], t[3]))
    merged = set()
    for i, (sa, leg, mv, xa0, xa1, st) in enumerate(info):
        if st != "adjusted" or sa in merged or xa0 <= lay.R1:
            continue
        A = self.subs[sa]
        for sb, legb, mvb, xb0, xb1, stb in info[i + 1:]:
            if legb != leg:
                break
            if sb in merged:
                continue
            if mvb != mv:
                if lay.conflict[mv, mvb]:
                    break
                continue
            B = self.subs[sb]
            if stb == "adjusted" and xb0 > lay.R1 and xb0 - xa1 <= p.merge_range \
                    and len(A["members"]) + len(B["members"]) <= p.max_node_size:
                self._merge(world, rs, A, B)
                merged.add(sb)
                xa1 = max(xa1, xb1)
            else:
                break


@pytest.mark.parametrize("method,throughput,seed", [("multi-vp", 3000.0, 2), ("multi-vp", 2200.0, 7)])
def test_merging_equals_the_replaced_code_on_runs(monkeypatch, method, throughput, seed):
    """``_merging`` (stop 42: ``merge_pairs``) against the frozen method,
    step by step on runs: the same groups, counters and fleet fields; the
    runs reach merges (several into one taker included)."""
    import copy

    from icv_envs.policies.regrouping import Regrouping

    real = Regrouping._merging
    fields = ("ref", "xg", "stage", "tlane", "tidx", "sub", "form")
    seen = {"merges": 0}

    def checked(self, world, rs):
        me2, w2, rs2 = copy.deepcopy((self, world, rs))
        _old_merging(me2, w2, rs2)
        real(self, world, rs)
        assert self.subs == me2.subs and self.stats == me2.stats
        for name in fields:
            assert _same(getattr(world.fleet, name), getattr(w2.fleet, name)), name
        seen["merges"] = self.stats["merges"]

    monkeypatch.setattr(Regrouping, "_merging", checked)
    _drive_intersection(method, throughput, seed, 150.0, 750)
    assert seen["merges"] > 0, seen


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_merge_pairs_equal_the_replaced_loop(data):
    """``merge_pairs`` against the frozen loop on random sub-formations:
    ties in the least distance, distances at ``R1`` and at ``merge_range``
    from the rear, sizes at ``max_node_size``, conflicting and
    non-conflicting movements between them."""
    from icv_envs.policies._kernels import merge_pairs

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    K = data.draw(st.integers(0, 12))
    leg = rng.integers(0, 2, K).astype(np.int64)
    mv = (3 * leg + rng.integers(0, 3, K)).astype(np.int64)
    dmin = rng.choice([100.0, 150.0, 160.0, 200.0, 210.0, 260.0], K)
    dmax = dmin + rng.choice([0.0, 10.0, 50.0], K)
    adjusted = rng.random(K) < 0.8
    size = rng.integers(1, 8, K).astype(np.int64)
    conflict = rng.random((12, 12)) < 0.5
    R1, rng_m, cap = 150.0, 50.0, 10
    # the loop, frozen (ids = positions)
    info = [(k, int(leg[k]), int(mv[k]), float(dmin[k]), float(dmax[k]), bool(adjusted[k])) for k in range(K)]
    info.sort(key=lambda t: (t[1], t[3]))
    sizes = size.tolist()
    merged, want = set(), []
    for i, (sa, lg, m, xa0, xa1, st_) in enumerate(info):
        if not st_ or sa in merged or xa0 <= R1:
            continue
        for sb, legb, mvb, xb0, xb1, stb in info[i + 1:]:
            if legb != lg:
                break
            if sb in merged:
                continue
            if mvb != m:
                if conflict[m, mvb]:
                    break
                continue
            if stb and xb0 > R1 and xb0 - xa1 <= rng_m and sizes[sa] + sizes[sb] <= cap:
                want.append((sa, sb))
                sizes[sa] += sizes[sb]
                merged.add(sb)
                xa1 = max(xa1, xb1)
            else:
                break
    got = merge_pairs(leg, mv, dmin, dmax, adjusted, size, conflict, R1, rng_m, cap)
    assert [tuple(x) for x in got.tolist()] == want


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_stuck_in_zone_equals_the_array_expression(data):
    """``stuck_in_zone`` (stop 42) against ``_reroute_stuck``'s array
    expression at b40d6e3: distances at ``R1``, every flag on and off."""
    from icv_envs.policies._kernels import stuck_in_zone

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    n = data.draw(st.integers(0, 30))
    phase = rng.integers(0, 3, n).astype(np.int64)
    lc_lane = rng.integers(-1, 3, n).astype(np.int64)
    R1 = 285.0
    dist = rng.choice([100.0, 285.0, np.nextafter(285.0, np.inf), 400.0], n)
    co = rng.random(n) < 0.3
    klane = rng.integers(0, 3, n).astype(np.int64)
    tlane = rng.integers(0, 3, n).astype(np.int64)
    want = np.flatnonzero((phase == 0) & (lc_lane < 0) & (dist <= R1) & ~co & (klane != tlane))
    assert _same(stuck_in_zone(phase, lc_lane, dist, R1, co, klane, tlane), want)


def _old_reroute_stuck(self, world, rs):
    """PlatoonExpert._reroute_stuck at b40d6e3 (stop 41), frozen."""
    from icv_envs._ufuncs import clip as uclip
    from icv_envs._ufuncs import flatnonzero

    f = world.fleet
    lay = world.layout
    stuck = ((rs.phase == 0) & (f.lc_lane < 0) & (rs.dist <= lay.R1) & ~self._coordinated(f)
             & (f.klane != f.tlane))
    if not np.count_nonzero(stuck):
        return rs
    served = lay.allowed[f.mv, uclip(f.klane, 0, 2)]
    keep = flatnonzero(stuck & served)
    if len(keep):
        f.tlane[keep] = f.klane[keep]
        f.want[keep] = -1
        self.stats["kept_lane_in_R1"] += len(keep)
    k = flatnonzero(stuck & ~served)
    if not len(k):
        return rs
    lane = uclip(f.klane[k], 0, 2)
    new = np.full(len(k), -1, dtype=np.int64)
    for turn in (1, 0, 2):
        m = 3 * f.leg[k] + turn
        ok = (new < 0) & lay.allowed[m, lane]
        new[ok] = m[ok]
    k, new = k[new >= 0], new[new >= 0]
    if len(k):
        world.reroute(k, new)
        f.tlane[k] = f.klane[k]
        f.want[k] = -1
        gone = set(f.vid[k].tolist())
        self._keep_members(lambda v: v not in gone, (self.formations, self.subs))
        f.sub[k] = -1
        f.ref[k] = -1
        f.xg[k] = 0.0
        rs = world.route()
    return rs


@pytest.mark.parametrize("method,throughput,seed", [("single-vp", 3000.0, 0), ("fcfs", 3000.0, 0)])
def test_reroute_stuck_equals_the_replaced_code_on_runs(monkeypatch, method, throughput, seed):
    """``_reroute_stuck`` (stop 42: ``stuck_in_zone``) against the frozen
    method, step by step on the runs where it once locked the intersection
    up (its docstring): the same fleet, groups and counters, lane keeping
    and rerouting reached."""
    import copy

    from icv_envs.policies.platoon_expert import PlatoonExpert

    real = PlatoonExpert._reroute_stuck
    seen = {"kept": 0, "rerouted": 0}

    def checked(self, world, rs):
        me2, w2, rs2 = copy.deepcopy((self, world, rs))
        _old_reroute_stuck(me2, w2, rs2)
        out = real(self, world, rs)
        assert self.stats == me2.stats and self.subs == me2.subs and self.formations == me2.formations
        for name in ("vid", *world.fleet._fields):
            assert _same(getattr(world.fleet, name), getattr(w2.fleet, name)), name
        seen["kept"] = self.stats["kept_lane_in_R1"]
        seen["rerouted"] = world.stats.get("rerouted", seen["rerouted"])
        return out

    monkeypatch.setattr(PlatoonExpert, "_reroute_stuck", checked)
    _drive_intersection(method, throughput, seed, 120.0, 600)
    assert seen["kept"] > 0 and seen["rerouted"] > 0, seen
