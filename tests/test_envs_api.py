"""API conformance: PettingZoo's and Gymnasium's own checkers, registries,
spaces that match what is returned."""

import gymnasium as gym
import numpy as np
import pettingzoo
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test

import icv_envs
from icv_envs import highway_formation_v0


@pytest.mark.parametrize("scenario", ["free", "lane-drop", "lane-change", "off-ramp", "on-ramp"])
def test_parallel_api(scenario):
    parallel_api_test(highway_formation_v0.parallel_env(scenario=scenario), num_cycles=300)


def test_parallel_api_with_agents_joining_mid_episode():
    env = highway_formation_v0.parallel_env(
        scenario="on-ramp", spawns=[{"time": 2.0, "position": 320.0, "lane": "ramp", "speed": 15.0}]
    )
    obs, _ = env.reset(seed=0)
    assert "icv_6" not in obs and "icv_6" in env.possible_agents
    seen = False
    for _ in range(20):
        obs, *_ = env.step({a: env.action_space(a).sample() * 0 for a in env.agents})
        seen |= "icv_6" in obs
    assert seen and "icv_6" in env.agents
    parallel_api_test(
        highway_formation_v0.parallel_env(
            scenario="on-ramp", spawns=[{"time": 2.0, "position": 320.0, "lane": "ramp", "speed": 15.0}]
        ),
        num_cycles=100,
    )


def test_aec_api():
    api_test(highway_formation_v0.env(scenario="off-ramp"), num_cycles=100)
    raw = highway_formation_v0.raw_env()
    raw.reset(seed=0)
    assert raw.agents


def test_gymnasium_check_env_and_make():
    env = gym.make("icv_envs/HighwayFormation-v0")
    check_env(env.unwrapped, skip_render_check=True)
    env2 = gym.make("icv_envs:icv_envs/HighwayFormation-v0", config={"scenario": "lane-drop"})
    obs, info = env2.reset(seed=3)
    assert env2.observation_space.contains(obs)
    assert obs.dtype == np.float32 and obs.shape == (8, 13)
    obs, r, term, trunc, info = env2.step(info["expert_action"])
    assert env2.observation_space.contains(obs)
    assert isinstance(r, float) and set(info["rewards"]) == {"progress", "safety", "comfort", "formation"}


def test_pettingzoo_registry():
    assert "icv_envs/highway_formation-v0" in pettingzoo.parallel_registry
    assert "icv_envs/highway_formation-v0" in pettingzoo.aec_registry
    p = pettingzoo.make("parallel", "icv_envs/highway_formation-v0", scenario="lane-drop")
    assert isinstance(p, highway_formation_v0.HighwayFormationParallelEnv)
    a = pettingzoo.make("aec", "icv_envs/highway_formation-v0")
    a.reset(seed=0)
    assert a.agent_selection in a.agents
    assert set(icv_envs.GYM_IDS) <= set(gym.registry)


def test_spaces_same_object_and_match_returns():
    env = highway_formation_v0.parallel_env(scenario="on-ramp")
    obs, infos = env.reset(seed=0)
    spaces_o = {id(env.observation_space(a)) for a in env.possible_agents}
    spaces_a = {id(env.action_space(a)) for a in env.possible_agents}
    assert len(spaces_o) == 1 and len(spaces_a) == 1
    for _ in range(10):
        for a, o in obs.items():
            assert env.observation_space(a).contains(o), a
            assert o.dtype == env.observation_space(a).dtype
        ex = env.expert_actions()
        for a in env.agents:
            act = infos[a]["expert_action"]
            assert env.action_space(a).contains(act) and act.dtype == np.float32
            np.testing.assert_array_equal(act, ex[a])
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    s = env.state()
    assert env.state_space.contains(s) and s.shape == (len(env.possible_agents), 13)
    assert s[:, 0].sum() == len(env.agents)


def test_missing_action_policy():
    env = highway_formation_v0.parallel_env(scenario="lane-drop")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no action for live agents"):
        env.step({env.agents[0]: np.zeros(2)})
    env2 = highway_formation_v0.parallel_env(scenario="lane-drop", missing_action="expert")
    env2.reset(seed=0)
    obs, *_ = env2.step({env2.agents[0]: np.zeros(2)})
    assert len(obs) == 8


def test_gym_ego_is_driven_by_action():
    env = gym.make("icv_envs/HighwayFormation-v0", config={"ego_vehicle": 2})
    env.reset(seed=0)
    core = env.unwrapped
    v0 = core.world.traffic.speed[core._ego_row()]
    for _ in range(5):
        env.step(np.array([-1.0, 0.0], dtype=np.float32))  # full braking
    v1 = core.world.traffic.speed[core._ego_row()]
    assert v0 - 6.0 - 1e-6 <= v1 < v0 - 5.5  # 1 s at -6 m/s^2


def test_episode_truncates_at_duration():
    env = highway_formation_v0.parallel_env(duration=2.0)
    env.reset(seed=0)
    steps = 0
    while env.agents:
        _, _, _, trunc, _ = env.step(env.expert_actions())
        steps += 1
    assert steps == 10 and all(trunc.values())


def test_agent_names_come_from_possible_agents_and_beyond():
    """``_names`` looks the names up in ``possible_agents`` and formats the
    ids beyond it: the same strings either way."""
    from icv_envs.envs import highway_formation_v0

    env = highway_formation_v0.parallel_env(vehicles_count=6)
    env.reset(seed=0)
    core = env.core
    n = len(core.possible_agents)
    for vids in ([], [0, 3, 5], [5, 0, 2], [0, n - 1], [1, n, n + 7]):
        assert core._names(vids) == [f"icv_{v}" for v in vids]
    assert core._names([2])[0] is core.possible_agents[2]
