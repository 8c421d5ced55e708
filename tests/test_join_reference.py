"""The formation layer's join references (icv_envs.sim.formations): a member
that joins or is re-assigned gets a reference that starts where it is and
moves to its slot with bounded acceleration, not a step."""

from __future__ import annotations

import numpy as np

from icv_envs.formation.control import PROFILE_ACCEL, PROFILE_DECEL
from icv_envs.policies.formation_expert import FormationExpert
from icv_envs.sim.formations import FormationManager
from icv_envs.sim.road import RoadLayout
from icv_envs.sim.world import StepEvents, World


def make_world(xs, lanes, speeds):
    road = RoadLayout(3, 5000.0, 4.0, np.full(3, np.inf), [], [], [], periodic=False)
    w = World(road, FormationManager(speed=25.0, max_anchor_lead=1e6), dt=0.04)
    w.traffic.add(np.asarray(xs, float), np.asarray(lanes, float) * 4.0, np.asarray(speeds, float))
    return w


def run(w, expert, seconds, policy_dt=0.2):
    ev = StepEvents()
    rec = []
    for _ in range(int(round(seconds / policy_dt))):
        act = expert.compute(w)
        a = np.where(act[:, 0] >= 0, act[:, 0] * 3.0, act[:, 0] * 6.0)
        phi = act[:, 1] * np.deg2rad(30.0)
        for _ in range(int(round(policy_dt / w.dt))):
            w.substep(a, phi, ev)
        w.manager.update(w.traffic, w.road, policy_dt)
        x_ref, _, _, member = w.manager.references(w.traffic)
        rec.append((w.traffic.center()[0].copy(), x_ref.copy(), w.manager.slots(w.traffic), w.traffic.accel.copy()))
    return rec, ev


def test_reference_starts_at_the_member_and_reaches_the_slot():
    # three vehicles far from their interlaced slots (up to 70 m), 3 m/s slow
    w = make_world([1000.0, 960.0, 1030.0], [0, 1, 2], [22.0, 22.0, 22.0])
    gid = w.manager.create(w.traffic, np.arange(3), w.road, anchor=1050.0)
    x_ref, _, v_ref, member = w.manager.references(w.traffic)
    cx = w.traffic.center()[0]
    assert member.all() and gid == 0
    np.testing.assert_allclose(x_ref, cx, atol=1e-9)  # no step at the join
    np.testing.assert_allclose(v_ref, 22.0, atol=1e-9)
    slots = w.manager.slots(w.traffic)
    assert np.abs(slots - cx).max() > 30.0
    T = w.manager._plans.T[w.traffic.vid].max()
    assert T < 120.0
    rec, ev = run(w, FormationExpert(), T + 10.0)
    assert not ev.crashed
    cx, x_ref, slots, acc = rec[-1]
    np.testing.assert_allclose(x_ref, slots, atol=1e-6)  # the profiles have ended on the slots
    assert np.abs(cx - slots).max() < 0.5
    # the vehicles followed their references closely, within the comfort band
    err = np.array([np.abs(c - r).max() for c, r, _, _ in rec])
    assert err.max() < 1.0
    a = np.array([r[3] for r in rec])
    assert a.max() <= PROFILE_ACCEL + 0.5 and a.min() >= -PROFILE_DECEL - 0.5


def test_a_member_held_back_is_re_planned_from_where_it_is():
    w = make_world([1000.0, 980.0], [0, 2], [25.0, 25.0])
    w.manager.create(w.traffic, np.arange(2), w.road, anchor=1000.0)
    before = w.manager.plans
    # hold vehicle 1 back 20 m (as if traffic had stopped it)
    w.traffic.x = w.traffic.x - np.array([0.0, 20.0])
    w.manager.update(w.traffic, w.road, 0.2)
    assert w.manager.plans == before + 1
    x_ref, _, _, _ = w.manager.references(w.traffic)
    assert abs(x_ref[1] - w.traffic.center()[0][1]) < 25.0 * 0.2 + 1e-6  # the new plan starts where it is


def test_references_are_kept_per_state_and_refreshed_by_every_writer():
    """references() answers from its cache only while the formation state
    is the one it computed: create(), update() and a change of vehicles
    each give a fresh answer equal to a computation from scratch; the
    answer is read-only (a caller cannot corrupt the next caller's)."""
    import pytest

    w = make_world([1000.0, 980.0, 960.0], [0, 1, 2], [25.0, 25.0, 25.0])
    m = w.manager
    r0 = m.references(w.traffic)
    assert r0[3].sum() == 0 and m.references(w.traffic) is r0  # no formation yet; same state: the kept answer
    with pytest.raises(ValueError):
        r0[0][0] = 1.0
    m.create(w.traffic, np.arange(2), w.road, anchor=1000.0)
    r1 = m.references(w.traffic)
    assert r1 is not r0 and r1[3].sum() == 2
    for _ in range(3):
        w.substep(np.zeros(3), np.zeros(3), StepEvents())
        m.update(w.traffic, w.road, 0.04)
        got = m.references(w.traffic)
        want, want_accel = m._references(w.traffic)
        for g, x in zip(got, want):
            np.testing.assert_array_equal(g, x)
        member = np.flatnonzero(w.traffic.group >= 0)
        np.testing.assert_array_equal(m.reference_accel(w.traffic), want_accel)
        np.testing.assert_array_equal(want_accel[member], m._profile(w.traffic, member)[2])
        assert not m.reference_accel(w.traffic).flags.writeable
    assert got[3].sum() == 3  # the free vehicle joined: the cache saw the update
    w.traffic.remove(np.array([False, True, False]))
    after = m.references(w.traffic)
    assert len(after[0]) == 2
