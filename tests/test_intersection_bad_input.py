"""Intersection bad input: a clear error naming the value and what is allowed."""

import argparse

import gymnasium as gym
import numpy as np
import pytest

from icv_envs.envs import intersection_v0
from icv_envs.envs.intersection import IntersectionEnv
from icv_envs.experiments import intersection_bench, intersection_compare
from icv_envs.experiments.intersection_compare import parse_throughputs, validate_grid
from icv_envs.sim.intersection_world import IntersectionLayout


def make(**config):
    return intersection_v0.parallel_env(**config)


@pytest.mark.parametrize(
    "config, match",
    [
        ({"lane_use": "british"}, r"unknown lane_use 'british'; allowed: \['paper', 'exclusive'\]"),
        ({"lane_use": {"left": [], "straight": [1], "right": [2]}},
         r"movement 0 \(N-left\) has no approach lane"),
        ({"lane_use": {"left": [0], "straight": [1], "right": [2], (2, "right"): []}},
         r"movement 8 \(S-right\) has no approach lane"),
        ({"lane_use": {"left": [5], "straight": [1], "right": [2]}}, r"lane of movement 'left'.*0\.\.2.*5"),
        ({"lane_use": {"uturn": [0]}}, r"unknown lane-use key 'uturn'"),
        ({"method": "traffic-lights"}, r"unknown method 'traffic-lights'; allowed: \['multi-vp', 'single-vp', 'fcfs', 'fcfs-tight'\]"),
        ({"R1": 500.0, "R2": 300.0}, r"box_half < R1 < R2 < R3.*R1=500, R2=300, R3=800"),
        ({"R2": 900.0}, r"box_half < R1 < R2 < R3.*R2=900, R3=800"),
        ({"R1": 500.0}, r"box_half < R1 < R2 < R3"),
        ({"R1": 10.0}, r"box_half < R1 < R2 < R3.*box_half=16, R1=10"),
        ({"R3": -800.0}, r"R3.*-800"),
        ({"throughput": 0.0}, r"throughput = 0.0 vehicles/h is invalid; allowed: a number in \(0, 20000\]"),
        ({"throughput": -1500.0}, r"throughput = -1500.0"),
        ({"throughput": float("nan")}, r"throughput = nan"),
        ({"throughput": "lots"}, r"throughput = 'lots'"),
        ({"throughput": True}, r"throughput = True"),
        ({"D_t": 10.0}, r"D_t'\] = 10.0 m is too small.*D_t >= 19.00 m"),
        ({"turn_shares": [1.0, -1.0, 1.0]}, r"turn_shares.*three numbers >= 0"),
        ({"turn_shares": [0.0, 0.0, 0.0]}, r"turn_shares.*positive sum"),
        ({"arrivals": "burst"}, r"arrivals = 'burst'; allowed: 'poisson', 'fixed'"),
        ({"formation_size": 0}, r"formation_size.*0.*\[1, 30\]"),
        ({"box_half": 10.0}, r"box_half.*10.0.*\[3 \* lane_width = 12, 100\]"),
        ({"fcfs": {"tiles": 2.0}}, r"unknown fcfs keys \['tiles'\]"),
        ({"fcfs": {"tile": -1.0}}, r"tile.*-1.0.*\[0.1, 5\]"),
        ({"fcfs": {"time_buffer": 2.5}}, r"time_buffer.*2.5"),
        ({"speed_range": [20.0, 10.0]}, r"speed_range"),
        ({"desired_speed": 30.0}, r"desired_speed.*30.0.*v_max = 20"),
        ({"policy_frequency": 7}, r"policy_frequency=7 must divide"),
        ({"duration": 0.0}, r"duration.*0.0"),
        ({"warmup": -5.0}, r"warmup.*-5.0"),
        ({"max_vehicles": 0}, r"max_vehicles = 0"),
        ({"reward": {"speed": 1.0}}, r"unknown reward keys.*speed"),
        ({"observation": {"vehicles_count": 0}}, r"vehicles_count.*0"),
        ({"missing_action": "ignore"}, r"missing_action.*ignore"),
        ({"opposing_left_conflict": "yes"}, r"opposing_left_conflict.*'yes'"),
        ({"colour": "red"}, r"unknown config keys \['colour'\]"),
    ],
)
def test_bad_config(config, match):
    with pytest.raises(ValueError, match=match):
        make(**config)


def test_layout_errors_directly():
    with pytest.raises(ValueError, match=r"unknown lane-use preset 'x'"):
        IntersectionLayout("x")
    with pytest.raises(ValueError, match=r"box_half < R1 < R2 < R3"):
        IntersectionLayout(R1=600.0)
    with pytest.raises(ValueError, match=r"departure_length must be > 0"):
        IntersectionLayout(departure_length=0.0)


def test_custom_lane_use_works_and_changes_the_conflicts():
    env = make(lane_use={"left": [0], "straight": [1, 2], "right": [2]}, duration=5.0)
    env.reset(seed=0)
    lay = env.core.layout
    assert lay.lane_use[1] == (1, 2) and lay.lane_use_name == "custom"
    # straight and right share lane 2 now: diverging conflict
    assert lay.conflict[1, 2] and "diverging" in lay.model.kinds[1, 2]


def test_bad_render_mode():
    with pytest.raises(ValueError, match=r"render_mode='video'.*rgb_array"):
        make(render_mode="video")


