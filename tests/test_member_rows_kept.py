"""The virtual platoon's member rows (VirtualPlatoon._member_rows) are kept
between calls while the fleet's rows and the nodes' member lists are the
same objects (issue 10, stop 40): the kept answer must equal a fresh one at
every step of a run, and any change of the nodes or of the fleet must be
seen."""

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env


def _fresh(ex, f):
    kept = ex._member_rows_kept
    ex._member_rows_kept = None
    try:
        return ex._member_rows(f)
    finally:
        ex._member_rows_kept = kept


def _same(a, b):
    assert list(a[0]) == list(b[0])
    for x, y in zip(a[1:], b[1:]):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("method, seed", [("multi-vp", 3), ("single-vp", 4)])
def test_kept_member_rows_equal_fresh_ones_along_a_run(method, seed):
    env = parallel_env(method=method, throughput=2500.0, duration=120.0)
    obs, infos = env.reset(seed=seed)
    ex, w = env.core.expert, env.core.world
    hits = 0
    for t in range(550):  # (the first nodes form after about 50 s: vehicles enter 800 m out)
        if env.episode_over:
            break
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
        if not ex.nodes or t < 250:
            continue
        f = w.fleet
        before = ex._member_rows_kept
        got = ex._member_rows(f)
        hits += ex._member_rows_kept is before
        _same(got, _fresh(ex, f))
        assert not got[1].flags.writeable and not got[2].flags.writeable and not got[3].flags.writeable
    assert hits > 10  # the kept answer was used


def test_a_replaced_member_list_or_a_new_fleet_is_seen():
    env = parallel_env(method="multi-vp", throughput=3000.0, duration=120.0)
    obs, infos = env.reset(seed=5)
    ex, w = env.core.expert, env.core.world
    while not any(len(N["members"]) > 1 for N in ex.nodes.values()):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    f = w.fleet
    ids, rows, seg, sizes = ex._member_rows(f)
    nid = next(k for k, N in ex.nodes.items() if len(N["members"]) > 1)
    N = ex.nodes[nid]
    N["members"] = N["members"][:-1]  # a node loses its last member (a new list, as the expert does it)
    _, rows2, _, sizes2 = ex._member_rows(f)
    assert len(rows2) == len(rows) - 1 and sizes2.sum() == sizes.sum() - 1
    _same(ex._member_rows(f), _fresh(ex, f))
    f.vid = f.vid.copy()  # the fleet's rows replaced (a spawn or removal makes a new array)
    assert ex._member_rows_kept[0][0] is not f.vid  # (the kept key's fleet rows)
    ex._member_rows(f)
    assert ex._member_rows_kept[0][0] is f.vid


def _fresh_sub_distances(ex, f, rs):
    kept = ex._sub_distances_kept
    ex._sub_distances_kept = None
    try:
        return ex._sub_distances(f, rs)
    finally:
        ex._sub_distances_kept = kept


@pytest.mark.parametrize("method, seed", [("multi-vp", 3), ("multi-vp", 8)])
def test_kept_sub_distances_equal_fresh_ones_along_a_run(method, seed):
    """Regrouping._sub_distances keeps its last answer while the fleet's
    rows, the route state and the sub-formations' member lists are the
    same objects: equal to a fresh answer at every step, and a replaced
    member list or a new route state is seen."""
    env = parallel_env(method=method, throughput=2500.0, duration=120.0)
    obs, infos = env.reset(seed=seed)
    ex, w = env.core.expert, env.core.world
    hits = 0
    for t in range(400):
        if env.episode_over:
            break
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
        if not ex.subs:
            continue
        f, rs = w.fleet, w.route()
        before = ex._sub_distances_kept
        got = ex._sub_distances(f, rs)
        hits += ex._sub_distances_kept is before
        want = _fresh_sub_distances(ex, f, rs)
        assert got[0] == want[0] and got[2] == want[2] and got[3] == want[3]
    assert hits > 10
    f, rs = w.fleet, w.route()
    sid = next(k for k, S in ex.subs.items() if len(set(rs.dist[f.rows(S["members"])].tolist())) > 1)
    k = list(ex.subs).index(sid)
    before = ex._sub_distances(f, rs)
    S = ex.subs[sid]
    S["members"] = S["members"][:1]  # a new list, as the expert replaces them: min and max now equal
    got = ex._sub_distances(f, rs)
    assert got[2][k] == got[3][k] and (got[2][k], got[3][k]) != (before[2][k], before[3][k])
    assert got[2] == _fresh_sub_distances(ex, f, rs)[2]
    w.invalidate()  # a new route state
    rs2 = w.route()
    ex._sub_distances(f, rs2)
    assert ex._sub_distances_kept[0][1] is rs2  # (the kept key's route state)
