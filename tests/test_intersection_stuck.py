"""The two gridlock mechanisms the seed sweep found (issue 8), on hand-built scenes.

1. A vehicle inside the coordinating zone that is not in its expected lane
   kept trying to change lanes among coordinated vehicles (at the stop line
   with no room left, it waited there for ever).  It now commits to its lane
   (no lane change inside R1, paper Sec. 4): it keeps it if that lane serves
   its movement, and otherwise takes a movement its lane serves (``rerouted``).
2. A vehicle waiting to change into a lane held back the vehicle already
   alongside it in that lane, whose presence blocked the lane change.
3. A vehicle stopped at an angle mid lane change was invisible to the lane it
   was leaving (the collision of the sweep at 4500 veh/h).

Tests 1 and 2 fail on the code before the fixes (a6324c5); test 3 fails
there for fcfs (for the VP methods the follower is held by other rules in
this scene).

The two circular waits of the saturation sweep (multi-vp at 3500 and 4000
veh/h, seed 0) are tested as rules at the end (both fail on 7e1c3f9: the
crossed pair changes lanes twice, the follower ahead of its reference
follows it).
"""

import numpy as np
import pytest

from icv_envs.envs.intersection import IntersectionEnv
from icv_envs.policies.platoon_common import ST_ADJUSTED


def empty_env(method):
    env = IntersectionEnv({"method": method, "throughput": 100.0, "duration": 60.0, "expert_in_info": False})
    env.ma_reset(seed=0)
    w = env.world
    w.fleet.crashed[:] = True
    w.remove_crashed_vehicles()
    env._pending = []
    for q in env._queues.values():
        q.clear()
    return env


def put(env, leg, lane, mv, s, speed, tlane):
    w = env.world
    vid = w.spawn(leg, lane, mv, speed, s, tlane=tlane)
    env.expert.on_spawn(w, vid, None, 0.0, lane)
    return vid


def run(env, seconds):
    w = env.world
    t_end = w.time + seconds
    while w.time < t_end - 1e-9:
        env.expert.update(w)
        env._advance(env.expert.compute(w))
        w.remove_crashed_vehicles()


@pytest.mark.parametrize("method", ["multi-vp", "single-vp", "fcfs"])
def test_a_vehicle_stuck_at_the_line_in_a_lane_not_serving_its_turn_is_rerouted(method):
    env = empty_env(method)
    lay = env.layout
    # leg 0: movement 0 only from lane 0, movement 1 (straight) from lane 1
    assert lay.allowed[0, 0] and not lay.allowed[0, 1] and lay.allowed[1, 1]
    vid = put(env, 0, 1, 0, -8.0, 2.0, tlane=0)  # 8 m before the line: no room to change lanes
    run(env, 15.0)
    w = env.world
    f = w.fleet
    r = f.rows([vid])[0]
    assert w.stats["rerouted"] == 1
    assert r < 0 or (f.mv[r] == 1 and f.entered[r])  # through the box (or already gone)
    assert w.stats["collisions"] == 0 and w.stats["wrong_exits"] == 0


@pytest.mark.parametrize("method", ["multi-vp", "single-vp", "fcfs"])
def test_a_vehicle_stuck_in_a_lane_serving_its_turn_keeps_it(method):
    env = empty_env(method)
    lay = env.layout
    assert lay.allowed[2, 1] and lay.allowed[2, 2]
    vid = put(env, 0, 2, 2, -8.0, 2.0, tlane=1)
    run(env, 15.0)
    w = env.world
    f = w.fleet
    r = f.rows([vid])[0]
    assert w.stats["rerouted"] == 0
    assert r < 0 or (f.mv[r] == 2 and f.entered[r])
    assert w.stats["collisions"] == 0


