"""Issue 11, items 13 and 14: config values that were accepted (NaN out, a
crash deep inside, memory exhaustion, or silently ignored) are errors naming
the key, the value and what is allowed; actions of the wrong kind name the
agent."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0

NAN, INF = float("nan"), float("inf")
FORMATION = highway_formation_v0.parallel_env
RAMPS = highway_ramps_v0.parallel_env
INTERSECTION = intersection_v0.parallel_env
ALL = [FORMATION, RAMPS, INTERSECTION]


def _ids(make):
    return make.__module__ if False else {FORMATION: "formation", RAMPS: "ramps", INTERSECTION: "intersection"}[make]


CASES = [
    # item 13: values
    (RAMPS, {"first_off_ramp": NAN}, r"first_off_ramp'\] = nan.*position in \[0, road_length"),
    (RAMPS, {"first_on_ramp": 1e7}, r"first_on_ramp'\] = 10000000.0"),
    (RAMPS, {"seam": -5.0}, r"seam'\] = -5.0"),
    (RAMPS, {"ramp_spacing": 5000.0}, r"ramp_spacing'\] = 5000.0.*road_length / ramps = 2000"),
    (RAMPS, {"ramp_spacing": NAN}, r"ramp_spacing'\] = nan"),
    (RAMPS, {"max_vehicles": 10**30}, r"max_vehicles = 10{30}.*\[1, 200000\]"),
    (RAMPS, {"duration": 86400.0, "vgr": 1.0}, r"possible agents.*at most 200000"),
    (INTERSECTION, {"max_vehicles": 10**30}, r"max_vehicles = 10{30}"),
    (INTERSECTION, {"duration": 86400.0, "throughput": 20000.0}, r"possible agents.*at most 200000"),
    (FORMATION, {"obstacle": {"lane": 1, "position": 900.0, "length": -4.0}}, r"\['obstacle'\]\['length'\] = -4.0"),
    (FORMATION, {"obstacle": {"lane": 1, "position": 900.0, "length": NAN}}, r"\['obstacle'\]\['length'\] = nan"),
    (FORMATION, {"obstacle": {"lane": 1, "position": 900.0, "colour": "red"}}, r"unknown obstacle keys \['colour'\]"),
    (FORMATION, {"obstacle": [1, 900.0]}, r"config\['obstacle'\] = \[1, 900.0\] \(list\).*None or a dict"),
    (FORMATION, {"on_ramp": {"position": 650.0, "length": 100.0, "approach": -1.0}},
     r"\['on_ramp'\]\['approach'\] = -1.0"),
    (FORMATION, {"on_ramp": {"position": 650.0, "length": 100.0, "aproach": 300.0}}, r"unknown on_ramp keys"),
    (FORMATION, {"off_ramp": {"position": 900.0, "length": 50.0, "ramp_length": NAN}},
     r"\['off_ramp'\]\['ramp_length'\] = nan"),
    (FORMATION, {"lane_drop": {"position": 700.0, "lanes": 3, "side": "left"}}, r"unknown lane_drop keys"),
    (FORMATION, {"spawns": [{"time": 1.0, "position": 1e9, "lane": 0}]}, r"\['spawns'\]\[0\]\['position'\] = 1000000000.0.*\[0, road_length=2000"),
    (FORMATION, {"spawns": [{"time": 1.0, "position": 100.0, "lane": 0, "exit": 5}]},
     r"\['spawns'\]\[0\]\['exit'\] = 5.*-1 \(no exit\)"),
    (FORMATION, {"spawns": [{"time": 1.0, "position": 100.0, "lane": 0, "sped": 5}]}, r"unknown spawns\[0\] keys"),
    (FORMATION, {"spawns": [{"time": 100.0, "position": 100.0, "lane": 0}]}, r"\['time'\] = 100.0.*duration = 60"),
    (FORMATION, {"formation": "abc"}, r"config\['formation'\] = 'abc' \(str\).*a dict"),
    (FORMATION, {"initial_position": "abc"}, r"initial_position'\] = 'abc'"),
    (RAMPS, {"ego_vehicle": 3}, r"ego_vehicle'\] = 3 is not used by HighwayRamps.*first arrival"),
    (RAMPS, {"formation_lanes": [True]}, r"formation_lanes = \[True\]"),
    # item 14: options accepted and ignored
    (RAMPS, {"initial_position": 100.0}, r"initial_position'\] = 100.0 is not used by HighwayRamps"),
    (RAMPS, {"vehicles_count": 5}, r"vehicles_count'\] = 5 is not used by HighwayRamps"),
    (RAMPS, {"formation_gap": 10.0}, r"formation_gap'\] = 10.0 is not used by HighwayRamps"),
]
for make in ALL:
    CASES += [
        (make, {"acceleration_range": [-INF, INF]}, r"acceleration_range'\] = \[-inf, inf\].*finite.*-20 <= a_min"),
        (make, {"acceleration_range": [-6.0, NAN]}, r"acceleration_range"),
        (make, {"duration": 1e9}, r"duration'\] = 1000000000.0.*\(0, 86400\]"),
        (make, {"observation": None}, r"config\['observation'\] = None \(NoneType\).*a dict"),
        (make, {"reward": 3}, r"config\['reward'\] = 3 \(int\)"),
        (make, {"screen_width": "abc"}, r"screen_width'\] = 'abc'.*integer number of pixels"),
        (make, {"screen_height": 10**9}, r"screen_height'\] = 1000000000"),
        (make, {"scaling": 0}, r"scaling'\] = 0 is invalid.*\(0, 10000\]"),
        (make, {"centering_position": [0.5]}, r"centering_position"),
        (make, {"real_time_rendering": "yes"}, r"real_time_rendering'\] = 'yes'.*True or False"),
        (make, {"other_vehicles_type": "highway_env.vehicle.behavior.AggressiveVehicle"},
         r"other_vehicles_type'\] = .*AggressiveVehicle' is not used"),
        (make, {"manual_control": True}, r"manual_control'\] = True is not used.*no manual control"),
        (make, {"show_trajectories": True}, r"show_trajectories'\] = True is not used"),
        (make, {"expert_in_info": "no"}, r"expert_in_info'\] = 'no'"),
    ]
CASES += [
    (INTERSECTION, {"fcfs": "abc"}, r"config\['fcfs'\] = 'abc'"),
    (INTERSECTION, {"fcfs": {"a_plan": None}}, r"\['fcfs'\]\['a_plan'\] = None"),
    (INTERSECTION, {"lane_use": {}}, r"config\['lane_use'\] = \{\} is invalid: movement 0"),
    (INTERSECTION, {"lane_use": 5}, r"config\['lane_use'\] = 5 is invalid"),
    (INTERSECTION, {"show_zones": None}, r"show_zones'\] = None"),
    (FORMATION, {"show_formation": 2}, r"show_formation'\] = 2"),
]


@pytest.mark.parametrize("make, config, match", CASES,
                         ids=[f"{_ids(m)}-{'-'.join(map(str, c))}" for m, c, _ in CASES])
def test_bad_value(make, config, match):
    with pytest.raises(ValueError, match=match):
        make(**config)


def test_first_off_ramp_nan_does_not_give_nan_observations_any_more():
    with pytest.raises(ValueError):
        RAMPS(first_off_ramp=NAN)
    env = RAMPS(duration=5.0)
    obs, _ = env.reset(seed=0)
    assert all(np.isfinite(o).all() for o in obs.values())


BAD_ACTIONS = [
    ("fast", r"action of {a} = 'fast' \(str\) is invalid"),
    ({"acceleration": 1.0}, r"action of {a} = \{{'acceleration': 1.0\}} \(dict\)"),
    ([10**30, 0], r"action of {a} = \[10{{30}}, 0\] has dtype object"),
    (10**30, r"action of {a} = 10{{30}} has dtype object"),
    ([1 + 2j, 0.0], r"action of {a} = \[\(1\+2j\), 0.0\] has dtype complex128"),
    (np.array([0.5 + 0.5j, 0.0]), r"action of {a} .*complex128"),
    ([True, False], r"action of {a} .*dtype bool"),
    (None, r"action of {a} = None"),
    (["1", "2"], r"action of {a} .*dtype <U1"),
    ([[0.0, 1.0]], r"action of {a} has shape \(1, 2\)"),
]


@pytest.mark.parametrize("make", ALL, ids=["formation", "ramps", "intersection"])
@pytest.mark.parametrize("action, match", BAD_ACTIONS, ids=[repr(a)[:20] for a, _ in BAD_ACTIONS])
def test_bad_action_names_the_agent(make, action, match):
    env = make(duration=5.0) if make is not FORMATION else make()
    env.reset(seed=0)
    acts = {a: np.zeros(2) for a in env.agents}
    target = env.agents[-1]
    acts[target] = action
    with pytest.raises(ValueError, match=match.format(a=target)):
        env.step(acts)


@pytest.mark.parametrize("env_id", ["icv_envs/HighwayFormation-v0", "icv_envs/Intersection-v0"])
def test_bad_gym_action_names_the_ego(env_id):
    env = gym.make(env_id, disable_env_checker=True)
    env.reset(seed=0)
    for action in ("fast", {"a": 1}, 1 + 1j, [10**30, 0]):
        with pytest.raises(ValueError, match="action of the ego"):
            env.step(action)


def test_integer_actions_are_accepted():
    env = FORMATION()
    env.reset(seed=0)
    env.step({a: np.array([1, -1]) for a in env.agents})  # integer arrays are numbers
    env.step({a: [0, 0] for a in env.agents})


@pytest.mark.parametrize("section, match", [
    ({"observation": {"type": "OccupancyGrid", "grid_size": [["-10", "10"], ["-10", "10"]]}}, "grid_size"),
    ({"observation": {"type": "OccupancyGrid", "grid_step": [True, True]}}, "grid_step"),
    ({"action": {"type": "DiscreteMetaAction", "target_speeds": ["5", "10"]}}, "target_speeds"),
    ({"action": {"type": "DiscreteMetaAction", "target_speeds": [True, 2.0]}}, "target_speeds"),
    ({"action": {"type": "FormationResidual", "bound": [True, 1]}}, "bound"),
    ({"observation": {"type": "Kinematics", "normalize": False, "clip": True}},
     "clip = True with normalize = False"),
])
def test_nested_config_numbers_are_not_misread(section, match):
    """Strings and bools inside the action and observation options were
    converted to numbers (``"5"`` -> 5 m/s, ``True`` -> a 1 m grid step) and
    an explicit ``clip=True`` on raw observations was ignored (stop 45);
    numpy numbers and arrays of numbers stay accepted."""
    from icv_envs.envs.highway_formation_v0 import parallel_env

    with pytest.raises(ValueError, match=match):
        parallel_env(vehicles_count=4, **section)
    for ok in ({"action": {"type": "FormationResidual", "bound": np.float32(0.5)}},
               {"action": {"type": "DiscreteMetaAction", "target_speeds": np.array([5, 10, 20])}},
               {"observation": {"type": "OccupancyGrid", "grid_size": np.array([[-10, 10], [-10, 10]])}}):
        parallel_env(vehicles_count=4, **ok)