@pytest.mark.parametrize(
    "action, match",
    [
        (np.zeros(3), r"shape \(3,\).*shape \(2,\)"),
        (np.array([np.nan, 0.0]), r"NaN"),
        (np.array([0.0, np.inf]), r"NaN or inf"),
    ],
)
def test_bad_actions(action, match):
    env = make(duration=10.0)
    env.reset(seed=0)
    a = env.agents[0]
    acts = {b: np.zeros(2) for b in env.agents}
    acts[a] = action
    with pytest.raises(ValueError, match=f"{a}.*" + match if "shape" in match else match):
        env.step(acts)
    with pytest.raises(ValueError, match="not live"):
        env.step({"icv_9999": np.zeros(2)})
    g = IntersectionEnv({"duration": 10.0})
    g.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        g.step(action)


def test_step_after_the_ego_is_done_or_before_reset():
    env = gym.make("icv_envs/Intersection-v0", config={"duration": 0.4}) if "icv_envs/Intersection-v0" in gym.registry \
        else IntersectionEnv({"duration": 0.4})
    env.reset(seed=0)
    env.step(np.zeros(2, dtype=np.float32))
    _, _, term, trunc, _ = env.step(np.zeros(2, dtype=np.float32))
    assert trunc
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(2, dtype=np.float32))


@pytest.mark.parametrize(
    "args, match",
    [
        ((["multi-vp", "roundabout"], [1000.0], 1, 10.0), r"unknown methods \['roundabout'\]"),
        (([], [1000.0], 1, 10.0), r"no methods given"),
        ((["fcfs"], [0.0], 1, 10.0), r"throughput 0.0 is invalid; allowed: 0 < throughput"),
        ((["fcfs"], [-5.0], 1, 10.0), r"throughput -5.0 is invalid"),
        ((["fcfs"], [], 1, 10.0), r"no throughput given"),
        ((["fcfs"], [1000.0], 0, 10.0), r"seeds = .?0.?: a count must be >= 1"),
        ((["fcfs"], [1000.0], "4-2", 10.0), r"range '4-2' is empty"),
        ((["fcfs"], [1000.0], 1, -1.0), r"seconds = -1.0"),
    ],
)
def test_bad_sweep_grid(args, match):
    with pytest.raises(ValueError, match=match):
        validate_grid(*args)


def test_bad_throughput_text_and_cli_errors(tmp_path):
    assert parse_throughputs("1000, 2000") == [1000.0, 2000.0]
    for text, match in (("a,b", "comma-separated numbers"), ("0", "throughput 0.0 is invalid"),
                        ("-100", "throughput -100.0"), ("", "empty")):
        with pytest.raises(ValueError, match=match):
            parse_throughputs(text)
    ns = argparse.Namespace(methods="multi-vp,teleport", throughput="1000", seeds=1, seconds=10.0,
                            out=str(tmp_path), backend="process", workers=1)
    with pytest.raises(ValueError, match=r"unknown methods \['teleport'\]"):
        intersection_compare.run_cli(ns)
    ns = argparse.Namespace(methods=None, throughput="1000", seeds=1, seconds=10.0, out=str(tmp_path),
                            backend="spark", workers=1)
    with pytest.raises(ValueError, match=r"backend 'spark'"):
        intersection_compare.run_cli(ns)
    ns = argparse.Namespace(methods="fcfs", throughput="1000", seeds=1, seconds=10.0, out=str(tmp_path),
                            backend="process", workers=1, lane_use="british")
    with pytest.raises(ValueError, match=r"unknown lane_use 'british'"):
        intersection_compare.run_cli(ns)
    with pytest.raises(ValueError, match=r"unknown method 'teleport'"):
        intersection_bench.run_cli(argparse.Namespace(seconds=1.0, throughput=None, method="teleport"))
    with pytest.raises(ValueError, match=r"throughput -3.0 is invalid"):
        intersection_bench.run_cli(argparse.Namespace(seconds=1.0, throughput=[-3.0], method=None))
    with pytest.raises(ValueError, match=r"warmup = -1.0; allowed: a finite number >= 0"):
        intersection_bench.bench_intersection(seconds=1.0, warmup=-1.0)
    with pytest.raises(ValueError, match=r"seeds = 0; allowed: an integer >= 1"):
        intersection_bench.bench_intersection(seconds=1.0, seeds=0)
    with pytest.raises(ValueError, match=r"seconds = nan; allowed: a finite number > 0"):
        intersection_bench.bench_intersection(seconds=float("nan"))


def test_fcfs_tight_fixes_its_buffers():
    from icv_envs.envs.intersection import FCFS_TIGHT, IntersectionEnv

    env = IntersectionEnv({"method": "fcfs-tight", "duration": 5.0})
    env.reset(seed=0)
    assert env.expert.table is not None and env.expert.space_buffer == FCFS_TIGHT["space_buffer"]
    assert env.expert.table.time_buffer == FCFS_TIGHT["time_buffer"]
    fair = IntersectionEnv({"method": "fcfs", "duration": 5.0})
    fair.reset(seed=0)
    assert fair.expert.space_buffer == 0.0 and fair.expert.table.time_buffer == 0
    with pytest.raises(ValueError, match="fcfs-tight' fixes the reservation buffers"):
        IntersectionEnv({"method": "fcfs-tight", "fcfs": {"time_buffer": 2}})
