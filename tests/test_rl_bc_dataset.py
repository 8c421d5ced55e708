"""baselines/bc_expert.py --dataset: behaviour cloning from a Minari dataset of the expert."""

from __future__ import annotations

import json

import numpy as np
import pytest
from baseline_scripts import load_baseline

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")
pytest.importorskip("minari")
torch.set_num_threads(1)



def _bc():
    return load_baseline("bc_expert")


def test_bc_from_dataset(tmp_path, monkeypatch):
    from icv_envs.rl.dataset import record_expert_dataset

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "ds"))
    cfg = {"scenario": "on-ramp", "duration": 2}
    info = record_expert_dataset("icv_envs/highway_formation-v0", 1, tmp_path / "ds", seed=3, config=cfg)
    bc = _bc()
    out = tmp_path / "bc"
    args = ["--config", json.dumps(cfg), "--dataset", str(tmp_path / "ds"), "--dagger-iters", "0", "--epochs", "30",
            "--net-arch", "32", "--eval-episodes", "0", "--out", str(out)]
    assert bc.main(args) == 0
    run = json.loads((out / "run.json").read_text())
    r0 = run["train"]["rounds"][0]
    assert r0["driver"] == "dataset" and r0["rollout"]["samples"] == info["steps"] == run["train"]["samples"]
    assert r0["fit"]["train_mse"] < 0.05  # the clone fits the expert's actions
    with pytest.raises(SystemExit, match="no dataset"):
        bc.main(args[:3] + [f"{tmp_path / 'ds'}::nope/x/expert-v0"] + args[4:])


def test_dataset_arrays_are_the_expert_actions(tmp_path, monkeypatch):
    from icv_envs.rl.dataset import record_expert_dataset
    from icv_envs.rl.envs import make_parallel_env

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "ds"))
    cfg = {"scenario": "on-ramp", "duration": 1}
    record_expert_dataset("icv_envs/highway_formation-v0", 1, tmp_path / "ds", seed=5, config=cfg)
    env = make_parallel_env("highway_formation_v0", cfg)
    X, Y, stats = _bc().load_dataset(str(tmp_path / "ds"), "highway_formation", env.observation_space("icv_0"),
                                     env.action_space("icv_0"))
    obs, infos = env.reset(seed=5)
    first = np.asarray(infos["icv_0"].get("expert_action", env.expert_actions()["icv_0"]), dtype=np.float32)
    assert np.array_equal(X[0], obs["icv_0"]) and np.allclose(Y[0], first)
