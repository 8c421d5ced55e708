"""The evaluation harness on all three envs: the reference methods (idm,
lane-lp on the highway-ramps env; single-vp, fcfs on the intersection) drive
through the env's expert_action, the env-specific metrics are reported, a
reference on the wrong env is a clear error, open-road episodes run to their
time limit, and the learned baselines train on and evaluate through the
intersection env (tiny budgets)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from icv_envs.rl.envs import env_family, episode_finished, make_parallel_env, resolve_env, step_until_agents
from icv_envs.rl.evaluate import EXPERT_METHODS, REFERENCE_POLICIES, evaluate, policy_names
from icv_envs.rl.evaluate import main as evaluate_main
from baseline_scripts import load_baseline

RAMPS = {"duration": 4.0}
INTER = {"duration": 4.0}
COMMON = ("collisions", "mean_speed", "speed_fluctuation", "exited", "episode_return", "episode_length")


@pytest.mark.parametrize("name, kind, family", [
    ("icv_envs/Intersection-v0", "gym", "intersection"),
    ("icv_envs/intersection-v0", "pettingzoo", "intersection"),
    ("intersection_v0", "pettingzoo", "intersection"),
    ("icv_envs.intersection_v0", "pettingzoo", "intersection"),
    ("icv_envs/HighwayRamps-v0", "gym", "highway_ramps"),
    ("icv_envs/highway_ramps-v0", "pettingzoo", "highway_ramps"),
    ("highway_ramps_v0", "pettingzoo", "highway_ramps"),
    ("icv_envs/HighwayFormation-v0", "gym", "highway_formation"),
    ("highway_formation_v0", "pettingzoo", "highway_formation"),
])
def test_env_ids_resolve(name, kind, family):
    spec = resolve_env(name)
    assert spec.kind == kind and env_family(name) == family == spec.family


@pytest.mark.parametrize("env, policy, config", [
    ("highway_ramps_v0", "idm", RAMPS),
    ("highway_ramps_v0", "lane-lp", RAMPS),
    ("icv_envs/HighwayRamps-v0", "lane-lp", RAMPS),
    ("intersection_v0", "single-vp", INTER),
    ("intersection_v0", "fcfs", INTER),
    ("icv_envs/Intersection-v0", "fcfs", INTER),
])
def test_reference_policies_evaluate_on_their_env(env, policy, config):
    res = evaluate(env, policy, episodes=2, seed=7, config=config)
    assert res["policy"] == res["algo"] == res["method"] == policy
    assert res["config"] == {**config, "method": policy}
    assert all(e["method"] == policy for e in res["per_episode"])  # the env ran that method
    assert [e["seed"] for e in res["per_episode"]] == [7, 8]
    for k in COMMON + ("lost",):
        assert k in res
    assert res["collisions"] == 0 and res["lost"] == 0
    assert res["episode_length"] == 20  # 4 s at 5 Hz: open-road episodes run to the time limit
    if "ntersection" in env:
        assert "achieved_throughput" in res and "mean_delay" in res
    json.dumps(res)


def test_expert_is_the_default_method_and_references_match_the_env():
    cases = (("highway_ramps_v0", RAMPS), ("intersection_v0", INTER), ("highway_formation_v0", {"duration": 2.0}))
    for env, cfg in cases:
        res = evaluate(env, "expert", episodes=1, seed=0, config=cfg)
        assert res["method"] == EXPERT_METHODS[resolve_env(env).family]
        assert res["config"] == cfg  # "expert" does not touch the config
    # the explicit default-method name drives exactly as "expert"
    a = evaluate("intersection_v0", "expert", episodes=1, seed=3, config=INTER)
    b = evaluate("intersection_v0", "multi-vp", episodes=1, seed=3, config=INTER)
    assert a["episode_return"] == b["episode_return"] and a["mean_speed"] == b["mean_speed"]
    assert policy_names("intersection_v0") == ["expert", "zero", "random", *REFERENCE_POLICIES["intersection"]]
    # every method the env has is a reference policy (the envs' own lists)
    assert set(REFERENCE_POLICIES["intersection"]) == {"multi-vp", "single-vp", "fcfs", "fcfs-tight"}
    assert policy_names("highway_formation_v0") == ["expert", "zero", "random"]


def test_intersection_metrics_with_traffic_in_the_box():
    # after an 80 s warm-up the first vehicles are at the box: some clear within 6 s
    res = evaluate("intersection_v0", "fcfs", episodes=1, seed=0, config={"duration": 6.0, "warmup": 80.0})
    assert res["cleared"] > 0 and res["achieved_throughput"] > 0 and res["mean_delay"] is not None
    assert res["lost"] == 0 and res["min_gap"] is None  # the intersection reports no min_gap


@pytest.mark.parametrize("env, policy, allowed", [
    ("highway_formation_v0", "fcfs", "none"),
    ("icv_envs/HighwayFormation-v0", "idm", "none"),
    ("intersection_v0", "idm", "multi-vp, single-vp, fcfs"),
    ("icv_envs/Intersection-v0", "lane-lp", "multi-vp, single-vp, fcfs"),
    ("highway_ramps_v0", "single-vp", "formation, lane-lp, idm"),
    ("icv_envs/HighwayRamps-v0", "fcfs", "formation, lane-lp, idm"),
])
def test_reference_on_the_wrong_env_is_an_error(env, policy, allowed):
    spec = resolve_env(env)
    with pytest.raises(ValueError, match=rf"policy '{policy}' is a reference method of the .* env, not of env "
                                         rf"'{spec.id}'.*reference methods: {allowed}"):
        evaluate(env, policy, episodes=1, config={"duration": 1.0})


def test_reference_bad_inputs_and_cli(capsys):
    with pytest.raises(ValueError, match=r"policy 'fcfs' sets config method 'fcfs', but config has method 'multi-vp'"):
        evaluate("intersection_v0", "fcfs", episodes=1, config={"method": "multi-vp", **INTER})
    with pytest.raises(ValueError, match=r"neither a known policy nor an existing path"):
        evaluate("intersection_v0", "fcfs-typo", episodes=1, config=INTER)
    assert evaluate_main(["--env", "icv_envs/intersection-v0", "--policy", "fcfs", "--episodes", "1",
                          "--config", json.dumps(INTER)]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["policy"] == last["method"] == "fcfs" and "achieved_throughput" in last
    assert evaluate_main(["--env", "highway_formation_v0", "--policy", "idm", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert "policy 'idm'" in err and "highway_ramps" in err and "highway_formation-v0" in err


def test_open_road_runs_to_the_time_limit():
    """One vehicle (max_vehicles=1) crosses and leaves at about 86 s; the road
    is then empty, but the episode runs on to its 100 s."""
    res = evaluate("intersection_v0", "expert", episodes=1, seed=0, config={"duration": 100.0, "max_vehicles": 1})
    assert res["exited"] == 1 and res["sim_seconds"] == pytest.approx(100.0) and res["episode_length"] == 500
    env = make_parallel_env("intersection_v0", {"duration": 100.0, "max_vehicles": 1})
    obs, infos = env.reset(seed=0)
    while env.agents:
        obs, *_, infos = env.step({a: infos[a]["expert_action"] for a in env.agents})
    assert not episode_finished(env) and not env.episode_over  # empty road, time not up
    assert len(step_until_agents(env)) > 0 and episode_finished(env) and env.episode_over


# ------------------------------------------------------------- learned policies
def _script(name):
    pytest.importorskip("stable_baselines3")
    torch = pytest.importorskip("torch")
    torch.set_num_threads(1)
    return load_baseline(name)


@pytest.fixture(scope="module")
def intersection_models(tmp_path_factory):
    root = tmp_path_factory.mktemp("int_models")
    cfg = json.dumps(INTER)
    out = {"ppo_shared": root / "ppo_shared", "bc_expert": root / "bc_expert"}
    assert _script("ppo_shared").main(
        ["--env", "intersection_v0", "--total-timesteps", "1000", "--n-steps", "8", "--batch-size", "130",
         "--n-epochs", "1", "--config", cfg, "--seed", "1", "--out", str(out["ppo_shared"]),
         "--eval-episodes", "1"]) == 0
    assert _script("bc_expert").main(
        ["--env", "intersection_v0", "--expert-steps", "20", "--dagger-iters", "1", "--dagger-steps", "10",
         "--epochs", "2", "--net-arch", "32,32", "--config", cfg, "--seed", "1", "--out", str(out["bc_expert"]),
         "--eval-episodes", "1"]) == 0
    return out


@pytest.mark.parametrize("name", ["ppo_shared", "bc_expert"])
def test_learned_policies_on_the_intersection(intersection_models, name, tmp_path):
    d = intersection_models[name]
    run = json.loads((d / "run.json").read_text())
    assert run["algo"] == name and run["env"] == "icv_envs/intersection-v0" and run["config"] == INTER
    assert run["observation_shape"] == [8, 14] and run["action_shape"] == [2]
    assert "achieved_throughput" in run["eval"] and "lost" in run["eval"]
    if name == "bc_expert":
        assert run["scenarios"] == [] and "eval_by_scenario" not in run
    res = evaluate("intersection_v0", str(d), episodes=2, seed=5, out=tmp_path)
    assert res["algo"] == name and res["mode"] == "all-agents" and res["config"] == INTER
    assert res["episode_length"] == 20 and res["lost"] == 0 and np.isfinite(res["episode_return"])
    assert json.loads((tmp_path / "eval.json").read_text())["achieved_throughput"] == res["achieved_throughput"]
    ego = evaluate("icv_envs/Intersection-v0", str(d), episodes=1, seed=5)  # the same model drives the ego
    assert ego["mode"] == "ego" and ego["trained_on"] == "icv_envs/intersection-v0"
    # a model trained on the intersection does not fit the highway observation (8, 13)
    with pytest.raises(ValueError, match=r"observation shape \(8, 14\).*observation shape \(8, 13\)"):
        evaluate("highway_formation_v0", str(d), episodes=1, config={"duration": 1.0})


def test_bc_expert_rejects_scenarios_off_the_highway(capsys):
    with pytest.raises(SystemExit) as e:
        _script("bc_expert").main(["--env", "intersection_v0", "--scenarios", "lane-drop"])
    assert e.value.code == 2 and "has no scenarios" in capsys.readouterr().err


def test_adapter_skips_the_empty_road():
    """ParallelVecEnv on the open road: after the only vehicle leaves (about
    86 s) the copy is stepped without actions to its 100 s inside one VecEnv
    step, then reset; no VecEnv step sees a copy without agents."""
    pytest.importorskip("stable_baselines3")
    from icv_envs.rl.vec_env import ParallelVecEnv

    venv = ParallelVecEnv(lambda: make_parallel_env("intersection_v0", {"duration": 100.0, "max_vehicles": 1}), seed=0)
    venv.reset()
    assert venv.num_envs == 1 and venv.active.all()
    for step in range(1, 600):
        _obs, _rew, dones, infos = venv.step(np.zeros((1, 2), dtype=np.float32))
        assert venv.active.all()  # the new episode's vehicle holds the slot at once
        if dones[0]:
            break
    assert infos[0]["episode_reset"] and not infos[0]["TimeLimit.truncated"]  # it exited: a terminal success
    assert infos[0]["exited"] and infos[0]["episode"]["l"] == step
    assert step + venv.empty_env_steps == 500 and venv.empty_env_steps > 0
    venv.close()
