"""Collisions by fault at the intersection (issue 11, item 5)."""

import math

import numpy as np
import pytest

from icv_envs.sim.intersection_metrics import collision_fault


def test_rear_end_the_rear_vehicle_is_at_fault():
    # b 4 m ahead of a, both heading east; a faster
    assert collision_fault(0.0, 0.0, 0.0, 10.0, 4.0, 0.0, 0.0, 2.0) == ("struck_ahead", 0)
    # the same with the roles swapped
    assert collision_fault(4.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 10.0) == ("struck_ahead", 1)


def test_rear_end_by_a_cut_in_the_front_vehicle_is_at_fault():
    # b ahead and to the left of a, turning right (heading -20 deg) into a's lane at 5 m/s
    kind, k = collision_fault(0.0, 0.0, 0.0, 8.0, 4.5, 1.0, math.radians(-20.0), 5.0)
    assert (kind, k) == ("struck_from_behind", 1)


def test_angle_the_vehicle_driving_into_the_other_is_at_fault():
    # a northbound at 10 m/s hits b crossing westbound at 1 m/s just ahead of it
    assert collision_fault(0.0, 0.0, math.pi / 2, 10.0, 1.0, 3.5, math.pi, 1.0) == ("angle", 0)
    # a standing vehicle is never at fault against a moving one
    assert collision_fault(0.0, 0.0, math.pi / 2, 0.0, -3.0, 1.0, 0.0, 6.0) == ("angle", 1)


def test_the_env_reports_collisions_by_fault_and_blames_the_policy_that_stops_in_the_box():
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method="multi-vp", throughput=3000.0, duration=40.0, missing_action="expert")
    env.reset(seed=0)
    m0 = env.metrics()["collisions_by_fault"]
    assert set(m0) == {"struck_ahead", "struck_from_behind", "angle"}
    rng = np.random.default_rng(0)
    while not env.episode_over:
        ex = env.expert_actions()
        # a third of the agents brake and steer at random: they cause collisions
        acts = {a: (rng.uniform(-1, 1, 2).astype(np.float32) if int(a[4:]) % 3 == 0 else ex[a]) for a in env.agents}
        env.step(acts)
    m = env.metrics()
    by = m["collisions_by_fault"]
    pairs = sum(v["expert"] + v["policy"] for v in by.values())
    assert m["collisions"] > 0
    # one entry per colliding pair; every vehicle of a pair counts in "collisions"
    assert 0 < pairs <= m["collisions"]
    assert sum(v["policy"] for v in by.values()) > 0
    env.close()


def test_experts_do_not_drive_into_vehicles_crawling_to_rest_behind_a_stopped_one():
    """fcfs, 2000 veh/h, seed 2: a policy stops the first vehicle in the box
    at t = 100 s; before the ghost rule, an fcfs vehicle with a reservation
    drove into a vehicle crawling across its path to its resting place
    behind the stopped one (t = 113.4 s; 3 such pairs in 240 s)."""
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method="fcfs", throughput=2000.0, duration=125.0, missing_action="expert")
    env.reset(seed=2)
    f = env.core.world.fleet
    stopper = None
    while not env.episode_over:
        ex = env.expert_actions()
        if stopper is None and env.core.world.time > 100:
            inbox = [i for i in range(f.n) if abs(f.x[i]) < 10 and abs(f.y[i]) < 10 and not f.cleared[i]
                     and f.speed[i] > 3]
            if inbox:
                stopper = f"icv_{f.vid[inbox[0]]}"
        acts = {stopper: np.array([-1.0, ex[stopper][1]], dtype=np.float32)} if stopper in env.agents else {}
        env.step(acts)
    m = env.metrics()
    env.close()
    assert stopper is not None
    assert m["collisions"] == 0, m["collisions_by_fault"]
