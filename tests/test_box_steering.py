"""The intersection expert's compiled steering
(:func:`icv_envs.policies._kernels.box_steering`, behind
``PlatoonControl._steering``) against the array code it replaced, frozen here
as the oracle, on the states of real runs: every method, expert-driven and
with random drivers (vehicles off their lane, at odd headings, standing), bit
for bit."""

from __future__ import annotations

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.formation.bezier import _lane_change_lateral, _pure_pursuit_steering


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
        acts = core.expert_actions()
        rand = rng.random(len(acts)) < random_share
        acts[rand] = rng.uniform(-1.0, 1.0, (int(rand.sum()), 2))
        obs, rew, term, trunc, infos = env.step(dict(zip(env.agents, acts.astype(np.float32))))
    assert checked > 5000 and arcs > 40 and departed > 200 and lane_changes > 300
