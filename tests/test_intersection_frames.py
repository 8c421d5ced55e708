"""The intersection world's compiled frames (``IntersectionWorld.substeps``,
:func:`icv_envs.sim._kernels.intersection_frames`) against the per-frame
``substep`` they replaced, frozen here as the oracle: the same runs, step by
step, with the same state, statistics, run metrics (motion, PET, jam watch,
faults), collision log and PettingZoo outputs, bit for bit; expert-driven,
with random drivers (collisions, wrong exits) and with drivers that stand
(the jam watch's queue test); and its compiled route coordinates
(``IntersectionWorld.route``, :func:`icv_envs.sim._kernels.intersection.route_rows`)
against the array code they replaced."""

from __future__ import annotations

import types

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.platoon.geometry import N_LANES
from icv_envs.sim._kernels.intersection import intersection_events
from icv_envs.sim.intersection_metrics import collision_fault
from icv_envs.sim.intersection_world import _OFFROAD_MARGIN, _OUT
from icv_envs.sim.traffic import bicycle_step
from pinned_numpy import at_pinned_level


def _frozen_substep(self, accel, steer, events) -> None:
    """``IntersectionWorld.substep`` as it was before the frames were compiled (the oracle)."""
    f = self.fleet
    lay = self.layout
    v_before = f.speed.copy()
    if f.n:
        a = np.where(f.crashed, -6.0, accel)
        st = np.where(f.crashed, 0.0, steer)
        f.x, f.y, f.heading, f.speed = bicycle_step(f.x, f.y, f.heading, f.speed, a, st, self.dt,
                                                    self.wheelbase, self.v_max)
        f.accel = np.asarray(a, dtype=np.float64)
        f.steer = np.asarray(st, dtype=np.float64)
    self.time += self.dt
    self.step_count += 1
    self._route = None
    if not f.n:
        return
    stt = self.stats
    stt["vehicle_steps"] += f.n
    stt["speed_sum"] += float(f.speed.sum())
    stt["abs_accel_sum"] += float(np.abs(f.accel).sum())
    self.motion.record(f.vid, v_before, f.speed, f.accel, self.dt)
    cx, cy = self.centers()
    b = lay.box_half
    (u, lat_leg, crash, new_wrong, clear_now, removed, left, pet_rows, pet_pid, pet_s, pet_arc,
     min_box) = intersection_events(
        cx, cy, f.speed, f.leg, f.mv, f.length, f.crashed, f.tlane, f.entered, f.departed, f.cleared,
        f.wrong_exit, f.exit_leg, f.plane, f.enter_time, _OUT, lay.app_dir, lay.app_right, lay.dep_right,
        lay.exit_of, b, lay.lane_width, N_LANES, _OFFROAD_MARGIN, -(lay.R3 - b + 50.0),
        lay.departure_length, self.time, lay.P0, lay.D0, lay.P1, lay.D1, lay.L, lay.arc)
    if new_wrong.any():
        stt["wrong_exits"] += int(new_wrong.sum())
        events.wrong_exit.update(int(v) for v in f.vid[new_wrong])
    if clear_now.any():
        kc = np.flatnonzero(clear_now)
        good = kc[~f.wrong_exit[kc]]
        stt["cleared"] += len(good)
        if len(good):
            pid = 3 * f.mv[good] + np.maximum(f.plane[good], 0)
            dist = -f.spawn_s[good] + lay.L[pid] + 0.5 * f.length[good]
            tt = self.time - f.spawn_time[good]
            stt["travel_time_sum"] += float(tt.sum())
            stt["delay_sum"] += float((tt - dist / self.v_free).sum())
        events.cleared.update(int(v) for v in f.vid[kc])
    stt["min_speed_in_box"] = min(stt["min_speed_in_box"], min_box)
    if pet_arc.any():
        k = np.flatnonzero(pet_arc)
        pet_s[k] = lay.arc_project(pet_pid[k], cx[pet_rows[k]], cy[pet_rows[k]])[0]
    self.pet.record(self.time, f.vid[pet_rows], pet_pid, pet_s, f.length[pet_rows])
    self.jams.record(self.time, self.dt, f.vid, f.speed, lambda rows: self._in_queue(rows, u, lat_leg),
                     dist=self.layout.box_half - u)
    i, j = self.collision_pairs(cx, cy)
    if len(i):
        crash[i] = True
        crash[j] = True
        ev = self._expert_vids
        for ra, rb in zip(i.tolist(), j.tolist()):
            a_, b_ = int(f.vid[ra]), int(f.vid[rb])
            events.collision_pairs.append((a_, b_))
            self.collision_log.append((round(self.time, 6), a_, b_))
            if not (f.crashed[ra] and f.crashed[rb]):
                kind, k = collision_fault(cx[ra], cy[ra], f.heading[ra], f.speed[ra],
                                          cx[rb], cy[rb], f.heading[rb], f.speed[rb])
                guilty = (a_, b_)[k]
                self.faults.record(kind, ev is None or guilty in ev)
    new_crash = crash & ~f.crashed
    if new_crash.any():
        f.crashed = f.crashed | new_crash
        events.crashed.update(int(v) for v in f.vid[new_crash])
        stt["collisions"] += int(new_crash.sum())
    gone = (removed | left) & ~f.crashed
    if gone.any():
        events.removed.update(int(v) for v in f.vid[removed & gone])
        events.left_road.update(int(v) for v in f.vid[left & gone])
        stt["removed"] += int((removed & gone).sum())
        stt["left_road"] += int((left & gone).sum())
        f.remove(gone)


