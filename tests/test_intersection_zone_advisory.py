"""The virtual platoon's speed advisory inside the coordinating zone (issue 8).

A node vehicle whose reference lies further behind it than comfortable
braking absorbs, and whose braking distance would end more than
``QUEUE_GAP`` before the stop line, drives at ``v0 L / (L + H)`` (it meets a
reference moving at ``v0`` at the stop line) instead of standing for it
right after ``R1`` (``VirtualPlatoon._references``, the advisory inside R1).  Before the rule,
those stands were the virtual platoon's only jams on the 20-seed sweep.
"""

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.experiments.intersection_compare import run_intersection
from icv_envs.policies.platoon_common import MODE_TREE
from icv_envs.sim.intersection_metrics import QUEUE_GAP


def test_zone_advisory_invariants_over_a_busy_run():
    seen = []
    env = parallel_env(method="multi-vp", throughput=3000.0, duration=200.0, expert_in_info=False)
    env.reset(seed=3)
    while not env.episode_over:
        acts = env.expert_actions()
        ex, w, lay = env.core.expert, env.core.world, env.core.layout
        rows, v_adv, H, v_tree = ex._zone_advised
        if len(rows):
            rs = w.route()
            f = w.fleet
            p = ex.p
            seen.append(len(rows))
            # node members before the box, their reference behind them by more than braking absorbs
            assert np.all((f.node[rows] >= 0) & (rs.phase[rows] == 0))
            room = f.speed[rows] ** 2 / (2 * abs(p.comfort[0]))
            assert np.all(H > room)
            L = np.maximum(-rs.u[rows] - 0.5 * f.length[rows] - p.stop_margin, 0.0)
            # only where standing would leave it away from the stop line
            assert np.all(L - room > QUEUE_GAP)
            np.testing.assert_allclose(v_adv, p.v0 * L / (L + H))
            assert np.all((v_adv > 0) & (v_adv < p.v0))
            # tracked without position error, comfortable braking, never into the box while advised
            assert np.all(ex._mode[rows] == MODE_TREE) and not ex._tight[rows].any()
            np.testing.assert_array_equal(ex._xref[rows], rs.X[rows])
            np.testing.assert_array_equal(ex._vref[rows], v_adv)
            assert ex._stop[rows].all()
            # the observation keeps reporting the tree's reference, not the advisory
            has, d, dv, _ = ex.references(w)
            assert has[rows].all()
            np.testing.assert_allclose(d[rows], -H)
            np.testing.assert_allclose(dv[rows], v_tree - f.speed[rows])
            acc = ex._longitudinal(w, rs)
            assert np.all(acc[rows] >= np.minimum(p.comfort[0], ex._vcap[rows]) - 1e-9)
        env.step({a: acts[a] for a in env.agents})
    m = env.metrics()
    env.close()
    assert sum(seen) > 0, "the run never advised a node vehicle inside R1"
    assert ex.stats["advised_in_zone"] >= sum(seen)
    assert m["collisions"] == 0


@pytest.mark.parametrize("method, seed, seconds", [
    # multi-vp, 3000 veh/h, seed 16: nine vehicles jammed at R1 from t = 81 s (after the warm-up) before the rule
    ("multi-vp", 16, 100.0),
    # single-vp, 3000 veh/h, seed 14: three jammed at R1 from t = 211 s
    ("single-vp", 14, 230.0),
])
def test_no_stand_at_R1_with_the_zone_advisory(method, seed, seconds):
    """Each case jammed without the rule (checked here, so the test can fail) and does not with it."""
    cfg = {"warmup": 100.0}
    off = run_intersection(method, 3000.0, seed, seconds, dict(cfg, vp_zone_advisory=False))
    assert off["jammed"] + off["warmup_jammed"] > 0
    assert all(j[2] > 250.0 for j in off["jam_log"])  # they stood at the entry of R1 (300 m)
    on = run_intersection(method, 3000.0, seed, seconds, cfg)
    assert on["collisions"] == 0 and on["warmup_collisions"] == 0
    assert on["jammed"] == 0 and on["warmup_jammed"] == 0, on["jam_log"][:5]


def test_vp_zone_advisory_false_switches_it_off_and_is_validated():
    env = parallel_env(method="single-vp", throughput=3000.0, duration=60.0, expert_in_info=False,
                       vp_zone_advisory=False)
    env.reset(seed=3)
    while not env.episode_over:
        acts = env.expert_actions()
        assert not len(env.core.expert._zone_advised[0])
        env.step({a: acts[a] for a in env.agents})
    assert env.core.expert.stats["advised_in_zone"] == 0
    env.close()
    with pytest.raises(ValueError, match="vp_zone_advisory"):
        parallel_env(vp_zone_advisory="yes")


def test_a_follower_keeps_its_slot_relative_to_the_nodes_first_vehicle():
    """Once the members ahead of it have left the road, a node's first vehicle
    is a later slot; a follower's reference is its slot relative to that one
    (multi-vp, 3000 veh/h, seed 2: with the absolute slot a member stopped in
    the box at t = 318-322 s and the whole virtual platoon stood, 9 vehicles
    jammed at R1 from t = 331 s after the warm-up)."""
    env = parallel_env(method="multi-vp", throughput=3000.0, duration=345.0, warmup=100.0, expert_in_info=False)
    env.reset(seed=2)
    shifted = 0
    while not env.episode_over:
        acts = env.expert_actions()
        ex, w = env.core.expert, env.core.world
        rows, kk = ex._tree_rows
        if len(rows):
            f, rs = w.fleet, w.route()
            first = ex._tree["first"][kk]
            fol = (rows != first) & ~ex._tight[rows] & (ex._mode[rows] == MODE_TREE)
            fol &= ~np.isin(rows, ex._zone_advised[0])
            r, fr = rows[fol], first[fol]
            np.testing.assert_allclose(ex._xref[r], rs.X[fr] + f.xg[r] - f.xg[fr])
            shifted += int((f.xg[fr] != 0).sum())
        env.step({a: acts[a] for a in env.agents})
    m = env.metrics()
    env.close()
    assert shifted > 0, "no node lost its slot-0 member while followers were in the tree"
    assert m["collisions"] == 0 and m["jammed"] == 0, m["jam_log"][:5]
