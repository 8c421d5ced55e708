"""Rendering (frames are not black, the formation overlay is drawn),
RecordVideo, and the CLI's JSON output."""

import json

import gymnasium as gym
import numpy as np
import pytest

from icv_envs import highway_formation_v0
from icv_envs.cli import main


def test_rgb_array_frames_show_road_vehicles_and_targets():
    env = highway_formation_v0.parallel_env(scenario="lane-drop", render_mode="rgb_array")
    obs, infos = env.reset(seed=0)
    for _ in range(75):  # past the re-formation: targets differ from positions
        obs, *_ , infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    frame = env.render()
    cfg = env.core.config
    assert frame.shape == (cfg["screen_height"], cfg["screen_width"], 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # not a blank (or black) frame
    colours = {tuple(c) for c in frame.reshape(-1, 3)[:: 7]}
    assert (100, 200, 255) in colours  # formation members are drawn in the group colour
    # the overlay switch draws targets and assignment lines (white and amber pixels)
    env2 = highway_formation_v0.parallel_env(scenario="lane-drop", render_mode="rgb_array", show_formation=False)
    obs, infos = env2.reset(seed=0)
    for _ in range(75):
        obs, *_, infos = env2.step({a: infos[a]["expert_action"] for a in env2.agents})
    frame2 = env2.render()
    amber = lambda f: int(((f[..., 0] == 255) & (f[..., 1] == 200) & (f[..., 2] == 0)).sum())
    assert amber(frame) > 0 and amber(frame2) == 0


def test_record_video(tmp_path):
    pytest.importorskip("moviepy")
    env = gym.make("icv_envs/HighwayFormation-v0", render_mode="rgb_array", config={"duration": 4.0})
    env = gym.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda e: True, disable_logger=True)
    obs, info = env.reset(seed=0)
    done = False
    while not done:
        obs, r, term, trunc, info = env.step(info["expert_action"])
        done = term or trunc
    env.close()
    videos = list(tmp_path.glob("*.mp4"))
    assert videos and videos[0].stat().st_size > 1000


def test_cli_run_prints_json_last_and_writes_files(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", "highway-formation", "--scenario", "off-ramp", "--policy", "expert", "--seconds", "60",
                 "--seed", "0", "--out", str(out), "--video"])
    assert code == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    m = json.loads(last)
    for key in ("collisions", "mean_speed", "speed_fluctuation", "min_gap", "vehicles"):
        assert key in m
    assert m["collisions"] == 0 and m["exited"] == 1 and m["vehicles"] == 7
    assert 20 < m["mean_speed"] < 30
    assert json.loads((out / "metrics.json").read_text())["collisions"] == 0
    assert (out / "video.gif").stat().st_size > 1000


def test_cli_zero_policy_runs(capsys):
    assert main(["run", "highway-formation", "--scenario", "free", "--policy", "zero", "--seconds", "5"]) == 0
    m = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert m["policy"] == "zero" and m["steps"] == 25


def test_cli_bench_small(capsys):
    assert main(["bench", "highway-formation", "--sizes", "10", "--seconds", "2", "--stock-seconds", "1"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    (row,) = res["results"]
    assert row["vehicles"] == 10 and row["speedup"] > 0 and row["icv_envs_collisions"] == 0


def test_cli_list(capsys):
    assert main(["list"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "icv_envs/HighwayFormation-v0" in out["gymnasium"] and "lane-drop" in out["scenarios"]


def test_human_render_mode_runs_headless():
    # SDL's dummy driver (set in conftest) stands in for a screen
    env = highway_formation_v0.parallel_env(scenario="lane-drop", render_mode="human", duration=1.0)
    obs, infos = env.reset(seed=0)
    while env.agents:
        obs, *_, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    assert env.render() is None
    env.close()
