"""Ensembles of saved models (icv_envs.rl.models.write_ensemble): the mean action of the members,
loadable wherever a model is (evaluate, leaderboard), and clear errors for members that do not fit."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")
torch.set_num_threads(1)

CFG = {"scenario": "on-ramp", "duration": 2}


def _model(d, seed, config=CFG, action=None):
    from stable_baselines3 import PPO

    from icv_envs.rl.envs import make_parallel_env
    from icv_envs.rl.models import write_run_json
    from icv_envs.rl.vec_env import ParallelVecEnv

    cfg = dict(config, **({"action": {"type": action}} if action else {}))
    venv = ParallelVecEnv(lambda: make_parallel_env("highway_formation_v0", cfg), seed=0)
    d.mkdir(parents=True, exist_ok=True)
    PPO("MlpPolicy", venv, n_steps=8, batch_size=8, seed=seed, device="cpu").save(d / "model.zip")
    write_run_json(d, {"algo": "bc_expert", "env": "icv_envs/highway_formation-v0", "config": cfg})
    venv.close()
    return d


def test_ensemble_acts_by_the_members_mean(tmp_path):
    from icv_envs.rl.models import LoadedEnsemble, load_model, write_ensemble

    a, b = _model(tmp_path / "a", 0), _model(tmp_path / "b", 1)
    write_ensemble(tmp_path / "ens", [a, b])
    meta = json.loads((tmp_path / "ens" / "run.json").read_text())
    assert meta["algo"] == "ensemble" and meta["members"] == ["../a", "../b"] and meta["config"] == CFG
    ens = load_model(tmp_path / "ens")
    assert isinstance(ens, LoadedEnsemble)
    obs = np.random.default_rng(0).normal(size=(5, *ens.observation_space.shape)).astype(np.float32)
    ma, mb = load_model(a).act(obs), load_model(b).act(obs)
    assert not np.allclose(ma, mb)
    got = ens.act(obs)
    assert got.dtype == np.float32 and np.allclose(got, (ma.astype(np.float64) + mb) / 2, atol=1e-7)
    with pytest.raises(ValueError, match="deterministic=False"):
        ens.act(obs, deterministic=False)


def test_discrete_ensemble_votes_by_mean_probability(tmp_path):
    from icv_envs.rl.models import load_model, write_ensemble

    a = _model(tmp_path / "a", 0, action="DiscreteMetaAction")
    b = _model(tmp_path / "b", 1, action="DiscreteMetaAction")
    write_ensemble(tmp_path / "same", [a, a])
    write_ensemble(tmp_path / "ab", [a, b])
    ma, mb = load_model(a), load_model(b)
    obs = np.random.default_rng(1).normal(size=(64, *ma.observation_space.shape)).astype(np.float32)
    same = load_model(tmp_path / "same").act(obs)
    assert same.dtype == np.int64 and np.array_equal(same, ma.act(obs).astype(np.int64))

    def probs(m):
        t, _ = m.model.policy.obs_to_tensor(obs)
        return m.model.policy.get_distribution(t).distribution.probs.detach().numpy()

    want = np.argmax(probs(ma) + probs(mb), axis=1)
    assert np.array_equal(load_model(tmp_path / "ab").act(obs), want)
    assert load_model(tmp_path / "ab").act(obs[:0]).shape == (0,)


def test_ensemble_is_evaluated_like_a_model(tmp_path):
    from icv_envs.rl.evaluate import evaluate
    from icv_envs.rl.models import write_ensemble

    write_ensemble(tmp_path / "ens", [_model(tmp_path / "a", 0), _model(tmp_path / "b", 1)])
    res = evaluate("icv_envs/highway_formation-v0", str(tmp_path / "ens"), episodes=1, seed=3)
    assert res["algo"] == "ensemble" and res["episodes"] == 1 and res["config"] == CFG


def test_ensemble_bad_members_are_clear_errors(tmp_path):
    from icv_envs.rl.models import load_model, write_ensemble

    a = _model(tmp_path / "a", 0)
    other = _model(tmp_path / "o", 1, config={"scenario": "lane-drop", "duration": 2})
    with pytest.raises(ValueError, match="differs from"):
        write_ensemble(tmp_path / "e1", [a, other])
    assert not (tmp_path / "e1" / "run.json").exists()
    meta = _model(tmp_path / "m", 2, action="DiscreteMetaAction")
    with pytest.raises(ValueError, match="differs from"):  # another action type: another config
        write_ensemble(tmp_path / "e2", [a, meta])
    with pytest.raises(ValueError, match="at least two"):
        write_ensemble(tmp_path / "e3", [a])
    (tmp_path / "e4").mkdir()
    (tmp_path / "e4" / "run.json").write_text(json.dumps({"algo": "ensemble", "members": ["../a", "../nope"]}))
    with pytest.raises(ValueError, match="nope"):
        load_model(tmp_path / "e4")


def test_leaderboard_cache_of_an_ensemble_follows_its_members(tmp_path):
    """A cached evaluation of an ensemble is stale once a member is retrained (newer model.zip)."""
    import os

    from icv_envs.rl.leaderboard import _newest_model_file
    from icv_envs.rl.models import write_ensemble

    a, b = _model(tmp_path / "a", 0), _model(tmp_path / "b", 1)
    meta = json.loads(write_ensemble(tmp_path / "ens", [a, b]).read_text())
    run = tmp_path / "ens" / "run.json"
    os.utime(a / "model.zip", (1, 1))
    os.utime(b / "model.zip", (2, 2))
    assert _newest_model_file(tmp_path / "ens", meta) == run
    later = run.stat().st_mtime + 10
    os.utime(b / "model.zip", (later, later))
    assert _newest_model_file(tmp_path / "ens", meta).resolve() == (b / "model.zip").resolve()
