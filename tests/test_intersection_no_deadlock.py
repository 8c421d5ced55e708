"""The virtual platoon cannot lock up (issue 8): a property test of the tree
and its references over random arrivals, and the seed sweep (slow)."""

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from icv_envs.envs.intersection import IntersectionEnv


def assert_no_inverted_pair(core, ids=None):
    """For every pair of nodes ``i`` before ``k`` in the virtual platoon's order
    that conflict and come from the same leg, no vehicle of ``i`` still before
    the box is physically behind a vehicle of ``k`` in the same approach lane
    (it would hold ``k`` back while waiting behind it), and every node member
    before the box is in its expected lane with no lane change to make."""
    ex = core.expert
    w = core.world
    f = w.fleet
    rs = w.route()
    lay = core.layout
    ids = list(ex.node_order if ids is None else ids)
    rows = {k: f.rows(ex.nodes[k]["members"]) for k in ids if k in ex.nodes}
    for k, r in rows.items():
        r = r[(r >= 0) & (rs.phase[np.maximum(r, 0)] == 0)]
        assert np.all(f.klane[r] == f.tlane[r]), (k, f.vid[r], f.klane[r], f.tlane[r])
        assert np.all(f.lc_lane[r] < 0)
    for a, i in enumerate(ids):
        ri = rows[i][(rows[i] >= 0)]
        ri = ri[rs.phase[ri] == 0]
        if not len(ri):
            continue
        for k in ids[a + 1:]:
            mi, mk = ex.nodes[i]["mv"], ex.nodes[k]["mv"]
            if not lay.conflict[mi, mk] or lay.leg_of[mi] != lay.leg_of[mk]:
                continue
            rk = rows[k][rows[k] >= 0]
            rk = rk[rs.phase[rk] == 0]
            for r in ri:
                same = rk[rs.lane[rk] == rs.lane[r]]
                assert not np.any(rs.dist[same] < rs.dist[r] - 1e-6), (
                    f"node {i} (earlier) has vehicle {f.vid[r]} behind vehicle(s) {f.vid[same]} of node {k}")


def assert_bounds_come_from_ahead(core):
    """Every vehicle held by the bound ``rear_i + D_t`` of an earlier node is
    held by a vehicle that is not behind it in its own approach lane."""
    ex = core.expert
    T = ex._tree
    if T is None:
        return
    w = core.world
    f = w.fleet
    rs = w.route()
    rows_all, kk = ex._tree_rows
    bound = ex._tight[rows_all]
    for r, k in zip(rows_all[bound], kk[bound]):
        b = T["rear_row"][T["pred"][k]]
        if rs.phase[r] == 0 and rs.phase[b] == 0 and f.leg[b] == f.leg[r] and rs.lane[b] == rs.lane[r]:
            assert rs.dist[b] <= rs.dist[r] + 1e-6, (f.vid[r], f.vid[b])


# derandomized so that CI is reproducible; ICV_EXPLORE=1 draws fresh random
# examples, ICV_DEADLOCK_EXAMPLES=N sets how many (e.g. 200 for a long search).
# The explicit examples are regressions found by earlier random runs.
@settings(max_examples=int(os.environ.get("ICV_DEADLOCK_EXAMPLES", "6")), deadline=None,
          derandomize=os.environ.get("ICV_EXPLORE") != "1", suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), throughput=st.sampled_from([1500.0, 2500.0, 3500.0, 4500.0]),
       method=st.sampled_from(["multi-vp", "single-vp"]),
       shares=st.sampled_from([[1, 1, 1], [2, 1, 1], [1, 2, 1], [1, 1, 2]]),
       lane_use=st.sampled_from(["paper", "exclusive"]))
# a cleared single-vp member re-entered the order as a phantom node each step and
# pushed a node already in the box behind a conflicting one: 2 collisions
@example(seed=2761, throughput=2500.0, method="single-vp", shares=[2, 1, 1], lane_use="exclusive")
def test_tree_never_holds_a_node_behind_a_vehicle_behind_it(seed, throughput, method, shares, lane_use):
    # small zones so that vehicles reach the coordinating zone within seconds
    env = IntersectionEnv({"method": method, "throughput": throughput, "turn_shares": shares, "lane_use": lane_use,
                           "R1": 120.0, "R2": 200.0, "R3": 280.0, "duration": 80.0, "expert_in_info": False})
    env.ma_reset(seed=seed)
    w = env.world
    while w.time < 80.0 - 1e-9:
        env._ma_advance(env.expert_actions())
        if env.expert.nodes:
            assert_no_inverted_pair(env)
            assert_bounds_come_from_ahead(env)
    assert w.stats["collisions"] == 0


@pytest.mark.slow
def test_seed_sweep_has_no_collision_and_no_jam(tmp_path):
    """The issue's sweep: seeds 0-19 at 2000, 2500, 3000 veh/h, 600 s after a 100 s warm-up (whose
    collisions and jams count too), multi-vp, single-vp, fcfs (benchmarks/intersection_seeds.py runs
    the same with a table; README, "Intersection")."""
    from icv_envs.experiments.intersection_compare import compare_intersection

    s = compare_intersection(["multi-vp", "single-vp", "fcfs"], [2000.0, 2500.0, 3000.0], "0-19", 600.0, tmp_path,
                             progress=False, config={"warmup": 100.0})
    assert s["collisions"] == 0 and s["lost"] == 0
    assert s["jammed"] == 0, [(r["method"], r["throughput"], r["jammed"]) for r in s["table"] if r["jammed"]]