def _state(env) -> dict:
    """Everything the frames touch, as exact values."""
    w = env.core.world
    f = w.fleet
    m, pet, jams = w.motion, w.pet, w.jams
    n_ids = f.next_vid

    def ids(a):  # per-id tables (their spare length is not state)
        a = np.asarray(a)[:n_ids]
        return np.concatenate([a, np.zeros((n_ids - len(a),) + a.shape[1:], dtype=a.dtype)])

    out = {name: getattr(f, name).copy() for name in ["vid", *f._fields]}
    out.update(time=w.time, step_count=w.step_count, stats=dict(w.stats), collision_log=list(w.collision_log),
               faults=w.faults.summary(),
               motion=(m.vehicle_steps, m.speed_sum, m.realised_abs_accel_sum, m.commanded_abs_accel_sum,
                       m.stopped_steps, ids(m._n), ids(m._s1), ids(m._s2)),
               pet=(list(pet.samples), pet.last_exit.copy(), pet.inside.copy(),
                    {k: list(v) for k, v in pet.pending.items()}, ids(pet._occ), ids(pet._pid), pet._busy.copy()),
               jams=(set(jams.ever), list(jams.log), jams.jammed_seconds, ids(jams._stopped_for)))
    return out


def _equal(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    if isinstance(a, float) and a != a:
        return b != b and type(a) is type(b)
    return type(a) is type(b) and a == b


def _actions(env, rng, driver: str) -> dict:
    ex = env.expert_actions()
    if driver == "expert":
        return ex
    if driver == "random":  # a third of the agents brake and steer at random: collisions, wrong exits
        return {a: (rng.uniform(-1, 1, 2).astype(np.float32) if int(a[4:]) % 3 == 0 else ex[a]) for a in env.agents}
    # "stand": every seventh agent brakes to a stop and stands (the jam watch's queue test)
    return {a: (np.array([-1.0, 0.0], dtype=np.float32) if int(a[4:]) % 7 == 0 else ex[a]) for a in env.agents}


@pytest.mark.parametrize("method,throughput,seed,driver", [
    ("multi-vp", 2500.0, 3, "expert"),
    ("multi-vp", 3000.0, 0, "random"),
    ("fcfs", 2000.0, 1, "stand"),
])
@at_pinned_level  # libm's trigonometry against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
def test_compiled_frames_equal_the_frozen_substep(method, throughput, seed, driver):
    envs = []
    for fused in (True, False):
        env = parallel_env(method=method, throughput=throughput, duration=140.0, missing_action="expert")
        env.reset(seed=seed)
        w = env.core.world
        if not fused:  # one frame at a time through the frozen substep
            w.substeps = None
            w.substep = types.MethodType(_frozen_substep, w)
        envs.append(env)
    rng = [np.random.default_rng(seed), np.random.default_rng(seed)]
    calls = {"judge": 0}
    jw = envs[0].core.world.jams
    judge = jw.judge

    def counted(*a, **k):
        calls["judge"] += 1
        return judge(*a, **k)

    jw.judge = counted
    steps = 0
    while not envs[0].episode_over:
        outs = [env.step(_actions(env, r, driver)) for env, r in zip(envs, rng)]
        steps += 1
        for x, y in zip(outs[0][:4], outs[1][:4]):
            assert x.keys() == y.keys()
            assert all(_equal(np.asarray(x[k]), np.asarray(y[k])) for k in x), steps
        a, b = _state(envs[0]), _state(envs[1])
        bad = [k for k in a if not _equal(a[k], b[k])]
        assert not bad, (steps, bad)
    assert envs[1].episode_over and steps == 700
    st = envs[0].core.world.stats
    assert st["cleared"] > 0 and st["removed"] > 0 and envs[0].core.world.pet.samples
    if driver == "random":
        assert st["collisions"] > 0 and envs[0].core.world.collision_log
    if driver == "stand":
        assert calls["judge"] > 0


def test_substeps_refuses_bad_controls():
    env = parallel_env(method="multi-vp", throughput=2500.0, duration=20.0)
    env.reset(seed=0)
    w = env.core.world
    n = w.fleet.n
    assert n > 0
    with pytest.raises(ValueError, match=r"accel and steer must have shape"):
        w.substeps(np.zeros(n + 1), np.zeros(n), 2, env.core._new_events())
    with pytest.raises(ValueError, match=r"n = 0; allowed"):
        w.substeps(np.zeros(n), np.zeros(n), 0, env.core._new_events())


def _frozen_route(w) -> dict:
    """``IntersectionWorld.route`` as array code (before it was compiled)."""
    from icv_envs.sim.intersection_world import _OUT

    f = w.fleet
    lay = w.layout
    h = 0.5 * w.wheelbase
    cx, cy = f.x + h * np.cos(f.heading), f.y + h * np.sin(f.heading)
    leg = f.leg
    ox = lay.box_half * _OUT[leg, 0]
    oy = lay.box_half * _OUT[leg, 1]
    d = lay.app_dir[leg]
    r = lay.app_right[leg]
    u = (cx - ox) * d[:, 0] + (cy - oy) * d[:, 1]
    lat_leg = (cx - ox) * r[:, 0] + (cy - oy) * r[:, 1]
    lane = np.clip(np.floor(lat_leg / lay.lane_width), 0, N_LANES - 1).astype(np.int64)
    phase = np.where(f.departed, 2, np.where(f.entered, 1, 0))
    plane = np.where(f.plane >= 0, f.plane, f.tlane)
    pid = 3 * f.mv + plane
    s, lat = lay.project(pid, cx, cy, phase)
    L = lay.L[pid]
    return dict(cx=cx, cy=cy, u=u, lat_leg=lat_leg, lane=lane, pid=pid, s=s, lat=lat, X=0.5 * L - s,
                dist=lay.box_half - s, phase=phase, L=L)


@pytest.mark.parametrize("method,seed", [("multi-vp", 5), ("fcfs", 6)])
@at_pinned_level  # libm's arctan2 against NumPy's: exact at AVX2 (tests/pinned_numpy.py)
def test_compiled_route_equals_the_array_code(method, seed):
    """``IntersectionWorld.route`` (compiled: ``route_rows``) against the array
    code it replaced, on every state of a run with a third of the drivers at
    random (vehicles off their lanes, on the turn arcs, departed)."""
    env = parallel_env(method=method, throughput=3000.0, duration=150.0, missing_action="expert")
    env.reset(seed=seed)
    core = env.core
    w = core.world
    rng = np.random.default_rng(seed)
    seen = {0: 0, 1: 0, 2: 0}
    while not env.episode_over:
        w.invalidate()
        rs = w.route()
        want = _frozen_route(w)
        for k, v in want.items():
            got = getattr(rs, k)
            assert got.dtype == v.dtype and np.array_equal(got, v), k
        for ph in seen:
            seen[ph] += int((rs.phase == ph).sum())
        acts = core.expert_actions().copy()  # (read-only from stop 45: this test mutated the env's cache)
        rand = rng.random(len(acts)) < 0.3
        acts[rand] = rng.uniform(-1.0, 1.0, (int(rand.sum()), 2))
        env.step(dict(zip(env.agents, acts.astype(np.float32))))
    assert min(seen.values()) > 200, seen
