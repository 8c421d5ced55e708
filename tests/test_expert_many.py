"""The formation expert of several worlds in one pass
(icv_envs.policies.formation_expert_many, issue 10 from stop 46): every
world gets the actions and the lane-change state its own expert gives it
alone, bit for bit, through the batched worlds and directly."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, reject, settings
from hypothesis import strategies as st

from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0
from icv_envs.envs.base import IcvAgentsEnv
from icv_envs.policies.formation_expert import FormationExpert
from icv_envs.policies.formation_expert_many import compute_many
from icv_envs.vector import BatchedWorlds

LC = ("lc_lane", "lc_x0", "lc_y0", "lc_y1", "lc_len")


def _twins(env, cfg, B, seed):
    a = BatchedWorlds(B, env=env, config=cfg, seed=seed, expert=True)
    b = BatchedWorlds(B, env=env, config=cfg, seed=seed, expert=True)
    b._expert_many = False  # each world's expert_actions(), one by one
    return a, b


# (lane-drop, seed 3, 6 worlds: a lane change that strays and starts again
# in the same lane within one step, at step 97, which a first version wrote
# back to no world)
@pytest.mark.parametrize("env, cfg, B, seed, steps", [
    ("highway_formation", {"scenario": "lane-drop"}, 6, 3, 110),
    ("highway_formation", {"scenario": "off-ramp"}, 4, 3, 200),
    ("highway_ramps", {"vgr": 0.5, "duration": 60.0}, 3, 3, 200),
])
def test_batched_worlds_expert_in_one_pass_equals_one_by_one(env, cfg, B, seed, steps):
    a, b = _twins(env, cfg, B, seed)
    a.reset()
    b.reset()
    assert a.expert_actions.tobytes() == b.expert_actions.tobytes()
    rng = np.random.default_rng(seed)
    changes = 0
    for t in range(steps):
        # the expert's actions mostly, random ones every fourth step (lane changes stray and re-plan)
        acts = a.expert_actions.copy() if t % 4 else rng.uniform(-1, 1, a._act_shape).astype(np.float32)
        oa, ob = a.step(acts), b.step(acts)
        for x, y in zip(oa[:5], ob[:5]):
            assert x.tobytes() == y.tobytes(), t
        assert a.expert_actions.tobytes() == b.expert_actions.tobytes(), t
        for ea, eb in zip(a.envs, b.envs):
            ta, tb = ea.core.world.traffic, eb.core.world.traffic
            for k in LC + ("x", "y", "speed"):
                assert getattr(ta, k).tobytes() == getattr(tb, k).tobytes(), (t, k)
            changes += int(np.count_nonzero(ta.lc_lane >= 0))
    assert changes > 0  # vehicles did change lanes


def _env_pairs():
    """Twin cores (same config and seed) of worlds that group differently:
    two lane-drop worlds, an off-ramp one (another road), a ring with the
    formation method, one with IDM (another expert), an intersection and a
    world without vehicles."""
    specs = [(highway_formation_v0, {"scenario": "lane-drop"}, 0), (highway_formation_v0, {"scenario": "lane-drop"}, 1),
             (highway_formation_v0, {"scenario": "off-ramp"}, 2),
             (highway_ramps_v0, {"vgr": 0.5, "duration": 30.0}, 3),
             (highway_ramps_v0, {"vgr": 0.5, "duration": 30.0, "method": "idm"}, 4),
             (intersection_v0, {"duration": 20.0}, 5), (highway_formation_v0, {"vehicles_count": 3}, 6)]
    pairs = []
    for mod, cfg, seed in specs:
        twins = []
        for _ in range(2):
            e = mod.parallel_env(**cfg)
            e.reset(seed=seed)
            for _ in range(25):
                ex = e.expert_actions()
                e.step({k: ex[k] for k in e.agents})
            twins.append(e.core)
        pairs.append(twins)
    for core in pairs[-1]:  # no vehicles left
        w = core.world
        w.traffic.remove(np.ones(w.traffic.n, dtype=bool))
        w._index = None
    return pairs


def test_expert_actions_many_equals_each_expert_actions_on_mixed_worlds():
    pairs = _env_pairs()
    got = IcvAgentsEnv.expert_actions_many([p[0] for p in pairs])
    for (ca, cb), ex in zip(pairs, got):
        want = cb.expert_actions()
        assert ex.dtype == want.dtype == np.float32 and ex.tobytes() == want.tobytes()
        assert not ex.flags.writeable
        assert ca.expert_actions() is ex  # kept as the core's own answer for this state
        if hasattr(ca.world, "road"):  # (the highway worlds: the expert's lane-change state)
            for k in LC:
                assert getattr(ca.world.traffic, k).tobytes() == getattr(cb.world.traffic, k).tobytes()
    # asked again in the same state: the kept arrays
    again = IcvAgentsEnv.expert_actions_many([p[0] for p in pairs])
    assert all(x is y for x, y in zip(again, got))


def test_compute_many_takes_a_subclass_alone_and_checks_its_arguments():
    class Tweaked(FormationExpert):
        def _lane_speeds(self, road, lane):
            return super()._lane_speeds(road, lane) - 1.0

    pairs = []
    for seed in (0, 1):
        cores = []
        for _ in range(2):
            e = highway_formation_v0.parallel_env(scenario="lane-drop")
            e.reset(seed=seed)
            cores.append(e.core)
        pairs.append(cores)
    experts = [Tweaked(pairs[0][0].expert.p), pairs[1][0].expert]
    got = compute_many(experts, [pairs[0][0].world, pairs[1][0].world])
    want = [Tweaked(pairs[0][1].expert.p).compute(pairs[0][1].world), pairs[1][1].expert.compute(pairs[1][1].world)]
    for g, w in zip(got, want):
        assert g.dtype == np.float64 and g.tobytes() == w.tobytes()
    with pytest.raises(ValueError, match="2 experts for 1 worlds"):
        compute_many(experts, [pairs[0][0].world])


@settings(max_examples=int(os.environ.get("ICV_HYPOTHESIS_EXAMPLES", "8")), deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(scenario=st.sampled_from(["free", "lane-drop", "lane-change", "off-ramp", "on-ramp"]),
       lanes=st.integers(2, 5), vehicles=st.integers(2, 24), B=st.integers(2, 4), seed=st.integers(0, 2**16),
       random_every=st.integers(2, 6))
def test_expert_in_one_pass_equals_one_by_one_over_roads_and_fleets(scenario, lanes, vehicles, B, seed, random_every):
    """Any scenario, lane count and fleet: the batch's expert actions and every
    world's state equal those of asking each world's expert alone, 40 steps
    of the expert's actions with random ones mixed in."""
    cfg = {"scenario": scenario, "lanes_count": lanes, "vehicles_count": vehicles, "duration": 8.0}
    try:
        a, b = _twins("highway_formation", cfg, B, seed)
    except ValueError:  # a scenario's road that this lane count cannot hold (its own error)
        reject()
    a.reset()
    b.reset()
    rng = np.random.default_rng(seed)
    for t in range(40):
        acts = rng.uniform(-1, 1, a._act_shape).astype(np.float32) if t % random_every == 0 else \
            a.expert_actions.copy()
        oa, ob = a.step(acts), b.step(acts)
        assert all(x.tobytes() == y.tobytes() for x, y in zip(oa[:5], ob[:5])), t
        assert a.expert_actions.tobytes() == b.expert_actions.tobytes(), t
        for ea, eb in zip(a.envs, b.envs):
            for k in LC:
                assert getattr(ea.core.world.traffic, k).tobytes() == getattr(eb.core.world.traffic, k).tobytes()


