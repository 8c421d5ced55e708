"""Action and observation types (config["action"/"observation"]["type"]):
every type passes Gymnasium's and SB3's check_env and PettingZoo's
parallel_api_test, api_test, seed tests and max_cycles_test (through the
slot layout on the open roads, whose raw modules cannot pass the test's
"median agent alive" check), does what it says, and rejects bad input."""

from __future__ import annotations

import math
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import given, settings
from hypothesis import strategies as st
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, seed_test

from icv_envs import highway_formation_v0, highway_ramps_v0, intersection_v0
from icv_envs.rl import slots

ENVS = {
    "highway_formation": (highway_formation_v0, "icv_envs/HighwayFormation-v0", {"scenario": "on-ramp", "duration": 4.0}),
    "highway_ramps": (highway_ramps_v0, "icv_envs/HighwayRamps-v0", {"duration": 4.0}),
    "intersection": (intersection_v0, "icv_envs/Intersection-v0", {"duration": 4.0}),
}
TYPES = {
    "continuous": ({"type": "ContinuousAction"}, {"type": "Kinematics"}),
    "meta": ({"type": "DiscreteMetaAction"}, {"type": "Kinematics"}),
    "residual": ({"type": "FormationResidual", "bound": [0.2, 0.1]}, {"type": "Kinematics"}),
    "kinematics-options": ({"type": "ContinuousAction"},
                           {"type": "Kinematics", "features": ["presence", "x", "y", "vx"], "vehicles_count": 5,
                            "absolute": True, "normalize": False}),
    "grid": ({"type": "DiscreteMetaAction"}, {"type": "OccupancyGrid", "align_to_vehicle_axes": True}),
}


def _cfg(env, kind):
    mod, gid, cfg = ENVS[env]
    act, obs = TYPES[kind]
    return mod, gid, dict(cfg, action=act, observation=obs)


@pytest.mark.parametrize("kind", list(TYPES))
@pytest.mark.parametrize("env", list(ENVS))
def test_checkers(env, kind):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    mod, gid, cfg = _cfg(env, kind)
    g = gym.make(gid, config=cfg)
    check_env(g.unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(gid, config=cfg).unwrapped, warn=False)
    parallel_api_test(mod.parallel_env(**cfg), num_cycles=15)
    api_test(mod.env(**cfg), num_cycles=8)
    parallel_seed_test(lambda: mod.parallel_env(**cfg), num_cycles=10)
    seed_test(lambda: mod.env(**cfg), num_cycles=5)
    max_cycles_test(slots.module(mod.__name__, cfg))


def test_max_cycles_raw_modules():
    """PettingZoo's max_cycles on the raw modules: exactly max_cycles steps,
    then every agent truncated and the episode over (PettingZoo's test itself
    passes on the highway-formation module, where every agent is alive)."""
    cfg = {"scenario": "lane-drop", "action": {"type": "DiscreteMetaAction"}}
    max_cycles_test(SimpleNamespace(parallel_env=lambda max_cycles=None: highway_formation_v0.parallel_env(
        max_cycles=max_cycles, **cfg), env=lambda max_cycles=None: highway_formation_v0.env(max_cycles=max_cycles, **cfg)))
    for mod in (highway_ramps_v0, intersection_v0):
        p = mod.parallel_env(max_cycles=3, missing_action="expert")
        p.reset(seed=0)
        for k in range(3):
            obs, rew, term, trunc, info = p.step({})
        assert all(trunc[a] or term[a] for a in obs) and not p.agents and p.episode_over
    with pytest.raises(ValueError, match="max_cycles"):
        highway_formation_v0.parallel_env(max_cycles=0)


def test_spaces_built_once_and_shared():
    env = intersection_v0.parallel_env(action={"type": "DiscreteMetaAction"}, observation={"type": "OccupancyGrid"})
    o, a = env.observation_space("icv_0"), env.action_space("icv_0")
    env.reset(seed=0)
    env.reset(seed=1)
    assert env.core.observation_space is o and env.core.action_space is a
    assert isinstance(a, gym.spaces.Discrete) and a.n == 5
    assert o.shape == (3, 11, 11) and o.dtype == np.float32
    g = gym.make("icv_envs/HighwayFormation-v0", config={"observation": {"normalize": False}})
    sp = g.observation_space
    obs, _ = g.reset(seed=0)
    g.reset(seed=1)
    assert g.observation_space is sp and obs.dtype == np.float32 and np.isinf(sp.high).all()


