"""Bad input gets a clear error naming the value and what is allowed."""

import gymnasium as gym
import numpy as np
import pytest

from icv_envs import highway_formation_v0
from icv_envs.cli import main
from icv_envs.policies import make_policy


def make(**config):
    return highway_formation_v0.parallel_env(**config)


@pytest.mark.parametrize(
    "config, match",
    [
        ({"lanes_count": 0}, r"lanes_count.*= 0.*integer in \[1, 6\]"),
        ({"lanes_count": -2}, r"lanes_count.*-2"),
        ({"lanes_count": 7}, r"lanes_count.*7.*\[1, 6\]"),
        ({"lanes_count": 2.5}, r"lanes_count.*2\.5"),
        ({"vehicles_count": 0}, r"vehicles_count.*0"),
        ({"speed_range": [-5.0, 30.0]}, r"speed_range.*-5"),
        ({"speed_range": [20.0, 10.0]}, r"speed_range"),
        ({"formation": {"speed": -25.0}}, r"speed.*-25"),
        ({"formation": {"spacing": 0.0}}, r"spacing.*0\.0.*> 0"),
        ({"formation": {"w2": -1.0}}, r"w2.*-1"),
        ({"formation": {"geometry": "diamond"}}, r"geometry.*diamond.*interlaced"),
        ({"formation": {"bogus": 1}}, r"unknown formation keys.*bogus"),
        ({"policy_frequency": 0}, r"policy_frequency.*0"),
        ({"policy_frequency": -5}, r"policy_frequency.*-5"),
        ({"simulation_frequency": -25}, r"simulation_frequency.*-25"),
        ({"policy_frequency": 7}, r"policy_frequency=7 must divide"),
        ({"duration": -1.0}, r"duration.*-1"),
        ({"ramp_speed": -15.0}, r"ramp_speed.*-15"),
        ({"scenario": "tunnel"}, r"unknown scenario 'tunnel'.*lane-drop"),
        ({"lane_drop": {"position": 500.0, "lanes": 4}}, r"lanes.*4.*\[1, lanes_count - 1 = 3\]"),
        ({"obstacle": {"lane": 9, "position": 500.0}}, r"lane.*9"),
        ({"off_ramp": {"position": 800.0, "length": 50.0}, "exits": {0: 3}}, r"exit 3.*does not exist"),
        ({"exits": {0: 0}}, r"exit 0.*does not exist.*\[\]"),
        ({"spawns": [{"time": 1.0, "position": 10.0, "lane": "ramp"}]}, r"needs an on_ramp"),
        ({"spawns": [{"time": 1.0, "position": 10.0, "lane": 0, "speed": -3.0}]}, r"speed.*-3"),
        ({"reward": {"speed": 1.0}}, r"unknown reward keys.*speed"),
        ({"missing_action": "ignore"}, r"missing_action.*ignore"),
        ({"colour": "red"}, r"unknown config keys.*colour"),
        ({"ego_vehicle": 99}, r"ego_vehicle.*99"),
    ],
)
def test_bad_config(config, match):
    with pytest.raises(ValueError, match=match):
        make(**config)


def test_more_vehicles_than_the_road_holds():
    with pytest.raises(ValueError, match=r"vehicles_count=500 does not fit.*at most about \d+ vehicles"):
        make(vehicles_count=500, road_length=1000.0)
    # placed automatically it fits on a long enough road, and not on a short one
    make(vehicles_count=100, initial_position=None, road_length=5000.0)
    with pytest.raises(ValueError, match="does not fit"):
        make(vehicles_count=400, initial_position=None, road_length=2000.0)


def test_bad_render_mode():
    with pytest.raises(ValueError, match=r"render_mode='video'.*rgb_array"):
        make(render_mode="video")


@pytest.mark.parametrize(
    "action, match",
    [
        (np.zeros(3), r"shape \(3,\).*shape \(2,\)"),
        (np.zeros((2, 1)), r"shape \(2, 1\)"),
        (np.array([np.nan, 0.0]), r"NaN"),
        (np.array([0.0, np.inf]), r"NaN or inf"),
    ],
)
def test_bad_actions_parallel(action, match):
    env = make(scenario="lane-drop")
    env.reset(seed=0)
    acts = {a: np.zeros(2) for a in env.agents}
    acts["icv_3"] = action
    with pytest.raises(ValueError, match="icv_3.*" + match if "shape" in match else match):
        env.step(acts)


def test_actions_for_unknown_agents():
    env = make()
    env.reset(seed=0)
    acts = {a: np.zeros(2) for a in env.agents}
    acts["icv_99"] = np.zeros(2)
    with pytest.raises(ValueError, match="not live.*icv_99"):
        env.step(acts)


@pytest.mark.parametrize("kind", ["dict", "defaultdict"])
def test_an_unknown_agent_in_place_of_a_live_one_is_named(kind):
    """As many keys as live agents, one of them unknown: the step's fast path
    (one lookup per agent) must not take it, nor a defaultdict make up the
    absent agent's action."""
    import collections

    env = make()
    env.reset(seed=0)
    acts = {a: np.zeros(2) for a in env.agents}
    del acts[env.agents[2]]
    acts["icv_99"] = np.zeros(2)
    if kind == "defaultdict":
        acts = collections.defaultdict(lambda: np.zeros(2), acts)
    with pytest.raises(ValueError, match="not live.*icv_99"):
        env.step(acts)


