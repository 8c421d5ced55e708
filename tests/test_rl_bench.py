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


def test_batched_sps_action_kinds():
    """Stop 43: the external actions are zeros (the default), uniform in
    [-0.3, 0.3] or uniform in [-1, 1] (an untrained
    policy), each counted as a manual run with the same draws counts them;
    the live agents per world and the world-steps are reported; anything
    else is an error naming the allowed kinds."""
    from icv_envs.rl.bench import batched_sps
    from icv_envs.vector import BatchedWorlds

    for kind, bound in (("small", 0.3), ("uniform", 1.0)):
        res = batched_sps(vehicles=5, worlds=2, steps=6, seed=3, actions=kind)
        bw = BatchedWorlds(2, config={"vehicles_count": 5, "initial_position": None}, seed=3)
        bw.reset()
        rng = np.random.default_rng(3)
        n = 0
        for _ in range(6):
            n += int(bw.mask.sum())
            bw.step(rng.uniform(-bound, bound, size=(2, bw.K, 2)).astype(np.float32))
        assert res["agent_steps"] == n > 0 and res["actions"] == kind
        assert res["live_agents_per_world"] == n / 12 and res["world_steps_per_cpu_s"] > 0
    assert batched_sps(vehicles=5, worlds=2, steps=3, seed=3)["actions"] == "zero"
    with pytest.raises(ValueError, match=r"actions = 'chaos'; allowed: \['zero', 'small', 'uniform'\]"):
        batched_sps(vehicles=5, worlds=2, steps=3, actions="chaos")


def test_batched_sps_policy_acts_and_is_timed_apart():
    """Stop 44: a ``policy(obs, mask)`` acts instead of external actions,
    given the batch's observations and masks; its calls' CPU time is left
    out of the figures (reported apart); with another action kind, with the
    expert or not callable it is an error, and so is the expert with another
    action kind (it acts instead: the kind would be ignored)."""
    import time

    from icv_envs.rl.bench import batched_sps

    seen = []

    def policy(obs, mask):
        seen.append((obs.shape, mask.shape, int(mask.sum())))
        t = time.process_time()
        while time.process_time() - t < 0.01:  # (10 ms of CPU a call)
            pass
        return np.zeros(mask.shape + (2,), dtype=np.float32)

    res = batched_sps(vehicles=5, worlds=2, steps=4, seed=3, policy=policy, warmup=1)
    zero = batched_sps(vehicles=5, worlds=2, steps=4, seed=3, warmup=1)
    assert res["actions"] == "policy" and res["agent_steps"] == zero["agent_steps"] > 0
    assert len(seen) == 2 * 5 and seen[0][0][:2] == seen[0][1] == (2, 5) and seen[0][2] == 10
    assert res["policy_cpu_seconds"] >= 0.04
    assert res["agent_steps"] / res["agent_steps_per_cpu_s"] < res["policy_cpu_seconds"]
    with pytest.raises(ValueError, match=r"actions = 'uniform' with a policy, which acts instead"):
        batched_sps(vehicles=5, worlds=2, steps=2, policy=policy, actions="uniform")
    with pytest.raises(ValueError, match=r"actions = 'small' with expert=True, which acts instead"):
        batched_sps(vehicles=5, worlds=2, steps=2, expert=True, actions="small")
    with pytest.raises(ValueError, match="expert=True and a policy"):
        batched_sps(vehicles=5, worlds=2, steps=2, expert=True, policy=policy)
    with pytest.raises(ValueError, match="policy = 3; allowed: a callable"):
        batched_sps(vehicles=5, worlds=2, steps=2, policy=3)


def test_batched_sps_warmup_is_not_counted():
    """``warmup`` batch steps run before the timed ones and are not counted."""
    from icv_envs.rl.bench import batched_sps
    from icv_envs.vector import BatchedWorlds

    res = batched_sps(vehicles=5, worlds=2, steps=3, seed=3, actions="uniform", warmup=4)
    bw = BatchedWorlds(2, config={"vehicles_count": 5, "initial_position": None}, seed=3)
    bw.reset()
    rng = np.random.default_rng(3)
    n = 0
    for i in range(7):
        if i >= 4:
            n += int(bw.mask.sum())
        bw.step(rng.uniform(-1.0, 1.0, size=(2, bw.K, 2)).astype(np.float32))
    assert res["agent_steps"] == n and res["live_agents_per_world"] == n / 6
    with pytest.raises(ValueError, match=r"warmup = -1; allowed: an integer >= 0"):
        batched_sps(vehicles=5, worlds=2, steps=3, warmup=-1)