def test_kinematics_options_are_views_of_the_full_layout():
    full = highway_formation_v0.parallel_env(scenario="lane-drop")
    sub = highway_formation_v0.parallel_env(scenario="lane-drop", observation={"features": ["vx", "presence", "x"]})
    raw = highway_formation_v0.parallel_env(scenario="lane-drop", observation={"normalize": False, "absolute": True})
    of, _ = full.reset(seed=3)
    osub, _ = sub.reset(seed=3)
    oraw, _ = raw.reset(seed=3)
    a = "icv_2"
    np.testing.assert_array_equal(osub[a], of[a][:, [3, 0, 1]])
    core = raw.core
    F = core._features()
    r = int(np.searchsorted(core.world.traffic.vid, 2))
    np.testing.assert_allclose(oraw[a][0], F[r].astype(np.float32))
    # absolute rows of the others are the other vehicles' own features
    for row in oraw[a][1:]:
        if row[0] == 1:
            j = int(np.argmin(np.abs(F[:, 1] - row[1]) + np.abs(F[:, 2] - row[2])))
            np.testing.assert_allclose(row, F[j].astype(np.float32), rtol=1e-6)


def test_occupancy_grid_cells():
    env = highway_formation_v0.parallel_env(scenario="free", vehicles_count=4, lanes_count=2,
                                            observation={"type": "OccupancyGrid", "features": ["presence", "vx"],
                                                         "grid_size": [[-50, 50], [-6, 6]], "grid_step": [5, 4]})
    obs, _ = env.reset(seed=0)
    core = env.core
    F = core._features()
    for i, vid in enumerate(core.world.traffic.vid):
        g = obs[f"icv_{vid}"]
        assert g.shape == (2, 20, 3)
        # the observer in its own cell (dx = 0 -> column 10, dy = 0 -> row 1), relative vx 0
        assert g[0, 10, 1] == 1 and g[1, 10, 1] == 0
        # every other vehicle in range sits in the cell of its offset
        for j in range(len(F)):
            dx, dy = F[j, 1] - F[i, 1], F[j, 2] - F[i, 2]
            ix, iy = math.floor((dx + 50) / 5), math.floor((dy + 6) / 4)
            if 0 <= ix < 20 and 0 <= iy < 3:
                assert g[0, ix, iy] == 1
        assert g[0].sum() <= len(F)


def test_residual_zero_is_the_expert():
    """FormationResidual with r = 0 reproduces the expert bit for bit."""
    res = highway_formation_v0.parallel_env(scenario="lane-drop", action={"type": "FormationResidual"})
    exp = highway_formation_v0.parallel_env(scenario="lane-drop", missing_action="expert")
    o1, _ = res.reset(seed=1)
    o2, _ = exp.reset(seed=1)
    for _ in range(25):
        o1, r1, *_ = res.step({a: np.zeros(2, np.float32) for a in res.agents})
        o2, r2, *_ = exp.step({})
        assert r1 == r2
        for a in o1:
            np.testing.assert_array_equal(o1[a], o2[a])
    # a correction changes the applied control by bound * r
    ex = res.core.expert_actions().astype(np.float64).copy()
    n = res.core.world.traffic.n
    res.step({a: np.array([1.0, -1.0], np.float32) for a in res.agents})
    assert res.core.world.traffic.n == n
    np.testing.assert_allclose(res.core._last_actions, np.clip(ex + [0.25, -0.25], -1, 1))