def test_bad_actions_gym():
    env = gym.make("icv_envs/HighwayFormation-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"ego.*shape \(3,\)"):
        env.step(np.zeros(3, dtype=np.float32))
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))


def test_out_of_range_actions_are_clipped():
    env = make()
    env.reset(seed=0)
    env.step({a: np.array([5.0, -5.0]) for a in env.agents})
    assert (env.core.world.traffic.accel <= 3.0 + 1e-12).all()


def test_unknown_policy():
    with pytest.raises(ValueError, match=r"unknown policy 'greedy'.*expert"):
        make_policy("greedy")


@pytest.mark.parametrize(
    "argv, match",
    [
        (["run", "highway-formation", "--scenario", "tunnel"], "unknown scenario 'tunnel'"),
        (["run", "highway-formation", "--policy", "greedy"], "unknown policy 'greedy'"),
        (["run", "roundabout"], "unknown env 'roundabout'"),
        (["run", "highway-formation", "--seconds", "-3"], r"--seconds must be a finite number > 0, got '-3'"),
        (["run", "highway-formation", "--seconds", "0"], r"--seconds must be"),
        (["bench", "highway-formation", "--sizes", "10,-1"], r"--sizes must be integers >= 1"),
    ],
)
def test_cli_bad_arguments(argv, match, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert pytest.importorskip("re").search(match, capsys.readouterr().err)


def test_cli_bad_config_value(capsys):
    assert main(["run", "highway-formation", "--seconds", "1", "--config", '{"lanes_count": 0}']) == 2
    assert "lanes_count" in capsys.readouterr().err
    assert main(["run", "highway-formation", "--seconds", "1", "--config", "{not json"]) == 2
    assert "not valid JSON" in capsys.readouterr().err


@pytest.mark.parametrize("kw, match", [
    ({"kp": 0.3}, "kp = 0.3; allowed: < 0"),
    ({"kv": float("nan")}, "kv = nan; allowed: a finite number"),
    ({"steer_max": 2.0}, "steer_max = 2.0; allowed: in"),
    ({"wheelbase": 0.0}, "wheelbase = 0.0; allowed: > 0"),
    ({"comfort_accel": (0.5, 1.5)}, "allowed: lower < 0 < upper"),
])
def test_formation_expert_checks_its_parameters_once(kw, match):
    """The expert calls the unchecked forms of the paper's functions every
    step; a parameter those functions would refuse is refused when the
    expert is made, naming the value."""
    from icv_envs.policies.formation_expert import ExpertParams, FormationExpert

    with pytest.raises(ValueError, match=match):
        FormationExpert(ExpertParams(**kw))


@pytest.mark.parametrize("kw, match", [
    ({"kp": 0.3}, "kp = 0.3; allowed: < 0"),
    ({"kv": float("inf")}, "kv = inf; allowed: a finite number"),
    ({"steer_max": -0.1}, "steer_max = -0.1; allowed: in"),
    ({"wheelbase": -2.0}, "wheelbase = -2.0; allowed: > 0"),
    ({"comfort": (0.5, 1.5)}, "comfort = 0.5 / 1.5; allowed: lower < 0 < upper"),
    ({"comfort": (-3.0,)}, r"comfort = \(-3.0,\); allowed: a pair"),
    ({"a_max": -1.0}, "a_min / a_max = -6.0 / -1.0; allowed: lower < 0 < upper"),
    ({"lc_min_length": 0.0}, "lc_min_length / lc_max_length = 0.0 / 40.0; allowed: 0 < lc_min_length"),
    ({"lc_max_length": 10.0}, "lc_min_length / lc_max_length = 15.0 / 10.0"),
    ({"D_t": -1.0}, "D_t = -1.0; allowed: >= 0 metres"),
    ({"D_t": float("nan")}, "D_t = nan; allowed: a finite number"),
])
def test_platoon_expert_checks_its_parameters_once(kw, match):
    """The intersection expert calls the unchecked steering and feedback
    laws every step; a parameter they would refuse is refused when the
    expert is made, naming the value."""
    from icv_envs.policies.platoon_expert import PlatoonExpert, PlatoonParams
    from icv_envs.sim.intersection_layout import IntersectionLayout

    with pytest.raises(ValueError, match=match):
        PlatoonExpert(IntersectionLayout(), PlatoonParams(**kw))


@pytest.mark.parametrize("kw", [{"w1": -1.0}, {"w2": float("nan")}, {"w1": True}, {"w2": "10"}])
def test_formation_manager_checks_its_assignment_weights_once(kw):
    """The formation layer assigns targets without re-checking its weights
    (issue 10), so it refuses bad ones when it is built, naming them."""
    from icv_envs.sim.formations import FormationManager

    name = next(iter(kw))
    with pytest.raises(ValueError, match=f"{name} must be a finite real number >= 0"):
        FormationManager(**kw)
