"""Smoke test of the training-throughput benchmark (never asserts speeds)."""

from __future__ import annotations

import json

import numpy as np

import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from icv_envs.rl.bench import bench_train, main  # noqa: E402

torch.set_num_threads(1)


def test_bench_train_smoke(capsys):
    res = bench_train(vehicles=20, env_steps=30, ppo_steps=64, reference=False)
    icv = res["icv_envs"]
    assert res["bench"] == "rl-train" and res["vehicles"] == 20
    assert icv["env_sps"] > 0 and icv["ppo_sps"] > 0 and icv["ppo_rollout_sps"] >= icv["ppo_sps"]
    assert icv["ppo_steps"] == 512  # one PPO rollout (n_steps=512) at least
    json.dumps(res)
    assert main(["--env-steps", "10", "--ppo-steps", "1", "--no-reference"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["bench"] == "rl-train"


def test_bench_train_bad_input():
    with pytest.raises(ValueError, match="vehicles"):
        bench_train(vehicles=0)


def test_batched_sps_times_one_run_of_the_same_steps():
    """The figure is the second of two identical runs (the first loads the
    kernels): the agent-steps counted are those of one run, and the runs
    are the same run (same seed)."""
    from icv_envs.rl.bench import batched_sps
    from icv_envs.vector import BatchedWorlds

    for expert in (False, True):
        res = batched_sps(vehicles=5, worlds=2, steps=4, expert=expert, seed=3)
        bw = BatchedWorlds(2, config={"vehicles_count": 5, "initial_position": None}, seed=3, expert=expert)
        bw.reset()
        n = 0
        for _ in range(4):
            n += int(bw.mask.sum())
            bw.step(bw.expert_actions if expert else np.zeros((2, bw.K, 2), dtype=np.float32))
        assert res["agent_steps"] == n > 0
