"""Lane-change reservations belong to whoever carries the plan out (issue 9).

The highway expert plans lane changes for every vehicle (the labels in
``infos["expert_action"]`` need them), and a planned lane change lists the
vehicle in its target lane of the controllers' lane index (a turn signal the
others yield to).  A vehicle driven by a learned policy does not follow that
plan: it must not hold the lane (before: 6.7% of the non-expert
vehicle-steps on lane-drop with half the agents off the expert did).  A
``FormationResidual`` agent carries the expert's plan out: it keeps it.
"""

import numpy as np
import pytest

from icv_envs.envs.highway_formation_v0 import parallel_env


def listed(index, n):
    """Set of (row, lane) pairs the index lists."""
    return set(zip(index.rows.tolist(), index.lanes.tolist()))


@pytest.mark.parametrize("action_type", ["ContinuousAction", "FormationResidual"])
def test_only_vehicles_carrying_the_plan_hold_its_lane(action_type):
    env = parallel_env(scenario="lane-drop", action={"type": action_type})
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    off, carried, planned = 0, 0, 0
    while env.agents:
        ex = env.expert_actions()
        acts = {}
        for i, a in enumerate(env.agents):
            if i % 2:
                acts[a] = ex[a]
            else:  # off the expert: a small random action
                acts[a] = np.clip(ex[a] + rng.normal(0, 0.3, 2), -1, 1).astype(np.float32) \
                    if action_type == "ContinuousAction" else rng.uniform(-1, 1, 2).astype(np.float32)
        env.step(acts)
        w = env.unwrapped.core.world if hasattr(env.unwrapped, "core") else env.core.world
        tr = w.traffic
        w.invalidate()  # the cached index is the one the expert planned on; rebuild it on the plans it made
        res = listed(w.lane_index(reserved=True), tr.n)
        body = listed(w.lane_index(reserved=False), tr.n)
        extra = res - body
        for r in range(tr.n):
            if tr.lc_lane[r] < 0:
                continue
            planned += 1
            expert = w._expert_vids is None or int(tr.vid[r]) in w._expert_vids
            holds = (r, int(tr.lc_lane[r])) in res
            if not expert:
                off += 1
                if action_type == "ContinuousAction":
                    assert not holds or (r, int(tr.lc_lane[r])) in body, "phantom reservation"
                else:
                    carried += holds
        assert all(tr.lc_lane[r] >= 0 for r, _ in extra)
    assert planned > 0 and off > 0
    if action_type == "FormationResidual":
        assert carried > 0


def test_intersection_signals_only_for_vehicles_carrying_the_plan():
    from icv_envs.envs.intersection_v0 import parallel_env as intersection

    env = intersection(throughput=3000.0, duration=60.0)
    env.reset(seed=1)
    rng = np.random.default_rng(0)
    off_planned = 0
    while env.agents:
        ex = env.expert_actions()
        acts = {a: ex[a] if i % 2 else np.clip(ex[a] + rng.normal(0, 0.3, 2), -1, 1).astype(np.float32)
                for i, a in enumerate(env.agents)}
        env.step(acts)
        x = env.core.expert
        f = env.core.world.fleet
        if x._plan_vids is None:
            continue
        sig = x._signals(f)
        off = ~np.isin(f.vid, np.fromiter(x._plan_vids, dtype=np.int64))
        off_planned += int((off & ((f.lc_lane >= 0) | (f.want >= 0))).sum())
        assert np.all(sig[off] == -1)
        on = ~off
        assert np.array_equal(sig[on], np.where(f.lc_lane >= 0, f.lc_lane, f.want)[on])
    env.close()
    assert off_planned > 0, "no vehicle off the expert had a plan: the test saw nothing"


def test_the_two_views_share_one_index_only_without_reservations():
    """World.lane_index builds the reserved (controllers') view and the body
    view separately, and hands out the one already built when no vehicle
    holds a reservation (the two are then the same index). Whichever view is
    asked first, each answer equals a fresh build of that view, over a run
    with lane changes (reservations) and without."""
    from icv_envs.sim.traffic import lane_index

    env = parallel_env(scenario="lane-drop")
    env.reset(seed=3)
    shared = separate = 0
    for t in range(200):
        if not env.agents:
            break
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
        w = env.core.world
        w.invalidate()
        first = t % 2 == 0  # alternate which view is built first
        a = w.lane_index(reserved=first)
        b = w.lane_index(reserved=not first)
        res, body = (a, b) if first else (b, a)
        tr = w.traffic
        cx, cy = tr.center()
        args = (cx, cy, tr.width, w.road.lane_width, w.road.total_lanes, w.road.length)
        kw = dict(periodic=w.road.periodic, length=tr.length, heading=tr.heading)
        for got, want in ((res, lane_index(*args, reserved_lane=w._reservations(), **kw)),
                          (body, lane_index(*args, reserved_lane=None, **kw))):
            for name in ("keys", "rows", "lanes", "x"):
                np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
            assert got.offset == want.offset
        if (w._reservations() >= 0).any():
            separate += 1
            assert res is not body
        else:
            shared += 1
            assert res is body
    assert shared > 10 and separate > 10
