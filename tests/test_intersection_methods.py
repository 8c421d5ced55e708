"""The three coordination methods: collision-free, nothing lost, regrouping,
tree-layers, reservations; the envelope is not what keeps the box safe."""

import numpy as np
import pytest

from icv_envs.envs import intersection_v0
from icv_envs.experiments.intersection_compare import run_intersection
from icv_envs.platoon import tree_depths

from test_intersection_no_deadlock import assert_no_inverted_pair


def _drive(env, seconds, check=None):
    obs, infos = env.reset(seed=env._seed) if hasattr(env, "_seed") else env.reset(seed=0)
    while env.core.world.time < seconds - 1e-9:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
        if check is not None:
            check(env)
    return env.metrics()


@pytest.mark.parametrize("method", ["multi-vp", "single-vp", "fcfs"])
@pytest.mark.parametrize("lane_use", ["paper", "exclusive"])
def test_short_run_is_collision_free_and_loses_nothing(method, lane_use):
    m = run_intersection(method, 2500.0, 0, 150.0, {"lane_use": lane_use})
    assert m["collisions"] == 0, m["collision_log"]
    assert m["lost"] == 0
    assert m["spawned"] == m["exited"] + m["left_road"] + m["remaining"] + m["crashed_removed"]
    assert m["cleared"] > 20 and m["wrong_exits"] == 0
    assert m["envelope_box_binding"] == 0  # the coordination, not the envelope, keeps the box safe
    assert 8.0 < m["mean_speed"] < 11.0


@pytest.mark.parametrize("method", ["multi-vp", "single-vp", "fcfs"])
def test_no_collision_without_the_envelope_in_the_box(method):
    m = run_intersection(method, 3000.0, 1, 150.0, {"envelope_in_box": False})
    assert m["collisions"] == 0, m["collision_log"]
    assert m["lost"] == 0 and m["cleared"] > 20


def _check_entries(env):
    """Every vehicle that has entered the box entered from a lane its movement may use."""
    core = env.core
    f = core.world.fleet
    ent = f.entered
    assert np.all(core.layout.allowed[f.mv[ent], f.plane[ent]])


def test_regrouping_puts_every_vehicle_in_an_allowed_lane_and_merges():
    env = intersection_v0.parallel_env(method="multi-vp", throughput=2500.0, duration=200.0)
    m = _drive(env, 200.0, _check_entries)
    st = env.core.expert.stats
    assert st["divisions"] > 10 and st["subformations"] > st["divisions"]
    assert st["merges"] >= 1 and st["lane_changes"] > 20
    assert m["collisions"] == 0


def test_tree_layers_follow_the_conflict_model():
    env = intersection_v0.parallel_env(method="multi-vp", throughput=3000.0, duration=120.0)
    seen_multi = []

    def check(env):
        core = env.core
        ex = core.expert
        if not ex.node_order:
            return
        w = core.world
        rs = w.route()
        ids, depths, T = ex.tree(w, rs)
        assert ids == ex.node_order
        mvs = np.array([ex.nodes[i]["mv"] for i in ids])
        C = core.layout.conflict[np.ix_(mvs, mvs)]
        np.testing.assert_array_equal(depths, tree_depths(C))
        # conflicting nodes never share a layer and keep their order
        for i in range(len(ids)):
            for j in range(i + 1, len(ids)):
                if C[i, j]:
                    assert depths[j + 1] > depths[i + 1]
        # the order never puts a node before one it physically follows in its lane (the
        # order is the entry order, tests/test_intersection_no_deadlock.py checks it fully)
        assert_no_inverted_pair(core, ids)
        seen_multi.append(max(len(ex.nodes[i]["members"]) for i in ids))

    m = _drive(env, 120.0, check)
    assert max(seen_multi) > 1  # sub-formations are nodes
    assert m["collisions"] == 0


def test_single_vp_has_one_vehicle_per_node():
    env = intersection_v0.parallel_env(method="single-vp", throughput=2500.0, duration=120.0)

    def check(env):
        for N in env.core.expert.nodes.values():
            assert len(N["members"]) == 1

    m = _drive(env, 120.0, check)
    assert m["nodes"] > 20 and m["collisions"] == 0


def test_fcfs_reservations_are_disjoint_and_followed():
    env = intersection_v0.parallel_env(method="fcfs", throughput=2500.0, duration=150.0)

    def check(env):
        ex = env.core.expert
        tab = ex.table
        # no tile is held by two vehicles at one step (the table stores one holder per tile and step)
        for vid in tab.vehicles:
            assert vid in ex.plans
        f = env.core.world.fleet
        # vehicles in the box all hold a reservation or have just cleared it
        box = f.entered & ~f.departed
        assert all(int(v) in ex.plans for v in f.vid[box])

    m = _drive(env, 150.0, check)
    st = env.core.expert.stats
    assert st["granted"] > 50 and st["rejected"] > 0
    assert st["max_plan_error"] < 0.75  # metres off the reserved trajectory inside the box
    assert m["collisions"] == 0 and m["lost"] == 0


def test_unreserved_vehicles_stop_before_the_box():
    # a reservation table that never grants: everybody queues at the stop line
    env = intersection_v0.parallel_env(method="fcfs", throughput=1500.0, duration=100.0)
    env.reset(seed=0)
    env.core.expert.table.request = lambda *a, **k: False
    while env.core.world.time < 100.0 - 1e-9:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    m = env.metrics()
    f = env.core.world.fleet
    assert not f.entered.any() and m["cleared"] == 0 and m["collisions"] == 0
    rs = env.core.world.route()
    first = rs.u.max()
    assert -5.0 < first < -2.5  # stopped just before the stop line


def test_throughput_rises_with_demand_and_metrics_are_sane():
    lo = run_intersection("multi-vp", 1000.0, 0, 300.0)
    hi = run_intersection("multi-vp", 2500.0, 0, 300.0)
    assert hi["cleared"] > lo["cleared"]
    for m in (lo, hi):
        assert m["collisions"] == 0 and m["lost"] == 0
        assert 0 < m["speed_fluctuation"] < 1.0
        assert m["mean_delay"] is not None and -10 < m["mean_delay"] < 60
