"""Intersection run metrics: realised speed fluctuation, PET on a hand-built crossing, the jam watchdog."""

import math

import numpy as np
import pytest

from icv_envs.experiments.seeds import parse_seeds
from icv_envs.sim.intersection_metrics import (
    JAM_SECONDS,
    ConflictAreas,
    JamWatch,
    MotionStats,
    PetStats,
    pet_summary,
)
from icv_envs.sim.intersection_world import IntersectionLayout, IntersectionWorld, StepEvents


def test_vehicle_held_at_zero_with_braking_has_no_realised_fluctuation():
    m = MotionStats()
    for _ in range(10):
        m.record([0], [0.0], [0.0], [-6.0], 0.04)
    s = m.summary()
    assert s["speed_fluctuation"] == 0.0 and s["commanded_abs_accel"] == 6.0
    assert s["stopped_share"] == 1.0 and s["speed_std"] == 0.0


def test_realised_fluctuation_in_the_world():
    lay = IntersectionLayout("paper")
    w = IntersectionWorld(lay)
    a = w.spawn(0, 1, 1, 0.0, -200.0, tlane=1)  # standing, told to brake
    b = w.spawn(1, 1, 4, 10.0, -200.0, tlane=1)  # braking for real at 2 m/s^2
    ev = StepEvents()
    for _ in range(25):
        w.substep(np.array([-6.0, -2.0]), np.zeros(2), ev)
    s = w.motion.summary()
    # only b's 2 m/s^2 counts, over both vehicles' substeps
    assert s["speed_fluctuation"] == pytest.approx(1.0, abs=1e-9)
    assert s["commanded_abs_accel"] == pytest.approx(4.0)
    assert s["stopped_share"] == pytest.approx(0.5)
    assert w.fleet.speed[w.fleet.rows([a])[0]] == 0.0 and w.fleet.speed[w.fleet.rows([b])[0]] == pytest.approx(8.0)


def _cross(lay, pa, pb):
    """The conflict area shared by paths pa and pb (ids, intervals on both)."""
    A = ConflictAreas(lay)
    ia, sa, loa, hia = A.by_path[pa]
    ib, sb, lob, hib = A.by_path[pb]
    common = sorted(set(ia.tolist()) & set(ib.tolist()))
    assert len(common) == 1
    z = common[0]
    ka, kb = int(np.flatnonzero(ia == z)[0]), int(np.flatnonzero(ib == z)[0])
    return A, z, (loa[ka], hia[ka]), (lob[kb], hib[kb])


def test_pet_on_a_hand_built_right_angle_crossing():
    lay = IntersectionLayout("paper")
    pa, pb = 3 * 1 + 1, 3 * 4 + 1  # N straight and E straight, middle lanes: a right angle
    A, z, (la, ha), (lb, hb) = _cross(lay, pa, pb)
    # right angle, 2 m wide vehicles: the area is +-1 m around the crossing point on both paths
    assert ha - la == pytest.approx(2.0, abs=0.05) and hb - lb == pytest.approx(2.0, abs=0.05)
    pet = PetStats(A)
    L, v, dt = 5.0, 10.0, 0.04
    # A crosses first; its rear leaves the area when s - L/2 = ha, at t_a
    t_a = (ha + L / 2) / v
    gap = 1.5  # B's front enters 1.5 s later: s + L/2 = lb at t_a + 1.5
    for k in range(200):
        t = k * dt
        sa = v * t
        sb = lb - L / 2 + v * (t - t_a - gap)
        pet.record(t, [1, 2], [pa, pb], [sa, sb], [L, L])
    s = pet.summary()
    assert s["pet_samples"] == 1
    assert s["pet_min"] == pytest.approx(gap, abs=dt + 1e-9)


def test_pet_is_negative_when_both_occupy_the_area():
    lay = IntersectionLayout("paper")
    pa, pb = 3 * 1 + 1, 3 * 4 + 1
    A, z, (la, ha), (lb, hb) = _cross(lay, pa, pb)
    pet = PetStats(A)
    L, v, dt = 5.0, 10.0, 0.04
    t_a = (ha + L / 2) / v
    for k in range(200):
        t = k * dt
        pet.record(t, [1, 2], [pa, pb], [v * t, lb - L / 2 + v * (t - t_a + 0.3)], [L, L])
    s = pet.summary()
    assert s["pet_samples"] == 1 and s["pet_min"] == pytest.approx(-0.3, abs=dt + 1e-9)


