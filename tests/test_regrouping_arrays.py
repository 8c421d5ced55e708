"""``Regrouping._sub_distances`` (the sub-formations' least and largest
member distance to the centre in one lookup, used by the merging rule and by
the virtual platoon's entry test) against the per-sub-formation loop it
replaced, on every state of a multi-vp run."""

from __future__ import annotations

import numpy as np
import pytest

from icv_envs.envs.intersection_v0 import parallel_env


def test_sub_distances_equal_the_loop():
    env = parallel_env(method="multi-vp", throughput=3000.0, duration=120.0)
    obs, infos = env.reset(seed=4)
    ex, w = env.core.expert, env.core.world
    checked = 0
    while not env.episode_over:
        f, rs = w.fleet, w.route()
        sids, subs, dmin, dmax = ex._sub_distances(f, rs)
        want = [(sid, S, float(rs.dist[f.rows(S["members"])].min()), float(rs.dist[f.rows(S["members"])].max()))
                for sid, S in ex.subs.items()]
        assert [(a, b, c, d) for a, b, c, d in zip(sids, subs, dmin, dmax)] == want
        assert all(type(x) is float for x in dmin + dmax)
        checked += len(sids)
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    assert checked > 1000
    if ex.subs:
        next(iter(ex.subs.values()))["members"] = []
        with pytest.raises(ValueError, match="has no members"):
            ex._sub_distances(w.fleet, w.route())