@pytest.mark.parametrize("act, expert", [("FormationResidual", False), ("FormationResidual", True),
                                         ("ContinuousAction", False)])
def test_formation_residual_worlds_ask_their_experts_together(act, expert):
    """FormationResidual (the expert's action plus a learned residual) asks
    the expert at the start of every step; the batch asks all its worlds'
    experts together first: the same trajectories as each world asking its
    own. Worlds of other action types are not asked (asking changes the
    expert's lane-change state)."""
    cfg = {"scenario": "lane-drop", "action": {"type": act}}
    a = BatchedWorlds(4, config=cfg, seed=9, expert=expert)
    b = BatchedWorlds(4, config=cfg, seed=9, expert=expert)
    b._expert_many = False
    a.reset()
    b.reset()
    rng = np.random.default_rng(9)
    lc = 0
    for t in range(120):
        acts = rng.uniform(-1, 1, a._act_shape)
        oa, ob = a.step(acts), b.step(acts)
        assert all(x.tobytes() == y.tobytes() for x, y in zip(oa[:5], ob[:5])), t
        for ea, eb in zip(a.envs, b.envs):
            ta, tb = ea.core.world.traffic, eb.core.world.traffic
            for k in LC + ("x", "y", "speed"):
                assert getattr(ta, k).tobytes() == getattr(tb, k).tobytes(), (t, k)
            lc += int(np.count_nonzero(ta.lc_lane >= 0))
    assert lc > 0 or act == "ContinuousAction"  # (learned actions: nobody asks the expert, no plan)