@pytest.mark.parametrize("method", ["multi-vp", "single-vp", "fcfs"])
def test_the_vehicle_alongside_a_waiting_lane_changer_goes_on(method):
    env = empty_env(method)
    w = env.world
    f = w.fleet
    # A in lane 0 wants lane 1 (its movement's only lane); B stands alongside in
    # lane 1; both in the adjusting zone (inside R1 nobody changes lanes)
    s0 = -(env.layout.R1 + 20.0 - env.layout.box_half)
    a = put(env, 0, 0, 1, s0, 0.0, tlane=1)
    b = put(env, 0, 1, 1, s0 - 0.5, 0.0, tlane=1)
    f.stage[f.rows([a, b])] = ST_ADJUSTED
    x0 = float(w.route().s[f.rows([b])[0]])
    run(env, 12.0)
    ra, rb = f.rows([a, b])
    assert rb >= 0
    moved = float(w.route().s[rb]) - x0
    assert moved > 10.0, moved  # before: B stood beside A, A could never change lanes
    assert f.klane[ra] == 1  # A is in its lane
    assert w.stats["collisions"] == 0


@pytest.mark.parametrize("method", ["multi-vp", "single-vp", "fcfs"])
def test_a_vehicle_stopped_at_an_angle_mid_lane_change_is_seen_by_the_lane_it_leaves(method):
    """3. The corridors listed a vehicle in a lane only if its centre was within
    half its width minus 0.3 m of it: a vehicle stopped at an angle in the middle
    of a lane change (centre 0.73 m past the lane line, a corner still 1.2 m in
    the old lane) was invisible to the follower there, which hit it (single-vp,
    4500 veh/h, seed 0)."""
    import math

    env = empty_env(method)
    w = env.world
    f = w.fleet
    lay = env.layout
    a = put(env, 0, 2, 2, -200.0, 0.0, tlane=2)
    b = put(env, 0, 1, 1, -235.0, 8.0, tlane=1)
    ra = f.rows([a])[0]
    # turn A 25 deg towards lane 2, as in the middle of a lane change 1 -> 2,
    # with its centre 0.73 m past the lane line (lat 8.73 m, line at 8 m)
    d0 = lay.app_dir[0]
    f.heading[ra] = math.atan2(d0[1], d0[0]) + math.radians(25.0)
    w._route = None
    lat = float(w.route().lat_leg[ra])
    shift = (8.73 - lat) * lay.app_right[0]
    f.x[ra] += shift[0]
    f.y[ra] += shift[1]
    w._route = None
    assert abs(float(w.route().lat_leg[ra]) - 8.73) < 1e-6
    f.stage[f.rows([a, b])] = ST_ADJUSTED
    w._route = None
    for _ in range(40):  # 8 s with A held still
        env.expert.update(w)
        act = env.expert.compute(w)
        act[f.rows([a])[0]] = [-1.0, 0.0]
        env._advance(act)
        f.speed[f.rows([a])[0]] = 0.0
    assert w.stats["collisions"] == 0, w.collision_log[:3]  # fcfs: 1 collision before the fix


def test_a_ready_vehicle_beside_another_in_its_target_lane_yields_and_changes_before_R1():
    """4. Two vehicles of different sub-formations side by side at 10 m/s, one
    of them needing the other's lane (multi-vp, 2000 veh/h, seed 2: vehicle
    24 in lane 0 wanting lane 1, vehicle 25 beside it there from 500 m to
    R1). Before the yield rule it reached R1 in the wrong lane, was rerouted
    to another movement and stood 11 s as a late node (2 jammed vehicles in
    the first 100 s). Now it drops back behind the other one and changes."""
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method="multi-vp", throughput=2000.0, duration=100.0, expert_in_info=False)
    env.reset(seed=2)
    w = env.core.world
    lay = env.core.layout
    changed_before_R1 = None
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
        r = w.fleet.rows(np.array([24]))[0]
        if r >= 0 and changed_before_R1 is None and w.route().dist[r] <= lay.R1:
            changed_before_R1 = int(w.fleet.klane[r]) == 1 and int(w.fleet.mv[r]) == 7
    m = env.metrics()
    assert changed_before_R1, "vehicle 24 reached R1 outside lane 1 or rerouted"
    assert env.core.expert.stats["lane_change_yields"] >= 1
    assert m["rerouted"] == 0 and m["jammed"] == 0 and m["collisions"] == 0