def test_no_pet_between_vehicles_of_one_path_and_summary_of_nothing():
    lay = IntersectionLayout("paper")
    A = ConflictAreas(lay)
    pet = PetStats(A)
    for k in range(200):
        t = k * 0.04
        pet.record(t, [1, 2], [4, 4], [10 * t, 10 * t - 12.0], [5.0, 5.0])
    assert pet.summary() == {"pet_min": None, "pet_p05": None, "pet_samples": 0}
    assert pet_summary([3.0, 1.0, 2.0])["pet_min"] == 1.0


def test_jam_watch_counts_only_stops_outside_a_queue():
    j = JamWatch()
    dt = 0.04
    n = int(math.ceil(JAM_SECONDS / dt)) + 5
    for k in range(n):
        # vehicle 1 stopped in a queue, vehicle 2 stopped in the open, vehicle 3 moving
        j.record(k * dt, dt, np.array([1, 2, 3]), np.array([0.0, 0.0, 5.0]), lambda rows: rows == 0)
    s = j.summary()
    assert s["jammed"] == 1 and j.log[0][1] == 2
    assert 0 < s["jammed_vehicle_seconds"] < 0.5


def test_world_queue_rule_anchors_a_discharging_queue_at_its_moving_front():
    """The tail of a queue whose front has moved off (its head more than 10 m from the line, moving) is
    still in the queue; a standing chain with a standing head away from the line is not; a vehicle
    behind a moving vehicle but more than 10 m back is not."""
    lay = IntersectionLayout("paper")
    w = IntersectionWorld(lay)
    # N lane 1: moving head 20 m before the line (gap 17.5 m), standing tail 2 m behind it
    w.spawn(0, 1, 1, 3.0, -20.0, tlane=1)
    for s in (-27.0, -34.0):
        w.spawn(0, 1, 1, 0.0, s, tlane=1)
    # E lane 1: standing head 60 m out, standing vehicle 2 m behind it
    w.spawn(1, 1, 4, 0.0, -60.0, tlane=1)
    w.spawn(1, 1, 4, 0.0, -67.0, tlane=1)
    # S lane 1: moving vehicle, a standing one 15 m (bumper) behind it
    w.spawn(2, 1, 7, 3.0, -60.0, tlane=1)
    w.spawn(2, 1, 7, 0.0, -80.0, tlane=1)
    rs = w.route()
    q = w._in_queue(np.arange(7), rs.u, rs.lat_leg)
    assert q[[1, 2]].all()  # the tail of the discharging queue
    assert not q[3:].any()


def test_world_queue_rule():
    lay = IntersectionLayout("paper")
    w = IntersectionWorld(lay)
    # a queue at the stop line of N lane 1 and a lone vehicle 200 m out in lane 2
    for s in (-3.5, -10.5, -17.5):
        w.spawn(0, 1, 1, 0.0, s, tlane=1)
    w.spawn(0, 2, 2, 0.0, -200.0, tlane=2)
    rs = w.route()
    q = w._in_queue(np.arange(4), rs.u, rs.lat_leg)
    assert q.tolist() == [True, True, True, False]
    ev = StepEvents()
    for _ in range(int(JAM_SECONDS / w.dt) + 10):
        w.substep(np.zeros(4), np.zeros(4), ev)
    assert w.jams.summary()["jammed"] == 1


@pytest.mark.parametrize("text,out", [("3", [0, 1, 2]), (3, [0, 1, 2]), ("5,7,10-12", [5, 7, 10, 11, 12]),
                                      ("4,", [4]), ("2-2", [2]), (" 1 , 0 ", [1, 0])])
def test_seed_lists(text, out):
    assert parse_seeds(text) == out


@pytest.mark.parametrize("bad", ["", "0", "-1", "a", "3-1", "1,,x", 0, -2, True, 2.5, [], [-1], ",", "1.5", "1,1"])
def test_bad_seed_lists(bad):
    with pytest.raises(ValueError, match="seeds"):
        parse_seeds(bad)
