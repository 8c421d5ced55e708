"""Errors name the key the user set, and defaults follow lanes_count (issue 11, item 13;
found by a randomised run of the config fuzz)."""

import numpy as np
import pytest

from icv_envs.envs import highway_formation_v0, highway_ramps_v0
from icv_envs.envs.highway_ramps import formation_lanes_for, lane_speeds_for


@pytest.mark.parametrize("lanes", [1, 2, 3, 5, 6])
@pytest.mark.parametrize("method", ["formation", "idm", "lane-lp"])
def test_ramps_with_another_lane_count_run_on_derived_defaults(lanes, method):
    env = highway_ramps_v0.parallel_env(lanes_count=lanes, method=method, duration=10.0)
    env.reset(seed=0)
    while env.agents:
        env.step({a: np.zeros(2) for a in env.agents})
    assert len(lane_speeds_for(lanes)) == lanes and lane_speeds_for(lanes)[-1] == (20.0 if lanes > 1 else 25.0)
    assert all(0 <= k < lanes for k in formation_lanes_for(lanes))
    assert lane_speeds_for(4) == [25.0, 25.0, 25.0, 20.0] and formation_lanes_for(4) == [0, 1, 2]


@pytest.mark.parametrize("cfg, names", [
    ({"scenario": "lane-drop"}, ["scenario", "HighwayRamps"]),
    ({"scenario": "x"}, ["scenario", "HighwayRamps"]),
    ({"lane_speeds": [25.0, 20.0]}, ["lane_speeds", "lanes_count = 4"]),
    ({"lanes_count": 2, "formation_lanes": [0, 1, 2]}, ["formation_lanes", "lanes_count = 2"]),
])
def test_ramps_errors_name_the_key_set(cfg, names):
    with pytest.raises(ValueError) as e:
        highway_ramps_v0.parallel_env(**cfg)
    assert all(n in str(e.value) for n in names), str(e.value)


def test_exit_error_names_exits_and_says_why():
    with pytest.raises(ValueError, match=r"config\['exits'\]\[0\] = 0.*no off-ramp"):
        highway_formation_v0.parallel_env(exits={0: 0})


def test_intersection_reward_speed_range_maps_the_progress_term_as_highway_env_does():
    """``reward_speed_range = [lo, hi]``: progress = clip((v - lo) / (hi - lo), 0, 1); None = v / v_max."""
    import numpy as np

    from icv_envs.envs.intersection_v0 import parallel_env

    for rsr in (None, [0.0, 10.0], [5, 15]):
        env = parallel_env(throughput=1500, duration=20, warmup=15, reward_speed_range=rsr)
        env.reset(seed=0)
        for _ in range(5):
            a = env.expert_actions()
            _, _, _, _, infos = env.step({g: a[g] for g in env.agents})
        f = env.core.world.fleet
        lo, hi = rsr or (0.0, 20.0)
        assert env.agents
        for ag in env.agents:  # agent icv_<k> drives vehicle id k
            v = float(f.speed[f.rows([int(ag.split("_")[1])])[0]])
            assert infos[ag]["rewards"]["progress"] == pytest.approx(np.clip((v - lo) / (hi - lo), 0.0, 1.0))
    for bad in ([10, 0], [0, 30], "fast", [0, True], [0, float("nan")]):
        with pytest.raises(ValueError, match="reward_speed_range"):
            parallel_env(reward_speed_range=bad).reset(seed=0)
