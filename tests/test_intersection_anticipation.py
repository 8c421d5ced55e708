"""The virtual platoon's anticipation in the adjusting zone (issue 8).

A vehicle of the adjusting zone (``R2 >= dist > R1``) that drives free
tracks, with comfortable braking only, the reference it would get if its
node were made now (``VirtualPlatoon._anticipate``); a node of its own leg
with a vehicle behind it never bounds it (that bound was a circular wait:
multi-vp, 3000 veh/h, seed 1 jammed 331 vehicles without the rule).
"""

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env
from icv_envs.policies.platoon_common import MODE_TREE


def rollout(method, seconds, anticipate=True, seed=0, check=None):
    env = parallel_env(method=method, throughput=3000.0, duration=seconds, expert_in_info=False,
                       vp_anticipation=anticipate)
    env.reset(seed=seed)
    while not env.episode_over:
        acts = env.expert_actions()
        if check is not None:
            check(env.core)
        env.step({a: acts[a] for a in env.agents})
    m = env.metrics()
    env.close()
    return m


@pytest.mark.parametrize("method", ["multi-vp", "single-vp"])
def test_anticipating_vehicles_are_held_back_gently_by_a_node_they_do_not_block(method):
    seen = []

    def check(core):
        ex, w, lay = core.expert, core.world, core.layout
        rows, R, bound = ex._anticipation
        if not len(rows):
            return
        rs = w.route()
        f = w.fleet
        seen.append(len(rows))
        # in the adjusting zone, approaching, not in a node, its reference behind it
        assert np.all((rs.dist[rows] > lay.R1) & (rs.dist[rows] <= lay.R2))
        assert np.all((rs.phase[rows] == 0) & (f.node[rows] < 0))
        assert np.all(R > rs.X[rows])
        assert np.all(ex._mode[rows] == MODE_TREE) and not ex._tight[rows].any()
        # the bounding node is never one of its own leg with a vehicle behind it
        for r, nid in zip(rows.tolist(), bound.tolist()):
            if nid >= 0 and lay.leg_of[ex.nodes[nid]["mv"]] == f.leg[r]:
                assert rs.dist[f.rows(ex.nodes[nid]["members"])].max() < rs.dist[r]
        # the reference only holds back, and only with comfortable braking
        acc = ex._longitudinal(w, rs)
        assert np.all(acc[rows] >= ex.p.comfort[0] - 1e-9)

    m = rollout(method, 150.0, check=check)
    assert sum(seen) > 0, "the run never held a vehicle back in the adjusting zone"
    assert m["collisions"] == 0


def test_vp_anticipation_false_switches_it_off_and_is_validated():
    counts = []
    rollout("single-vp", 60.0, anticipate=False,
            check=lambda core: counts.append(core.expert.stats["anticipating"]))
    assert counts and max(counts) == 0
    with pytest.raises(ValueError, match="vp_anticipation"):
        parallel_env(vp_anticipation="yes")