def test_a_world_listed_twice():
    """``compute_many`` refuses a world listed twice (one pass would compute
    it twice from the same state, where asking twice in turn does not);
    ``expert_actions_many`` asks an env listed twice once, as asking its
    ``expert_actions()`` twice does."""
    envs = []
    for _ in range(2):
        e = highway_formation_v0.parallel_env(scenario="lane-drop")
        e.reset(seed=4)
        envs.append(e.core)
    with pytest.raises(ValueError, match=r"worlds\[2\] is worlds\[0\]; allowed: distinct worlds"):
        compute_many([envs[0].expert, envs[1].expert, envs[0].expert],
                     [envs[0].world, envs[1].world, envs[0].world])
    got = IcvAgentsEnv.expert_actions_many([envs[0], envs[0]])
    assert got[0] is got[1] is envs[0].expert_actions()
    assert got[0].tobytes() == envs[1].expert_actions().tobytes()


def test_group_tags_join_equal_keys_only_and_survive_forgetting(monkeypatch):
    """Stop 48: a world's group key is a tag, the same int for worlds whose
    experts and roads are equal by value (the worlds of one batch share one
    pass), another for other parameters or another road; when the table is
    forgotten (it is capped), new tags never repeat an old one, so worlds
    tagged before and after can only be parted, never joined."""
    import dataclasses

    from icv_envs.policies import formation_expert_many as fm

    def cores(scenario, seed, **p):
        e = highway_formation_v0.parallel_env(scenario=scenario)
        e.reset(seed=seed)
        core = e.core
        if p:
            core.expert.p = dataclasses.replace(core.expert.p, **p)
        return core

    a, b = cores("lane-drop", 0), cores("lane-drop", 1)
    c = cores("off-ramp", 0)
    d = cores("lane-drop", 2, desired_speed=a.expert.p.desired_speed + 1.0)
    ta, tb, tc, td = (fm._group_key(x.expert, x.world) for x in (a, b, c, d))
    assert isinstance(ta, int) and ta == tb and len({ta, tc, td}) == 3
    # forgetting the table: a fresh world equal to a and b gets a new tag, parted from them, never another key's
    monkeypatch.setattr(fm, "_TAGS", {})
    e = cores("lane-drop", 3)
    te = fm._group_key(e.expert, e.world)
    assert te not in (ta, tc)
    # a batch still gets each world's own actions (the parted world alone, the others together)
    worlds = [a.world, b.world, c.world, e.world]
    got = compute_many([x.expert for x in (a, b, c, e)], worlds)
    assert len(got) == 4 and all(g.shape == (x.traffic.n, 2) for g, x in zip(got, worlds))