def test_meta_actions_change_lane_and_speed():
    env = highway_formation_v0.parallel_env(scenario="free", vehicles_count=1, lanes_count=3, missing_action="expert",
                                            action={"type": "DiscreteMetaAction", "target_speeds": [20, 25, 30]})
    env.reset(seed=0)
    core = env.core
    tr = core.world.traffic
    lane0 = int(core.world.road.lane_of(tr.center()[1])[0])
    side = -1 if lane0 > 0 else 1
    first = 0 if side < 0 else 2  # LANE_LEFT lowers the lane index, LANE_RIGHT raises it
    env.step({"icv_0": first})
    env.step({"icv_0": 3})  # FASTER: 25 -> 30 m/s
    for _ in range(40):
        env.step({"icv_0": 1})
    lane = int(core.world.road.lane_of(tr.center()[1])[0])
    assert lane == lane0 + side
    assert abs(tr.y[0] - lane * core.world.road.lane_width) < 0.3 and abs(tr.heading[0]) < 0.02
    assert abs(tr.speed[0] - 30.0) < 0.5
    for _ in range(2):
        env.step({"icv_0": 4})  # SLOWER twice: 20 m/s
    for _ in range(40):
        env.step({"icv_0": 1})
    assert abs(tr.speed[0] - 20.0) < 0.5
    # no lane beyond the edge: the request is ignored
    edge = highway_formation_v0.parallel_env(scenario="free", vehicles_count=1, lanes_count=1, missing_action="expert",
                                             action={"type": "DiscreteMetaAction"})
    edge.reset(seed=0)
    for _ in range(20):
        edge.step({"icv_0": 0})
    assert abs(edge.core.world.traffic.y[0]) < 0.05


def test_meta_actions_at_the_intersection_keep_the_road():
    """IDLE meta actions follow the approach lane, the path through the box
    and the departure lane: vehicles exit on their movement's leg."""
    env = intersection_v0.parallel_env(duration=110.0, throughput=300.0, action={"type": "DiscreteMetaAction"})
    env.reset(seed=0)
    wrong = crashed = exited = 0
    while env.agents:
        obs, rew, term, trunc, info = env.step({a: 1 for a in env.agents})
        wrong += sum(bool(i.get("wrong_exit")) for i in info.values())
        exited += sum(bool(i.get("exited")) for i in info.values())
    m = env.metrics()
    assert exited > 0 and wrong == 0 and m["wrong_exits"] == 0 and m["left_road"] == 0


@pytest.mark.parametrize("cfg, match", [
    ({"action": {"type": "Meta"}}, "unknown action type 'Meta'"),
    ({"action": {"type": "ContinuousAction", "bound": 0.1}}, r"\['bound'\] do not apply"),
    ({"action": {"type": "FormationResidual", "bound": 3}}, "bound"),
    ({"action": {"type": "DiscreteMetaAction", "target_speeds": [30, 20]}}, "target_speeds"),
    ({"action": {"type": "DiscreteMetaAction", "lateral": False, "longitudinal": False}}, "both False"),
    ({"observation": {"type": "Grid"}}, "unknown observation type 'Grid'"),
    ({"observation": {"features": ["x", "speed"]}}, r"unknown observation feature\(s\) \['speed'\]"),
    ({"observation": {"type": "OccupancyGrid", "features": ["on_road"]}}, "on_road"),
    ({"observation": {"type": "OccupancyGrid", "vehicles_count": 4}}, r"\['vehicles_count'\] do not apply"),
    ({"observation": {"see_behind": True}}, "see_behind"),
    ({"observation": {"absolute": "yes"}}, "absolute"),
])
def test_bad_types_raise(cfg, match):
    for mod in (highway_formation_v0, intersection_v0):
        with pytest.raises(ValueError, match=match):
            mod.parallel_env(**cfg)


def test_bad_actions_name_the_agent():
    env = highway_formation_v0.parallel_env(action={"type": "DiscreteMetaAction"})
    env.reset(seed=0)
    acts = {a: 1 for a in env.agents}
    for bad in (5, -1, 1.5, "1", np.array([1, 2])):
        acts["icv_3"] = bad
        with pytest.raises(ValueError, match="icv_3"):
            env.step(acts)
    acts["icv_3"] = np.int64(2)
    env.step(acts)
    lat = highway_formation_v0.parallel_env(action={"type": "DiscreteMetaAction", "longitudinal": False})
    assert lat.action_space("icv_0").n == 3


