"""`icv-envs dataset`: the expert recorded as a Minari dataset, loaded back
with minari and checked against a replay with the same seed."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

minari = pytest.importorskip("minari")
pytest.importorskip("pyarrow")

from icv_envs.cli import main  # noqa: E402
from icv_envs.rl.dataset import record_expert_dataset  # noqa: E402


def test_gym_dataset_round_trip_and_replay(tmp_path, monkeypatch):
    cfg = {"scenario": "lane-drop", "duration": 5.0}
    assert main(["dataset", "--env", "icv_envs/HighwayFormation-v0", "--episodes", "2", "--out", str(tmp_path),
                 "--seed", "7", "--config", json.dumps(cfg)]) == 0
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    ds = minari.load_dataset("icv_envs/highway_formation/expert-v0")
    assert ds.total_episodes == 2
    ep = list(ds.iterate_episodes())[1]
    T = len(ep.actions)
    assert ep.observations.shape == (T + 1, 8, 13) and ep.observations.dtype == np.float32
    assert ep.infos["env_seed"].shape == (T + 1, 1) and int(ep.infos["env_seed"][0, 0]) == 8
    assert ep.truncations[-1] or ep.terminations[-1]
    env = gym.make("icv_envs/HighwayFormation-v0", config=cfg)
    obs, info = env.reset(seed=int(ep.infos["env_seed"][0, 0]))
    np.testing.assert_array_equal(obs, ep.observations[0])
    for t in range(T):
        np.testing.assert_array_equal(ep.actions[t], info["expert_action"])  # the expert's action was recorded
        obs, r, term, trunc, info = env.step(ep.actions[t])
        np.testing.assert_array_equal(obs, ep.observations[t + 1])
        assert r == ep.rewards[t] and term == ep.terminations[t] and trunc == ep.truncations[t]
        assert ep.infos["reward_formation"][t + 1, 0] == info["rewards"]["formation"]
    assert ds.recover_environment().spec.id == "icv_envs/HighwayFormation-v0"


def test_pettingzoo_dataset_one_episode_per_vehicle_replays(tmp_path, monkeypatch):
    from icv_envs import intersection_v0

    cfg = {"duration": 15.0, "action": {"type": "FormationResidual"}}
    res = record_expert_dataset("icv_envs/intersection-v0", 1, tmp_path, seed=3, config=cfg)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    ds = minari.load_dataset(res["dataset_id"])
    eps = list(ds.iterate_episodes())
    assert len(eps) == res["episodes"] > 1
    vehicles = [int(e.infos["vehicle"][0, 0]) for e in eps]
    assert len(set(vehicles)) == len(vehicles)
    ep = max(eps, key=lambda e: len(e.actions))
    vid = int(ep.infos["vehicle"][0, 0])
    assert np.all(ep.actions == 0)  # the residual that reproduces the expert
    par = intersection_v0.parallel_env(**cfg)
    obs, infos = par.reset(seed=int(ep.infos["env_seed"][0, 0]))
    a = f"icv_{vid}"
    traj_obs, traj_rew = ([obs[a]] if a in obs else []), []
    while par.agents:
        obs, rew, term, trunc, infos = par.step({b: np.zeros(2, np.float32) for b in par.agents})
        if a in obs:
            if traj_obs:  # a step of the vehicle (else: it appeared in this step)
                traj_rew.append(rew[a])
            traj_obs.append(obs[a])
            if term[a] or trunc[a]:
                break
    np.testing.assert_array_equal(np.stack(traj_obs), ep.observations)
    np.testing.assert_array_equal(np.asarray(traj_rew), ep.rewards)


def test_dataset_bad_input():
    with pytest.raises(ValueError, match="no form in action type 'DiscreteMetaAction'"):
        record_expert_dataset("icv_envs/HighwayFormation-v0", 1, "/tmp/icv_ds_unused",
                              config={"duration": 1.0, "action": {"type": "DiscreteMetaAction"}})
    with pytest.raises(ValueError, match="episodes"):
        record_expert_dataset("icv_envs/HighwayFormation-v0", 0, "/tmp/icv_ds_unused")
    assert main(["dataset", "--env", "nope", "--episodes", "1", "--out", "/tmp/icv_ds_unused"]) == 2
