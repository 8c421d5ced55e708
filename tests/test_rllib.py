"""Ray RLlib: the compat wrapper fits RLlib's multi-agent env API (ordered
possible agents, agents joining mid-episode, episode end, render), and
``baselines/rllib_shared.py`` trains one iteration, saves a checkpoint and
run.json, and its checkpoint evaluates. Skipped without ``ray[rllib]``
(install it in a separate venv: it pins its own gymnasium)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ray")
pytest.importorskip("ray.rllib")
pytest.importorskip("torch")

from icv_envs import highway_formation_v0  # noqa: E402
from icv_envs.rl.rllib_compat import IcvParallelPettingZooEnv, evaluate_checkpoint, make_rllib_env  # noqa: E402
from baseline_scripts import load_baseline

METRICS = ("collisions", "mean_speed", "speed_fluctuation", "min_gap", "episode_return")
LATE_SPAWN = [{"time": 2.0, "position": 320.0, "lane": "ramp", "speed": 15.0}]


def _script():
    return load_baseline("rllib_shared")


def test_wrapper_agents_spaces_and_episode_end():
    from ray.rllib.utils.pre_checks.env import check_multiagent_environments

    par = highway_formation_v0.parallel_env(scenario="on-ramp", duration=6.0, spawns=LATE_SPAWN,
                                            render_mode="rgb_array")
    env = IcvParallelPettingZooEnv(par)
    assert env.possible_agents == par.possible_agents  # ordered, the late spawn included
    late = par.possible_agents[-1]
    assert set(env.observation_spaces) == set(env.action_spaces) == set(par.possible_agents)
    assert env.get_observation_space(late) == par.observation_space(late)
    check_multiagent_environments(env)

    obs, infos = env.reset(seed=0)
    assert late not in obs and env.agents == par.agents
    joined = None
    for step in range(1, 1000):
        obs, rew, term, trunc, infos = env.step({a: infos[a]["expert_action"] for a in par.agents})
        assert set(obs) <= set(env.agents) and set(rew) == set(obs)
        if joined is None and late in obs:
            joined = step
        if term["__all__"] or trunc["__all__"]:
            break
    assert joined is not None and joined > 1  # joined mid-episode
    assert trunc["__all__"] and not term["__all__"]  # time ran out: truncation, exactly once
    assert not par.agents
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3


def test_env_creator_takes_env_and_config():
    env = make_rllib_env({"env": "highway_formation_v0", "config": {"scenario": "lane-drop", "duration": 2.0}})
    assert env.par_env.core.config["scenario"] == "lane-drop"
    obs, _ = env.reset(seed=1)
    assert all(o.shape == (8, 13) and o.dtype == np.float32 for o in obs.values())
    env.close()


def test_help():
    with pytest.raises(SystemExit) as exc:
        _script().main(["--help"])
    assert exc.value.code == 0


def test_one_iteration_checkpoint_and_eval(tmp_path):
    out = tmp_path / "rllib"
    cfg = {"scenario": "on-ramp", "duration": 10.0}
    assert _script().main(["--iterations", "1", "--train-batch-size", "400", "--minibatch-size", "64",
                           "--num-epochs", "1", "--seed", "0", "--config", json.dumps(cfg),
                           "--out", str(out), "--eval-episodes", "1"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["algo"] == "rllib_shared" and run["config"] == cfg
    assert run["observation_shape"] == [8, 13] and run["action_shape"] == [2]
    assert run["train"]["iterations"] == 1 and run["train"]["env_steps"] >= 400
    ckpt = Path(run["checkpoint"])
    assert ckpt.is_dir() and (ckpt / "rllib_checkpoint.json").is_file()
    assert Path(run["module"]).is_dir()
    for k in METRICS:
        assert k in run["eval"]
    res = evaluate_checkpoint(out, episodes=1, seed=5, config={"scenario": "lane-drop", "duration": 4.0})
    assert res["algo"] == "rllib_shared" and res["episodes"] == 1 and res["vehicles"] > 0
    for k in METRICS:
        assert k in res