def test_a_waiting_lane_changer_is_not_held_by_a_member_alongside_it_in_the_lane_it_wants():
    """5. multi-vp, 2000 veh/h, seed 7: vehicle 187 (lane 1, wanting lane 0)
    stopped 306 m out, its turn signal listing it in lane 0, where member 190
    stood 0.6 m ahead of it keeping its slot 9 m *behind* 187. The envelope
    holds 187 behind 190 (its 'leader' in the wanted lane) and 190 behind its
    slot: both stand from 268 s to the end of the run (39 vehicles jammed
    behind them). The cause: when its sub-formation's front joined a node,
    the remaining members were ranked by distance and 187, 0.5 m ahead,
    became the first, so 190's slot went 9 m behind it. A member waiting to
    change lanes is now ranked behind a member alongside it in the lane it
    needs (Regrouping._order_keys); fails on 9bb0cf9."""
    from icv_envs.envs.intersection_v0 import parallel_env

    env = parallel_env(method="multi-vp", throughput=2000.0, duration=300.0, expert_in_info=False)
    env.reset(seed=7)
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    jammed = {int(j[1]) for j in env.core.world.jams.log}
    assert not jammed & {187, 190}, jammed
    assert env.metrics()["collisions"] == 0


def test_a_member_waiting_to_change_lanes_ranks_behind_a_member_alongside_it_in_that_lane():
    """The rank rule behind test 5 on a hand-built scene (Regrouping._order_keys):
    A in lane 1 needs lane 0, B stands in lane 0 0.5 m behind it (bodies
    overlapping): A ranks behind B. A clear ahead of B keeps its physical
    rank, and two members that would swap lanes keep theirs."""
    env = empty_env("multi-vp")
    w = env.world
    f = w.fleet
    ex = env.expert

    def keys(sa, sb, ta, tb, la=1, lb=0):
        for r in range(f.n):
            f.crashed[r] = True
        w.remove_crashed_vehicles()
        a = put(env, 0, la, 0 if ta == 0 else 1, sa, 0.0, tlane=ta)
        b = put(env, 0, lb, 0 if tb == 0 else 1, sb, 0.0, tlane=tb)
        w._route = None
        rows = f.rows([a, b])
        k = ex._order_keys(w, rows, w.route().dist[rows])
        return k[0], k[1]

    ka, kb = keys(-290.0, -290.5, ta=0, tb=0)
    assert ka > kb  # A (0.5 m ahead) ranks behind B
    ka, kb = keys(-280.0, -290.5, ta=0, tb=0)
    assert ka < kb  # A clear ahead of B (bumper gap > 0) keeps its rank
    ka, kb = keys(-290.0, -290.5, ta=0, tb=1)
    assert ka < kb  # swapping lanes: physical order


# --- the circular waits of the saturation sweep (stop 16) -------------------------------------------------


def _sub_of_two(env, lanes, dists, speed):
    """Two vehicles of leg 0, movement 2 (served by lanes 1 and 2), in one sub-formation."""
    lay = env.layout
    w = env.world
    vids = [put(env, 0, ln, 2, -(d - lay.box_half), speed, tlane=ln) for ln, d in zip(lanes, dists)]
    for k, (v, ln) in enumerate(zip(vids, lanes)):
        env.expert.on_spawn(w, v, "pair", 2.6 * k, ln)
    env.expert.update(w)  # division (inside R2)
    f = w.fleet
    rows = f.rows(vids)
    assert f.sub[rows[0]] >= 0 and f.sub[rows[0]] == f.sub[rows[1]]
    return vids, rows