def test_meta_lane_change_is_aborted_by_the_opposite_request():
    """highway-env semantics: LANE_LEFT during a change to the right (and the
    reverse) takes the vehicle back to its lane; the same direction again is
    ignored (one lane at a time)."""
    env = highway_formation_v0.parallel_env(scenario="free", vehicles_count=1, lanes_count=3, missing_action="expert",
                                            action={"type": "DiscreteMetaAction"})
    env.reset(seed=0)
    core = env.core
    tr, road = core.world.traffic, core.world.road
    lane0 = int(road.lane_of(tr.center()[1])[0])
    go, back = (0, 2) if lane0 > 0 else (2, 0)
    env.step({"icv_0": go})
    env.step({"icv_0": go})  # same direction while changing: ignored
    env.step({"icv_0": 1})
    y_mid = float(tr.y[0])
    assert abs(y_mid - lane0 * road.lane_width) > 0.05  # the change has started
    env.step({"icv_0": back})
    assert core.action_type.controller.aborted == 1
    for _ in range(40):
        env.step({"icv_0": 1})
    assert abs(tr.y[0] - lane0 * road.lane_width) < 0.3 and abs(tr.heading[0]) < 0.02
    # a change that is not aborted still ends in the next lane
    env.reset(seed=0)
    tr, road = core.world.traffic, core.world.road
    for a in [go] + [1] * 40:
        env.step({"icv_0": a})
    assert int(road.lane_of(tr.center()[1])[0]) == lane0 + (1 if go == 2 else -1)


def test_meta_lane_change_is_aborted_at_the_intersection():
    env = intersection_v0.parallel_env(duration=60.0, throughput=300.0, action={"type": "DiscreteMetaAction"})
    env.reset(seed=0)
    core = env.core
    while not env.agents:
        env.step({})
    a0 = env.agents[0]
    f = core.world.fleet

    def lat():
        row = int(np.flatnonzero(f.vid == int(a0[4:]))[0])
        return float(core.world.route().lat_leg[row]), int(core.world.route().lane[row])

    lat0, lane = lat()
    go, back = (0, 2) if lane > 0 else (2, 0)
    env.step({a: (go if a == a0 else 1) for a in env.agents})
    env.step({a: 1 for a in env.agents})
    assert abs(lat()[0] - lat0) > 0.02  # the change has started
    env.step({a: (back if a == a0 else 1) for a in env.agents})
    assert core.action_type.controller.aborted == 1
    for _ in range(30):
        env.step({a: 1 for a in env.agents})
    assert abs(lat()[0] - lat0) < 0.4 and lat()[1] == lane


def test_intersection_leader_features_are_opt_in_and_match_the_corridor_leader():
    """``lead_gap`` / ``lead_dv`` (opt-in): the default layout is unchanged, the
    extra columns are the leader the safety reward sees, and both the
    Gymnasium and the PettingZoo checkers accept the wider space."""
    from icv_envs.envs.intersection import OBS_FEATURES

    feats = list(OBS_FEATURES) + ["lead_gap", "lead_dv"]
    cfg = {"throughput": 2000, "duration": 4.0}
    wide = intersection_v0.parallel_env(**cfg, observation={"features": feats, "normalize": False})
    base = intersection_v0.parallel_env(**cfg)
    ow, iw = wide.reset(seed=5)
    ob, ib = base.reset(seed=5)
    assert wide.observation_space("icv_0").shape == (8, 16)
    saw_leader = False
    for _ in range(15):
        ow, *_, iw = wide.step({a: iw[a]["expert_action"] for a in wide.agents})
        ob, *_, ib = base.step({a: ib[a]["expert_action"] for a in base.agents})
        core = wide.core
        gap, dv = core._leaders()
        f = core.world.fleet
        for a in wide.agents:
            r = int(np.searchsorted(f.vid, int(a.split("_")[1])))
            expect_gap = min(gap[r], 100.0)
            assert ow[a][0, 14] == pytest.approx(expect_gap, abs=1e-4)
            assert ow[a][0, 15] == pytest.approx(dv[r] if np.isfinite(gap[r]) else 0.0, abs=1e-4)
            saw_leader |= bool(np.isfinite(gap[r]))
        # the extra columns do not change who is on the road
        assert set(ob) == set(ow)
    assert saw_leader
    norm = intersection_v0.parallel_env(**cfg, observation={"features": feats})
    on, _ = norm.reset(seed=5)
    for a in on:
        np.testing.assert_array_equal(on[a][:, :14], intersection_v0.parallel_env(**cfg).reset(seed=5)[0][a])
        break
    g = gym.make("icv_envs/Intersection-v0", config=dict(cfg, observation={"features": ["lead_dv", "x", "lead_gap"]}))
    check_env(g.unwrapped, skip_render_check=True)
    parallel_api_test(intersection_v0.parallel_env(**cfg, observation={"features": feats}), num_cycles=10)
    with pytest.raises(ValueError, match="lead_gap"):
        highway_formation_v0.parallel_env(observation={"features": ["x", "lead_gap"]})


