"""The three baselines train with tiny budgets, save, and load and evaluate
through the harness; ppo_shared is reproducible; the harness rejects bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from icv_envs.rl.evaluate import evaluate  # noqa: E402
from icv_envs.rl.evaluate import main as evaluate_main  # noqa: E402
from baseline_scripts import load_baseline

torch.set_num_threads(1)

SHORT = {"duration": 4.0}  # 20 policy steps per episode keeps the tests fast
METRICS = ("collisions", "mean_speed", "speed_fluctuation", "min_gap", "exited", "episode_return")


def _script(name):
    return load_baseline(name)


@pytest.fixture(scope="module")
def scripts():
    return {n: _script(n) for n in ("ppo_single", "ppo_shared", "bc_expert")}


@pytest.fixture(scope="module")
def trained(scripts, tmp_path_factory):
    """One tiny model per script."""
    root = tmp_path_factory.mktemp("models")
    cfg = json.dumps(SHORT)
    out = {n: root / n for n in scripts}
    assert scripts["ppo_single"].main(
        ["--total-timesteps", "3072", "--n-steps", "512", "--batch-size", "128", "--n-epochs", "1",
         "--config", cfg, "--seed", "1", "--out", str(out["ppo_single"]), "--eval-episodes", "1"]) == 0
    assert scripts["ppo_shared"].main(
        ["--total-timesteps", "4096", "--n-steps", "64", "--batch-size", "128", "--n-epochs", "1",
         "--config", cfg, "--seed", "1", "--out", str(out["ppo_shared"]), "--eval-episodes", "1"]) == 0
    assert scripts["bc_expert"].main(
        ["--expert-steps", "60", "--dagger-iters", "1", "--dagger-steps", "20", "--epochs", "2",
         "--net-arch", "32,32", "--scenarios", "free,on-ramp", "--config", cfg, "--seed", "1",
         "--out", str(out["bc_expert"]), "--eval-episodes", "1"]) == 0
    return out


@pytest.mark.parametrize("name", ["ppo_single", "ppo_shared", "bc_expert"])
def test_script_outputs(trained, name):
    d = trained[name]
    assert (d / "model.zip").is_file()
    run = json.loads((d / "run.json").read_text())
    assert run["algo"] == name
    assert run["config"] == SHORT
    assert run["observation_shape"] == [8, 13] and run["action_shape"] == [2]
    assert run["env_kind"] == ("gym" if name == "ppo_single" else "pettingzoo")
    for k in METRICS:
        assert k in run["eval"]
    if name == "bc_expert":
        assert set(run["eval_by_scenario"]) == {"free", "on-ramp"}
        assert [r["driver"] for r in run["train"]["rounds"]] == ["expert", "learner"]
        assert run["train"]["final"]["train_mse"] < 1.0
        assert run["train"]["saved_round"] in (0, 1)  # the better-scoring fit
        assert "score_rollout" in run["train"]["rounds"][-1]


@pytest.mark.parametrize("name", ["ppo_single", "ppo_shared", "bc_expert"])
@pytest.mark.parametrize("env", ["icv_envs/highway_formation-v0", "icv_envs/HighwayFormation-v0"])
def test_models_evaluate_through_the_harness(trained, name, env, tmp_path):
    res = evaluate(env, str(trained[name]), episodes=2, seed=3, out=tmp_path)
    assert res["algo"] == name and res["episodes"] == 2
    assert res["mode"] == ("all-agents" if "highway_formation-v0" in env else "ego")
    assert res["config"] == SHORT  # taken from run.json
    for k in METRICS:
        assert k in res
    assert [e["seed"] for e in res["per_episode"]] == [3, 4]
    assert np.isfinite(res["episode_return"])
    assert json.loads((tmp_path / "eval.json").read_text())["episode_return"] == res["episode_return"]
    # the model.zip path works too, and a seeded evaluation repeats exactly
    again = evaluate(env, str(trained[name] / "model.zip"), episodes=2, seed=3)
    assert again["episode_return"] == res["episode_return"]


def test_named_policies_and_cli(capsys):
    exp = evaluate("highway_formation_v0", "expert", episodes=1, seed=0, config={"scenario": "lane-drop", **SHORT})
    assert exp["collisions"] == 0 and exp["episode_length"] == 20
    r1 = evaluate("icv_envs/HighwayFormation-v0", "random", episodes=2, seed=5, config=SHORT)
    r2 = evaluate("icv_envs/HighwayFormation-v0", "random", episodes=2, seed=5, config=SHORT)
    assert r1["episode_return"] == r2["episode_return"]
    assert evaluate_main(["--env", "icv_envs/highway_formation-v0", "--policy", "zero", "--episodes", "1",
                          "--config", json.dumps(SHORT)]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert json.loads(last)["policy"] == "zero"


def test_ppo_shared_is_reproducible(scripts, tmp_path):
    argv = ["--total-timesteps", "768", "--n-steps", "32", "--batch-size", "128", "--n-epochs", "2",
            "--config", json.dumps(SHORT), "--eval-episodes", "0"]
    for tag, seed in (("a", "4"), ("b", "4"), ("c", "5")):
        assert scripts["ppo_shared"].main(argv + ["--seed", seed, "--out", str(tmp_path / tag)]) == 0
    from stable_baselines3 import PPO

    params = {t: PPO.load(tmp_path / t / "model.zip", device="cpu").policy.state_dict() for t in "abc"}
    assert params["a"].keys() == params["b"].keys()
    assert all(torch.equal(params["a"][k], params["b"][k]) for k in params["a"])
    assert not all(torch.equal(params["a"][k], params["c"][k]) for k in params["a"])


def test_bad_inputs(trained, capsys):
    with pytest.raises(ValueError, match=r"unknown env 'nope-v0'; known envs: .*icv_envs/HighwayFormation-v0"):
        evaluate("nope-v0", "expert", episodes=1)
    with pytest.raises(ValueError, match=r"neither a known policy nor an existing path"):
        evaluate("highway_formation_v0", str(trained["ppo_shared"] / "missing"), episodes=1)
    with pytest.raises(ValueError, match=r"no model.zip"):
        evaluate("highway_formation_v0", str(trained["ppo_shared"].parent), episodes=1)
    # the same model against an env whose observation has 4 rows instead of 8
    other = {"observation": {"vehicles_count": 4}, **SHORT}
    with pytest.raises(ValueError, match=r"observation shape \(8, 13\).*env 'icv_envs/highway_formation-v0'.*"
                                         r"observation shape \(4, 13\)"):
        evaluate("highway_formation_v0", str(trained["ppo_shared"]), episodes=1, config=other)
    with pytest.raises(ValueError, match=r"episodes"):
        evaluate("highway_formation_v0", "expert", episodes=0)
    # the CLI turns them into exit status 2 and a message
    assert evaluate_main(["--env", "nope-v0", "--policy", "expert"]) == 2
    assert "known envs" in capsys.readouterr().err


def test_scripts_help_and_env_kind_errors(scripts, capsys):
    for mod in scripts.values():
        with pytest.raises(SystemExit) as e:
            mod.main(["--help"])
        assert e.value.code == 0
    with pytest.raises(SystemExit) as e:
        scripts["ppo_single"].main(["--env-id", "icv_envs/highway_formation-v0"])
    assert e.value.code == 2 and "ppo_shared" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        scripts["ppo_shared"].main(["--env", "icv_envs/HighwayFormation-v0"])
    with pytest.raises(SystemExit):
        scripts["bc_expert"].main(["--config", "{not json"])