def test_two_members_that_would_swap_lanes_exchange_their_targets():
    """multi-vp 4000 veh/h seed 0: two members side by side, each assigned the other's lane at division,
    stood from the warm-up to the end of the run (92 jammed behind them). They exchange targets now:
    neither changes lanes, both cross."""
    env = empty_env("multi-vp")
    w = env.world
    f = w.fleet
    vids, (ra, rb) = _sub_of_two(env, (1, 2), (326.0, 328.6), 0.0)
    # the division's assignment, crossed: each one's target is the other's lane
    f.tlane[ra], f.tlane[rb] = f.klane[rb], f.klane[ra]
    f.tidx[ra], f.tidx[rb] = f.tidx[rb], f.tidx[ra]
    env.expert.subs[int(f.sub[ra])]["state"] = "lc"
    lc0 = env.expert.stats["lane_changes"]
    run(env, 60.0)
    assert env.expert.stats["lane_changes"] == lc0  # no lane change was needed
    assert env.expert.stats["crossed_targets_swapped"] == 1
    rows = f.rows(vids)
    assert all(r < 0 or f.entered[r] for r in rows)
    assert w.stats["collisions"] == 0


def test_a_follower_ahead_of_its_reference_in_its_lane_drives_free():
    """multi-vp 3500 veh/h seed 0: a member 1 m ahead of its sub-formation's first vehicle, in that
    vehicle's lane, held its slot (ahead of the first, in the lane it could not change into) while
    the first stood behind it: 354 jammed, 738 veh/h. It drives free now."""
    from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_FREE

    env = empty_env("multi-vp")
    w = env.world
    f = w.fleet
    vids, (ra, rb) = _sub_of_two(env, (2, 2), (330.0, 323.0), 0.0)  # b is ahead of a in lane 2
    f.tlane[rb] = 1
    f.ref[ra], f.ref[rb] = -1, f.vid[ra]  # b follows a, slot 7 m ahead of a (interlaced, lane 1)
    f.xg[rb] = -7.0
    rs = w.route()
    env.expert._references(w, rs)  # the per-vehicle modes of this step
    assert env.expert._mode[rb] == MODE_FREE
    assert env.expert.stats["ahead_of_reference"] == 1
    # in another lane the same slot is followed as before
    f.klane[rb] = 1
    env.expert._references(w, rs)
    assert env.expert._mode[rb] == MODE_FOLLOW


def _signalling_pair(d_b, signal=True):
    env = empty_env("multi-vp")
    w = env.world
    f = w.fleet
    vids, (ra, rb) = _sub_of_two(env, (1, 2), (330.0, d_b), 0.0)  # A in lane 1, B in lane 2
    f.tlane[ra], f.tlane[rb] = 2, 2
    f.ref[ra], f.ref[rb] = -1, f.vid[ra]  # B follows A, slot 9 m behind A
    f.xg[rb] = 9.0
    f.want[ra] = 2 if signal else -1  # A signals into B's lane
    env.expert._references(w, w.route())
    return env.expert, rb


def test_a_follower_ahead_of_its_reference_in_the_lane_it_signals_into_drives_free():
    """multi-vp 3000 veh/h seed 23 (held-out): the sub-formation's first vehicle A, in lane 1, waited
    to change into lane 2 with its turn signal on; member B, in lane 2, 3 m ahead of A (alongside),
    had its slot 9 m behind A. A braked behind B (it is listed in lane 2), B stood waiting to drop
    back behind A: both stood from 450 s to the end of the run, 39 jammed behind them (fails on
    254fbaa, where only a follower in its reference's own lane drove free). B drives free now."""
    from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_FREE

    ex, rb = _signalling_pair(327.0)  # B 3 m ahead of A
    assert ex._mode[rb] == MODE_FREE
    assert ex.stats["ahead_of_reference"] == 1
    # without the signal, B (in another lane than A) keeps following its slot
    ex, rb = _signalling_pair(327.0, signal=False)
    assert ex._mode[rb] == MODE_FOLLOW
    # behind A in the signalled lane, B follows its slot as before
    ex, rb = _signalling_pair(333.0)
    assert ex._mode[rb] == MODE_FOLLOW
    assert ex.stats["ahead_of_reference"] == 0
