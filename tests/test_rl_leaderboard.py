"""The leaderboard code path on a tiny budget, its interval estimates and model matching."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
torch.set_num_threads(1)

from icv_envs.rl import leaderboard as lb  # noqa: E402


def test_interval_estimates_numpy_matches_definition():
    x = np.arange(8, dtype=float)
    est = lb.interval_estimates(x, reps=200, seed=0, backend="numpy")
    assert est["mean"] == pytest.approx(3.5)
    assert est["iqm"] == pytest.approx(np.mean([2, 3, 4, 5]))  # middle half
    assert est["mean_lo"] <= est["mean"] <= est["mean_hi"]
    assert est["iqm_lo"] <= est["iqm"] <= est["iqm_hi"]
    assert lb.interval_estimates(x, reps=200, seed=0, backend="numpy") == est  # fixed random state
    const = lb.interval_estimates(np.full(5, 2.0), reps=50, backend="numpy")
    assert const["mean_lo"] == const["mean_hi"] == 2.0


def test_interval_estimates_rliable_agrees_with_numpy():
    pytest.importorskip("rliable")
    try:
        from rliable import library  # noqa: F401
    except Exception as exc:  # noqa: BLE001 - rliable's arch pin against pandas 3
        pytest.skip(f"rliable does not import here: {exc}")
    x = np.random.default_rng(1).normal(size=12)
    a = lb.interval_estimates(x, reps=2000, backend="rliable")
    b = lb.interval_estimates(x, reps=2000, backend="numpy")
    assert a["ci_backend"] == "rliable"
    assert a["mean"] == pytest.approx(b["mean"]) and a["iqm"] == pytest.approx(b["iqm"])
    assert a["mean_lo"] == pytest.approx(b["mean_lo"], abs=0.15) and a["mean_hi"] == pytest.approx(b["mean_hi"], abs=0.15)


def test_bad_input_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="unknown tasks"):
        lb.run_leaderboard(tmp_path, tmp_path, tasks=["nope"])
    with pytest.raises(ValueError, match="episodes"):
        lb.run_leaderboard(tmp_path, tmp_path, tasks=["on-ramp"], episodes=0)
    with pytest.raises(ValueError, match="backend"):
        lb.interval_estimates([1.0], backend="scipy")


def test_model_fits():
    t = lb.TASKS["lane-drop"]
    assert lb.model_fits({"env": "icv_envs/highway_formation-v0", "config": {"scenario": "lane-drop"}}, t)
    assert lb.model_fits({"env": "icv_envs/HighwayFormation-v0", "config": {"scenario": "lane-drop",
                                                                             "action": {"type": "X"}}}, t)
    assert lb.model_fits({"env": "icv_envs/highway_formation-v0", "config": {},
                          "scenarios": ["free", "lane-drop"]}, t)
    assert not lb.model_fits({"env": "icv_envs/highway_formation-v0", "config": {"scenario": "on-ramp"}}, t)
    assert not lb.model_fits({"env": "icv_envs/intersection-v0", "config": {"scenario": "lane-drop"}}, t)
    i = lb.TASKS["intersection-1500"]
    assert not lb.model_fits({"env": "icv_envs/intersection-v0", "config": {"throughput": 1500}}, i)


def test_tiny_leaderboard_end_to_end(tmp_path, monkeypatch):
    """Two short tasks, 2 episodes, one saved model: every file is written, the
    expert is collision-free and ahead of random, a rerun with --reuse gives the
    same table."""
    from icv_envs.cli import main

    tiny = {
        "on-ramp": lb.Task("on-ramp", "icv_envs/highway_formation-v0", {"scenario": "on-ramp", "duration": 6}, 2),
        "intersection-1500": lb.Task("intersection-1500", "icv_envs/intersection-v0",
                                     {"throughput": 1500, "duration": 8, "warmup": 10}, 2),
    }
    monkeypatch.setattr(lb, "TASKS", tiny)
    models = tmp_path / "models"
    _tiny_model(models / "ppo_tiny", {"scenario": "on-ramp", "duration": 6})
    out = tmp_path / "board"
    argv = ["leaderboard", "--out", str(out), "--models", str(models), "--reps", "50"]
    assert main(argv) == 0
    with open(out / "leaderboard.csv") as f:
        rows = list(csv.DictReader(f))
    by = {(r["task"], r["policy"]): r for r in rows}
    assert set(by) == {("on-ramp", p) for p in ("expert", "zero", "random", "ppo_tiny")} | {
        ("intersection-1500", p) for p in ("expert", "single-vp", "fcfs", "fcfs-tight", "zero", "random")}
    ex, rnd = by[("on-ramp", "expert")], by[("on-ramp", "random")]
    assert float(ex["collisions_per_100_mean"]) == 0.0
    assert float(ex["return_mean"]) > float(rnd["return_mean"])
    assert float(ex["return_vs_expert"]) == pytest.approx(1.0)
    assert float(by[("intersection-1500", "expert")]["throughput_mean"]) >= 0.0
    assert by[("on-ramp", "ppo_tiny")]["kind"].startswith("learned")
    md = (out / "leaderboard.md").read_text()
    assert "| ppo_tiny |" in md and "### intersection-1500" in md
    assert (out / "leaderboard.png").stat().st_size > 10_000
    assert json.loads((out / "evals" / "on-ramp" / "expert.json").read_text())["seed"] == lb.DEFAULT_SEED
    before = (out / "leaderboard.csv").read_text()
    assert main(argv + ["--reuse"]) == 0
    assert _no_time(before) == _no_time((out / "leaderboard.csv").read_text())


def _no_time(text: str) -> list[dict]:
    rows = list(csv.DictReader(text.splitlines()))
    for r in rows:
        r.pop("eval_seconds")
    return rows


def _tiny_model(d, config):
    """An untrained SB3 PPO model in the baselines' format (model.zip + run.json)."""
    from stable_baselines3 import PPO

    from icv_envs.rl.envs import make_parallel_env
    from icv_envs.rl.models import write_run_json
    from icv_envs.rl.vec_env import ParallelVecEnv

    venv = ParallelVecEnv(lambda: make_parallel_env("highway_formation_v0", config), seed=0)
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=8, seed=0, device="cpu")
    d.mkdir(parents=True)
    model.save(d / "model.zip")
    write_run_json(d, {"algo": "ppo_recipe", "env": "icv_envs/highway_formation-v0", "config": config})
    venv.close()


def test_reaching_the_end_of_the_highway_is_not_a_failure():
    """``left_road`` on the highway is the end of the road (a truncation); at the intersection it is
    driving back out of the approach road (a failure)."""
    from icv_envs.rl.leaderboard import episode_metrics

    row = {"episode_return": 1.0, "collisions": 1, "left_road": 1, "vehicles": 10, "spawned": 10,
           "mean_speed": 20.0, "speed_fluctuation": 0.1, "achieved_throughput": 100.0}
    assert episode_metrics(row, "highway_formation")["collisions_per_100"] == 10.0
    assert episode_metrics(row, "intersection")["collisions_per_100"] == 20.0
