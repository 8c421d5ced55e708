"""Bad input to icv_envs.rl is a clear ValueError naming the argument, never a crash deep inside,
silently wrong output or an argument accepted and then ignored (tiny envs: 4 vehicles, 2 s)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

TINY = {"vehicles_count": 4, "duration": 2}
DISCRETE = dict(TINY, action={"type": "DiscreteMetaAction"})


# ---------------------------------------------------------------- bench
@pytest.mark.parametrize("kw, name", [
    ({"steps": 0}, "steps"), ({"steps": -1}, "steps"), ({"steps": 2.5}, "steps"),
    ({"vehicles": 4.9}, "vehicles"), ({"vehicles": "4"}, "vehicles"), ({"vehicles": True}, "vehicles"),
    ({"worlds": 0}, "worlds"), ({"worlds": 1.5}, "worlds"), ({"seed": -1}, "seed"), ({"seed": 0.5}, "seed"),
    ({"expert": "no"}, "expert"), ({"config": [1]}, "config"),
])
def test_batched_sps_rejects_bad_arguments(kw, name):
    from icv_envs.rl.bench import batched_sps

    args = dict(vehicles=4, worlds=2, steps=2, config={"duration": 2})
    with pytest.raises(ValueError, match=rf"^{name} = "):
        batched_sps(**{**args, **kw})


def test_batched_sps_config_clashing_with_an_argument_is_an_error():
    from icv_envs.rl.bench import batched_sps

    with pytest.raises(ValueError, match=r"vehicles_count'\] = 6 clashes with vehicles = 4"):
        batched_sps(vehicles=4, worlds=2, steps=2, config={"vehicles_count": 6, "duration": 2})


@pytest.mark.parametrize("kw, name", [({"steps": -5}, "steps"), ({"steps": 0}, "steps"), ({"steps": 2.5}, "steps"),
                                      ({"vehicles": 4.9}, "vehicles"), ({"seed": -1}, "seed")])
def test_env_sps_rejects_bad_numbers(kw, name):
    from icv_envs.rl.bench import ICV_ID, env_sps

    with pytest.raises(ValueError, match=rf"^{name} = "):
        env_sps(ICV_ID, **{"vehicles": 4, "steps": 3, **kw})


# ---------------------------------------------------------------- slots
def test_slot_env_step_rejects_unknown_keys_and_non_dicts():
    from icv_envs.rl.slots import slot_parallel_env

    env = slot_parallel_env("highway_formation_v0", TINY)
    env.reset(seed=0)
    zero = np.zeros(2, dtype=np.float32)
    with pytest.raises(ValueError, match=r"not slots: \['slot_99', 'icv_0'\]; allowed: \['slot_0'"):
        env.step({"slot_99": zero, "icv_0": zero, "slot_0": zero})
    with pytest.raises(ValueError, match="must be a dict.*got list"):
        env.step([zero] * env.K)
    env.step({s: zero for s in env.agents})  # the valid form still steps


def test_vehicle_episodes_step_rejects_unknown_keys_and_non_dicts():
    from icv_envs.rl.slots import vehicle_slots_env

    env = vehicle_slots_env("highway_formation_v0", TINY)
    env.reset(seed=0)
    zero = np.zeros(2, dtype=np.float32)
    with pytest.raises(ValueError, match=r"not agents.*\['slot_99'\]"):
        env.step({"slot_99": zero, "slot_0": zero})
    with pytest.raises(ValueError, match="must be a dict.*got list"):
        env.step([zero])
    env.step({s: zero for s in env.agents})


@pytest.mark.parametrize("z", [math.nan, -math.inf, math.inf, "1", -100, -0.5, True, None])
def test_slot_margin_z_is_validated(z):
    from icv_envs.rl.envs import make_parallel_env
    from icv_envs.rl.slots import SlotParallelEnv, slot_count, slot_parallel_env

    par = make_parallel_env("intersection_v0", {"duration": 4, "missing_action": "expert"})
    with pytest.raises(ValueError, match=r"^z = "):
        slot_count(par, z)
    with pytest.raises(ValueError, match=r"^z = "):
        SlotParallelEnv(par, z=z)
    with pytest.raises(ValueError, match=r"^z = "):
        slot_parallel_env("intersection_v0", {"duration": 4}, z=z)


def test_slot_margin_z_valid_values_unchanged():
    from icv_envs.rl.envs import make_parallel_env
    from icv_envs.rl.slots import slot_count

    par = make_parallel_env("intersection_v0", {"duration": 4, "missing_action": "expert"})
    assert slot_count(par, 0) <= slot_count(par) == slot_count(par, 1.0) <= slot_count(par, np.float32(2.5))


# ---------------------------------------------------------------- vec_env
def _vec_fn():
    from icv_envs.rl.envs import make_parallel_env

    return make_parallel_env("highway_formation_v0", TINY)


@pytest.mark.parametrize("kw, name", [({"seed": 1.7}, "seed"), ({"seed": "5"}, "seed"), ({"seed": "abc"}, "seed"),
                                      ({"seed": True}, "seed"), ({"seed": -1}, "seed"),
                                      ({"n_copies": True}, "n_copies"), ({"n_copies": 1.0}, "n_copies")])
def test_parallel_vec_env_rejects_bad_seed_and_copies(kw, name):
    pytest.importorskip("stable_baselines3")
    from icv_envs.rl.vec_env import ParallelVecEnv

    with pytest.raises(ValueError, match=rf"^{name} = "):
        ParallelVecEnv(_vec_fn, **kw)


def test_parallel_vec_env_rejects_bad_env_fn_and_calls():
    pytest.importorskip("stable_baselines3")
    from icv_envs.rl.vec_env import ParallelVecEnv

    with pytest.raises(ValueError, match="env_fn returned None"):
        ParallelVecEnv(lambda: None)
    with pytest.raises(ValueError, match="env_fn = 5; allowed: a callable"):
        ParallelVecEnv(5)
    v = ParallelVecEnv(_vec_fn, seed=0)
    for bad in (2.9, "5", -3):
        with pytest.raises(ValueError, match=r"^seed = "):
            v.seed(bad)
    assert v.seed(7)[0] == 7
    v.reset()
    with pytest.raises(ValueError, match=r"actions have shape \(\)"):
        v.step(np.float32(0))
    with pytest.raises(ValueError, match="agent = 'nope'; allowed: one of the possible agents"):
        v.slot(0, "nope")
    with pytest.raises(ValueError, match=r"copy = 1; allowed: an integer in 0 \.\. 0"):
        v.slot(1, "icv_0")
    for bad in (10**6, -1, v.num_envs, 1.0, True):
        with pytest.raises(ValueError, match=rf"i = .*; allowed: an integer in 0 \.\. {v.num_envs - 1}"):
            v.slot_agent(bad)
    assert v.slot_agent(v.num_envs - 1) == (0, v.possible_agents[-1]) and v.slot(0, "icv_1") == 1
    v.close()


# ---------------------------------------------------------------- envs
def test_parse_config_takes_a_path_and_rejects_other_types(tmp_path):
    from icv_envs.rl.envs import parse_config

    f = tmp_path / "cfg.json"
    f.write_text(json.dumps({"duration": 3}))
    assert parse_config(f) == parse_config(str(f)) == {"duration": 3}
    with pytest.raises(ValueError, match="does not exist"):
        parse_config(tmp_path / "x.json")
    for bad in (123, [1], b"{}"):
        with pytest.raises(ValueError, match="allowed: None, a dict, a JSON object string"):
            parse_config(bad)


def test_make_env_config_must_be_a_dict():
    from icv_envs.rl.envs import make_gym_env, make_parallel_env

    with pytest.raises(ValueError, match=r"config = \[1\]; allowed: None or a dict"):
        make_gym_env("icv_envs/HighwayFormation-v0", config=[1])
    with pytest.raises(ValueError, match="config = 'x'; allowed: None or a dict"):
        make_parallel_env("highway_formation_v0", config="x")
    with pytest.raises(ValueError, match=r"config = \[\]; allowed: None or a dict"):
        make_parallel_env("highway_formation_v0", config=[])


# ---------------------------------------------------------------- evaluate
@pytest.mark.parametrize("env", ["highway_formation_v0", "icv_envs/HighwayFormation-v0"])
def test_evaluate_random_with_discrete_actions_is_uniform_and_seeded(env):
    from icv_envs.rl.evaluate import evaluate

    a = evaluate(env, "random", episodes=1, seed=3, config=DISCRETE)
    b = evaluate(env, "random", episodes=1, seed=3, config=DISCRETE)
    assert a["per_episode"] == b["per_episode"] and a["episode_length"] > 0


def test_evaluate_zero_with_discrete_actions_is_idle():
    """``zero`` (coast straight) is the IDLE meta-action, not index 0 (LANE_LEFT)."""
    from icv_envs.envs.actions import DiscreteMetaAction
    from icv_envs.rl.envs import episode_finished, make_parallel_env
    from icv_envs.rl.evaluate import evaluate

    idle = next(k for k, a in DiscreteMetaAction.ACTIONS_ALL.items() if a == "IDLE")
    env = make_parallel_env("highway_formation_v0", DISCRETE)
    env.reset(seed=2)
    total = 0.0
    while not episode_finished(env):
        _, rew, _, _, _ = env.step({a: idle for a in env.agents})
        total += float(sum(rew.values()))
    env.close()
    res = evaluate("highway_formation_v0", "zero", episodes=1, seed=2, config=DISCRETE)
    assert res["episode_return"] == total


@pytest.mark.parametrize("env", ["highway_formation_v0", "icv_envs/HighwayFormation-v0"])
def test_evaluate_expert_with_discrete_actions_is_a_clear_error(env):
    from icv_envs.rl.evaluate import evaluate

    with pytest.raises(ValueError, match="policy 'expert'.*action type 'DiscreteMetaAction'"):
        evaluate(env, "expert", episodes=1, config=DISCRETE)


def test_evaluate_cli_random_with_discrete_actions(capsys):
    from icv_envs.cli import main

    assert main(["evaluate", "--env", "highway_formation_v0", "--policy", "random", "--episodes", "1",
                 "--config", json.dumps(DISCRETE)]) == 0
    assert json.loads(capsys.readouterr().out)["policy"] == "random"


@pytest.mark.parametrize("bad", ["no", 1, None])
def test_evaluate_deterministic_must_be_a_bool(bad):
    from icv_envs.rl.evaluate import evaluate

    with pytest.raises(ValueError, match="deterministic = "):
        evaluate("highway_formation_v0", "zero", episodes=1, config=TINY, deterministic=bad)


# ---------------------------------------------------------------- leaderboard
@pytest.fixture
def no_eval(monkeypatch):
    """Any evaluation fails the test: the bad input must be caught before one runs."""
    import icv_envs.rl.leaderboard as lb

    def evaluate(*a, **k):
        raise RuntimeError("an evaluation ran before the bad input was caught")

    monkeypatch.setattr(lb, "evaluate", evaluate)
    return lb


def test_leaderboard_missing_models_dir_is_an_error(tmp_path, no_eval):
    from icv_envs.cli import main

    with pytest.raises(ValueError, match="models_dir = .*typo.* is not an existing directory"):
        no_eval.run_leaderboard(tmp_path / "out", tmp_path / "typo", tasks=["lane-drop"], progress=False)
    with pytest.raises(ValueError, match="not an existing directory"):
        no_eval.find_models(tmp_path / "typo", no_eval.TASKS["lane-drop"])
    assert main(["leaderboard", "--out", str(tmp_path / "out"), "--models", str(tmp_path / "typo"),
                 "--tasks", "lane-drop"]) == 2
    assert not (tmp_path / "out").exists()


def test_leaderboard_empty_and_duplicate_tasks_are_errors(tmp_path, no_eval):
    from icv_envs.cli import main

    for tasks, match in (([], "empty"), (["lane-drop", "lane-drop"], r"\['lane-drop'\] given more than once"),
                         ("lane-drop", "a list of task names")):
        with pytest.raises(ValueError, match=match):
            no_eval.run_leaderboard(tmp_path / "out", tmp_path, tasks=tasks, progress=False)
    for tasks in ("", "lane-drop,lane-drop"):
        assert main(["leaderboard", "--out", str(tmp_path / "out"), "--models", str(tmp_path),
                     "--tasks", tasks]) == 2
    assert not (tmp_path / "out").exists()


def test_leaderboard_bad_backend_is_caught_before_evaluating(tmp_path, no_eval):
    with pytest.raises(ValueError, match="backend 'scipy' is invalid"):
        no_eval.run_leaderboard(tmp_path / "out", tmp_path, tasks=["lane-drop"], backend="scipy", progress=False)


# ---------------------------------------------------------------- models
def test_write_ensemble_never_clobbers_and_checks_members_first(tmp_path):
    from icv_envs.rl.models import write_ensemble

    model = tmp_path / "model"
    model.mkdir()
    (model / "model.zip").write_bytes(b"not really a zip")
    run = '{"algo": "ppo_recipe", "config": {"scenario": "on-ramp"}}'
    (model / "run.json").write_text(run)
    missing = [str(tmp_path / "nonexist1"), str(tmp_path / "nonexist2")]
    with pytest.raises(ValueError, match="holds a model"):
        write_ensemble(model, missing)
    assert (model / "run.json").read_text() == run and (model / "model.zip").read_bytes() == b"not really a zip"
    with pytest.raises(ValueError, match="ensemble member .*nonexist1.* does not exist") as err:
        write_ensemble(tmp_path / "ens", missing)
    assert "expert" not in str(err.value) and "policy" not in str(err.value)
    assert not (tmp_path / "ens").exists()
    with pytest.raises(ValueError, match="ensemble member .* holds no model.zip"):
        write_ensemble(tmp_path / "ens", [tmp_path, tmp_path])
    for bad in ("ab", str(model), None, [1, 2]):
        with pytest.raises(ValueError, match=r"^members = .*allowed: a list or tuple"):
            write_ensemble(tmp_path / "ens", bad)
    assert not (tmp_path / "ens").exists()


# ---------------------------------------------------------------- dataset
def test_record_expert_dataset_checks_seed_and_id_before_recording(tmp_path, monkeypatch):
    pytest.importorskip("minari")
    from icv_envs.rl.dataset import record_expert_dataset

    out = tmp_path / "ds"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(out))  # (restored after the test; the recording sets it)
    for kw, match in (({"seed": -1}, r"^seed = -1"), ({"seed": 1.5}, r"^seed = 1.5"),
                      ({"dataset_id": "bogus"}, "dataset_id = 'bogus'.*name-vN"),
                      ({"dataset_id": "a/b-v0"}, "dataset_id = 'a/b-v0'"), ({"dataset_id": 5}, "dataset_id = 5")):
        with pytest.raises(ValueError, match=match):
            record_expert_dataset("icv_envs/HighwayFormation-v0", 1, out, config=TINY, **kw)
    assert not out.exists()  # nothing recorded, no stray directory
    res = record_expert_dataset("icv_envs/HighwayFormation-v0", 1, out, config=TINY)
    assert res["dataset_id"] == "icv_envs/highway_formation/expert-v0" and res["episodes"] == 1
    assert Path(res["path"]) == out.resolve()


@pytest.mark.parametrize("env_id, base", [("icv_envs/HighwayFormation-v0", {"duration": 4.0}),
                                          ("icv_envs.envs.highway_formation_v0", TINY)])
def test_evaluate_expert_is_the_expert_whatever_the_action_type_and_infos(env_id, base):
    """``evaluate(..., "expert")`` under ``FormationResidual`` sent the raw
    ``[u_a, u_s]`` as the residual (the vehicles applied expert + 0.25 x
    expert), and with ``expert_in_info=False`` the Gym path drove zeros
    (stop 45); both now drive exactly as the expert under the default type."""
    from icv_envs.rl.evaluate import evaluate

    ref = evaluate(env_id, "expert", episodes=1, seed=3, config=dict(base))
    for extra in ({"action": {"type": "FormationResidual"}}, {"expert_in_info": False}):
        got = evaluate(env_id, "expert", episodes=1, seed=3, config={**base, **extra})
        for k in ("mean_speed", "speed_fluctuation", "episode_return", "collisions"):
            assert got[k] == ref[k], (extra, k)


def test_run_policies_act_in_the_env_action_type():
    """``run highway-formation --policy``: the expert in the env's action type
    (FormationResidual: the zero residual, the same run as the default type;
    DiscreteMetaAction: an error naming the policy), ``zero`` IDLE and
    ``random`` sampled from the discrete space (each failed at the first step
    with the env's error about a [0, 0] or random float action)."""
    from icv_envs.experiments.run import run_highway_formation

    ref = run_highway_formation("free", "expert", seconds=2.0, seed=1)
    res = run_highway_formation("free", "expert", seconds=2.0, seed=1,
                                config={"action": {"type": "FormationResidual"}})
    assert res["mean_speed"] == ref["mean_speed"] and res["formation_error_x"] == ref["formation_error_x"]
    disc = {"action": {"type": "DiscreteMetaAction"}}
    with pytest.raises(ValueError, match="policy 'expert' drives with the expert's continuous"):
        run_highway_formation("free", "expert", seconds=2.0, seed=1, config=disc)
    for p in ("zero", "random"):
        assert run_highway_formation("free", p, seconds=2.0, seed=1, config=disc)["collisions"] >= 0