# ---------------------------------------------------- the meta-action layer's fast path (stop 45)
@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**16))
def test_meta_control_laws_equal_the_checked_public_functions(n, seed):
    """The meta-action layer calls the steering and feedback laws without
    their input checks (the simulator's own finite float64 arrays): the same
    numbers as the public, checked functions, bit for bit."""
    from types import SimpleNamespace

    from icv_envs.envs.meta_control import _A_REF, _KP, _KV, _steering
    from icv_envs.formation.bezier import pure_pursuit_steering
    from icv_envs.formation.control import DEFAULT_KP, DEFAULT_KV, _longitudinal_feedback, longitudinal_feedback

    rng = np.random.default_rng(seed)
    x, y, h = rng.uniform(-500, 500, n), rng.uniform(-10, 10, n), rng.uniform(-3.5, 3.5, n)
    tx, ty = x + rng.uniform(0, 30, n), rng.uniform(-10, 10, n)
    p = SimpleNamespace(wheelbase=2.8, steer_max=float(np.deg2rad(30.0)), a_min=-6.0, a_max=3.0)
    assert np.array_equal(_steering(x, y, h, tx, ty, p), pure_pursuit_steering(x, y, h, tx, ty, p.wheelbase,
                                                                               p.steer_max))
    v, vt = rng.uniform(0, 35, n), rng.choice([0.0, 5.0, 20.0, 30.0], n)
    z = np.zeros_like(v)
    assert np.array_equal(_longitudinal_feedback(z, z, v, vt, _KP, _KV, p.a_min, p.a_max, _A_REF),
                          longitudinal_feedback(z, z, v, vt, DEFAULT_KP, DEFAULT_KV, p.a_min, p.a_max))


def test_discrete_check_many_is_the_per_agent_check():
    """``DiscreteMetaAction.check_many``: integer scalars in range as one
    array, the indices ``check`` gives; anything else (floats, 0-d arrays,
    bools, out of range) through ``check``, whose error names the agent."""
    from icv_envs.envs.highway_formation_v0 import parallel_env

    env = parallel_env(vehicles_count=3, action={"type": "DiscreteMetaAction"})
    env.reset(seed=0)
    at = env.core._act_type
    names = ["icv_0", "icv_1", "icv_2"]
    for values in ([0, 4, 2], [np.int64(1), np.int32(3), np.uint8(0)], [1.0, np.array(2), 3]):
        assert list(np.asarray(at.check_many(values, names))) == [at.check(v, a) for a, v in zip(names, values)]
    for bad, who in (([0, 5, 1], "icv_1"), ([0, 1, -1], "icv_2"), ([True, 1, 1], "icv_0"),
                     ([0, np.uint64(2**63), 1], "icv_1")):
        with pytest.raises(ValueError, match=f"action of {who} = .*allowed: an integer in \\[0, 4\\]"):
            at.check_many(bad, names)
