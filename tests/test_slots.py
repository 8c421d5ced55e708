"""The slot layout (icv_envs.rl.slots): K from the config, slot reuse,
masking, overflow to the expert, the same traffic as the raw env, and the
MARL libraries on every env: SuperSuit's vector env + SB3 PPO, RLlib's stock
ParallelPettingZooEnv (both batch modes), TorchRL's PettingZooWrapper with
masks. Library tests skip when the library is not installed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from icv_envs import highway_formation_v0, intersection_v0
from icv_envs.rl.slots import SlotParallelEnv, slot_count, slot_parallel_env

ENVS = [
    ("intersection_v0", {"duration": 2.0}),
    ("highway_ramps_v0", {"duration": 2.0}),
    ("highway_formation_v0", {"scenario": "on-ramp", "duration": 2.0}),
]


def test_slot_count_from_the_config():
    p = highway_formation_v0.parallel_env(scenario="on-ramp", missing_action="expert")
    assert slot_count(p) == p.core.config["vehicles_count"] + len(p.core.config["spawns"])
    q = intersection_v0.parallel_env(missing_action="expert")  # duration 120 s > the trip time
    c, lay = q.core.config, q.core.layout
    W = (lay.R3 - lay.box_half + float(np.mean(lay.L[lay.L > 0])) + c["departure_length"]) / c["desired_speed"]
    m = 1500.0 / 3600.0 * W
    assert slot_count(q) == math.ceil(m + math.sqrt(6 * m)) < len(q.possible_agents)
    # an episode shorter than the trip time: fewer vehicles at once
    short = intersection_v0.parallel_env(missing_action="expert", duration=10.0)
    assert slot_count(short) == math.ceil(1500 / 3600 * 10 + math.sqrt(6 * 1500 / 3600 * 10))
    with pytest.raises(ValueError, match="missing_action='expert'"):
        SlotParallelEnv(intersection_v0.parallel_env())
    with pytest.raises(ValueError, match="slots"):
        slot_parallel_env("intersection_v0", slots=0)


def test_slots_reuse_mask_overflow_and_same_traffic():
    cfg = {"duration": 25.0, "warmup": 75.0, "throughput": 1500.0}  # vehicles leave during the episode
    env = slot_parallel_env("intersection_v0", cfg, slots=6)
    obs, info = env.reset(seed=0)
    raw = intersection_v0.parallel_env(missing_action="expert", **cfg)
    raw.reset(seed=0)
    hosted = {s: set() for s in env.possible_agents}
    while env.agents:
        assert env.agents == env.possible_agents
        vehicles = [v for v in env.slot_vehicles() if v is not None]
        assert len(vehicles) == len(set(vehicles))  # a vehicle holds at most one slot
        for s in env.agents:
            v = info[s]["vehicle"]
            if info[s]["active"]:
                hosted[s].add(v)
                assert obs[s][0, 0] == 1
            elif not info[s]["vehicle_done"]:
                assert v == -1 and not obs[s].any()
        acts = {s: info[s]["expert_action"] for s in env.agents}
        obs, rew, term, trunc, info = env.step(acts)
        raw.step({})
        for s in env.possible_agents:
            if not info[s]["acted"]:
                assert rew[s] == 0.0
            assert not term[s]
    assert all(trunc.values())
    assert max(len(h) for h in hosted.values()) >= 2  # slots are reused
    assert env.overflow_vehicle_steps > 0  # 6 slots are too few at 1500 veh/h: the expert drives the rest
    assert 0.0 <= env.placeholder_fraction < 1.0
    # the slot layout drives with the expert's actions: the same traffic as the raw env
    m1, m2 = env.core.metrics(), raw.core.metrics()
    for k in ("spawned", "cleared", "collisions", "mean_speed"):
        assert m1[k] == m2[k], k


def test_parallel_api_and_state():
    env = slot_parallel_env("intersection_v0", {"duration": 6.0}, slots=4)
    parallel_api_test(env, num_cycles=40)
    env.reset(seed=0)
    s = env.state()
    assert s.shape == env.state_space.shape and env.state_space.contains(s)
    d = slot_parallel_env("intersection_v0", {"duration": 6.0, "action": {"type": "DiscreteMetaAction"}}, slots=12)
    _, info = d.reset(seed=0)
    masks = {tuple(info[s]["action_mask"]) for s in d.agents if not info[s]["active"]}
    assert masks == {(0, 1, 0, 0, 0)}  # an empty slot may only IDLE
    assert all(tuple(info[s]["action_mask"]) == (1,) * 5 for s in d.agents if info[s]["active"])


@pytest.mark.parametrize("action", ["ContinuousAction", "DiscreteMetaAction"])
@pytest.mark.parametrize("name, cfg", ENVS)
def test_supersuit_sb3_ppo(name, cfg, action):
    ss = pytest.importorskip("supersuit")
    pytest.importorskip("stable_baselines3")
    import torch
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    env = slot_parallel_env(name, dict(cfg, action={"type": action}))
    venv = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(env), 1, num_cpus=0, base_class="stable_baselines3")
    assert venv.num_envs == env.K
    # no seed= : SuperSuit's ConcatVecEnv has no seed() for SB3 to call
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=4 * env.K, n_epochs=1, device="cpu")
    model.learn(total_timesteps=16 * venv.num_envs)  # 16 steps > one 10-step episode: a reset inside
    assert model.num_timesteps >= 16 * venv.num_envs
    venv.close()


@pytest.mark.parametrize("batch_mode", ["truncate_episodes", "complete_episodes"])
@pytest.mark.parametrize("name, cfg", ENVS)
def test_rllib_stock_wrapper_ppo(name, cfg, batch_mode):
    pytest.importorskip("ray.rllib")
    import ray
    import torch
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.connectors.env_to_module import FlattenObservations
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    from ray.tune.registry import register_env

    torch.set_num_threads(1)
    register_env("icv_slots_test", lambda c: ParallelPettingZooEnv(slot_parallel_env(c["env"], c["config"])))
    if not ray.is_initialized():
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    action = "DiscreteMetaAction" if name == "intersection_v0" else "ContinuousAction"
    config = (
        PPOConfig()
        .environment("icv_slots_test", env_config={"env": name, "config": dict(cfg, action={"type": action})})
        .framework("torch")
        .env_runners(num_env_runners=0, num_envs_per_env_runner=1, batch_mode=batch_mode, rollout_fragment_length=10,
                     env_to_module_connector=lambda env, spaces=None, device=None: FlattenObservations(multi_agent=True))
        .learners(num_learners=0)
        .training(train_batch_size_per_learner=40, minibatch_size=32, num_epochs=1)
        .multi_agent(policies={"shared"}, policy_mapping_fn=lambda aid, *a, **k: "shared")
        .debugging(seed=0)
    )
    algo = config.build_algo()
    try:
        r = algo.train()
        assert r["env_runners"]["num_env_steps_sampled_lifetime"] >= 40
        assert r["env_runners"]["num_episodes_lifetime"] >= 2  # 10-step episodes ended and restarted
    finally:
        algo.stop()


@pytest.mark.parametrize("action", ["ContinuousAction", "DiscreteMetaAction"])
@pytest.mark.parametrize("name, cfg", ENVS)
def test_torchrl_pettingzoo_wrapper_with_masks(name, cfg, action):
    pytest.importorskip("torchrl")
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    base = slot_parallel_env(name, dict(cfg, action={"type": action}))
    env = PettingZooWrapper(env=base, use_mask=True, categorical_actions=True, seed=0)
    td = env.rollout(15, break_when_any_done=False)  # past the 10-step episode: a reset inside
    assert td.batch_size[0] == 15
    g = list(env.group_map)[0]
    assert td[g, "observation"].shape[1] == base.K
    assert td[g, "mask"].all()  # every slot is an agent all episode
    active = td["next", g, "info", "active"]
    assert active.shape[:2] == (15, base.K)
    if action == "DiscreteMetaAction":
        am = td[g, "action_mask"]
        assert am.shape[-1] == 5
        # empty slots only IDLE; live ones everything
        inactive = ~td[g, "info", "active"].bool()
        if inactive.any():
            assert (am[inactive].long().sum(-1) == 1).all() and am[inactive][:, 1].all()
    assert td["next", "done"].any()
