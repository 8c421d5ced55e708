"""ParallelVecEnv: agents joining and leaving, masking, termination vs
truncation, terminal observations, resets, seeding."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from gymnasium import spaces  # noqa: E402
from pettingzoo import ParallelEnv  # noqa: E402

from icv_envs.rl.envs import make_parallel_env  # noqa: E402
from icv_envs.rl.vec_env import ParallelVecEnv  # noqa: E402

torch.set_num_threads(1)


class ToyEnv(ParallelEnv):
    """Scripted joins and leaves (slots in ``possible_agents`` order a, b, c):

    * ``a``: live from reset, *terminates* on step 2;
    * ``b``: spawns during step 1, is *truncated* on step 3 with an all-zero
      final observation (like a vehicle that drove off the end of the road);
    * ``c``: live from reset, truncated on step 4 (time limit): the episode ends.

    Observation of agent k at step t: ``full(shape, 1 + t + 0.1 k + seed/1000)``;
    reward: ``10 k + t``.
    """

    metadata = {"name": "toy_v0"}
    possible_agents = ["a", "b", "c"]

    def __init__(self):
        self.render_mode = None
        self.space = spaces.Box(-100.0, 100.0, (2, 3), dtype=np.float32)
        self.act_space = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        self.seeds, self.actions_log = [], []
        self.agents = []

    def observation_space(self, agent):
        return self.space

    def action_space(self, agent):
        return self.act_space

    def _o(self, agent):
        k = self.possible_agents.index(agent)
        return np.full((2, 3), 1 + self.t + 0.1 * k + self.seed_ / 1000, dtype=np.float32)

    def reset(self, seed=None, options=None):
        self.seeds.append(seed)
        self.seed_ = seed or 0
        self.t = 0
        self.agents = ["a", "c"]
        return {a: self._o(a) for a in self.agents}, {a: {"expert_action": np.zeros(2)} for a in self.agents}

    def step(self, actions):
        assert set(actions) == set(self.agents), (actions, self.agents)
        self.actions_log.append({a: np.array(v) for a, v in actions.items()})
        self.t += 1
        t = self.t
        obs, rew, term, trunc, infos = {}, {}, {}, {}, {}
        for a in self.agents:
            obs[a] = self._o(a)
            rew[a] = 10.0 * self.possible_agents.index(a) + t
            term[a] = trunc[a] = False
            infos[a] = {"expert_action": np.zeros(2)}
        if t == 1:
            obs["b"], rew["b"], term["b"], trunc["b"], infos["b"] = self._o("b"), 0.0, False, False, {}
        if t == 2:
            term["a"] = True
        if t == 3:
            trunc["b"] = True
            obs["b"] = np.zeros((2, 3), dtype=np.float32)
        if t == 4:
            trunc["c"] = True
        self.agents = [a for a in obs if not (term[a] or trunc[a])]
        return obs, rew, term, trunc, infos


def toy_obs(t, k, seed=0):
    return np.full((2, 3), 1 + t + 0.1 * k + seed / 1000, dtype=np.float32)


def test_toy_join_leave_mask_and_flags():
    venv = ParallelVecEnv(ToyEnv, seed=7)
    assert venv.num_envs == 3
    env = venv.envs[0]
    obs = venv.reset()
    assert env.seeds == [7]
    np.testing.assert_allclose(obs[0], toy_obs(0, 0, 7))
    assert not obs[1].any()  # b is not there yet: zero observation
    assert list(venv.active) == [True, False, True]

    # step 1: b spawns; its slot's action is ignored
    acts = np.array([[0.1, 0.1], [0.9, 0.9], [0.3, 0.3]], dtype=np.float32)
    obs, rew, done, info = venv.step(acts)
    assert set(env.actions_log[-1]) == {"a", "c"}
    np.testing.assert_allclose(env.actions_log[-1]["c"], [0.3, 0.3])
    assert list(done) == [False, True, False]  # the placeholder of b ends
    assert [i["active"] for i in info] == [True, False, True]
    assert info[1].get("spawned") and "terminal_observation" not in info[1]
    assert rew[1] == 0 and rew[0] == 1 and rew[2] == 21
    np.testing.assert_allclose(obs[1], toy_obs(1, 1, 7))
    assert list(venv.active) == [True, True, True]
    assert "expert_action" in info[0]

    # step 2: a terminates
    obs, rew, done, info = venv.step(acts)
    assert list(done) == [True, False, False]
    np.testing.assert_allclose(info[0]["terminal_observation"], toy_obs(2, 0, 7))
    assert info[0]["TimeLimit.truncated"] is False
    assert info[0]["episode"]["r"] == pytest.approx(1 + 2) and info[0]["episode"]["l"] == 2
    assert not obs[0].any()
    assert list(venv.active) == [False, True, True]
    assert "episode" not in info[1] and "episode" not in info[2]

    # step 3: b truncated with a zero final observation -> its previous one is used
    obs, rew, done, info = venv.step(acts)
    assert set(env.actions_log[-1]) == {"b", "c"}
    assert list(done) == [True, True, False]
    assert info[0]["active"] is False and rew[0] == 0 and "terminal_observation" not in info[0]
    assert info[1]["TimeLimit.truncated"] is True
    assert info[1]["terminal_observation_substituted"] is True
    np.testing.assert_allclose(info[1]["terminal_observation"], toy_obs(2, 1, 7))
    assert info[1]["episode"]["l"] == 2  # steps 2 and 3 (step 1 was its spawn)
    assert list(venv.active) == [False, False, True]

    # step 4: c truncated by the time limit, the episode is over: reset with the next seed
    obs, rew, done, info = venv.step(acts)
    assert list(done) == [True, True, True]
    assert info[2]["TimeLimit.truncated"] is True
    np.testing.assert_allclose(info[2]["terminal_observation"], toy_obs(4, 2, 7))
    assert info[2]["episode"]["l"] == 4 and info[2]["episode"]["r"] == pytest.approx(21 + 22 + 23 + 24)
    assert all(i.get("episode_reset") for i in info)
    assert env.seeds == [7, 8]
    np.testing.assert_allclose(obs[0], toy_obs(0, 0, 8))
    np.testing.assert_allclose(obs[2], toy_obs(0, 2, 8))
    assert not obs[1].any()
    assert list(venv.active) == [True, False, True]
    venv.close()


def test_toy_copies_seeds_and_methods():
    venv = ParallelVecEnv(ToyEnv, n_copies=2, seed=100)
    assert venv.num_envs == 6
    assert venv.slot_agent(4) == (1, "b") and venv.slot(1, "b") == 4
    venv.reset()
    for _ in range(8):  # two episodes of each copy
        venv.step(np.zeros((6, 2), dtype=np.float32))
    assert venv.envs[0].seeds == [100, 102, 104]
    assert venv.envs[1].seeds == [101, 103, 105]
    # seed() restarts the episode counter at the next reset
    assert venv.seed(5) == [5, 5, 5, 6, 6, 6]
    venv.reset()
    assert venv.envs[0].seeds[-1] == 5 and venv.envs[1].seeds[-1] == 6
    # a reset() without a new seed moves on to fresh episodes
    venv.reset()
    assert venv.envs[0].seeds[-1] == 7 and venv.envs[1].seeds[-1] == 8
    # attribute / method access per slot, calls once per copy
    assert venv.get_attr("render_mode") == [None] * 6
    assert venv.get_attr("t", indices=[0, 3]) == [0, 0]
    venv.set_attr("marker", 1, indices=[4])
    assert not hasattr(venv.envs[0], "marker") and venv.envs[1].marker == 1
    res = venv.env_method("observation_space", "a", indices=[0, 1, 5])
    assert len(res) == 3 and res[0] is venv.envs[0].space and res[2] is venv.envs[1].space
    assert venv.env_is_wrapped(ToyEnv) == [True] * 6
    assert venv.env_is_wrapped(spaces.Box) == [False] * 6
    with pytest.raises(ValueError, match="same env instance"):
        e = ToyEnv()
        ParallelVecEnv(lambda: e, n_copies=2)
    with pytest.raises(ValueError, match="n_copies"):
        ParallelVecEnv(ToyEnv, n_copies=0)


# ---------------------------------------------------------------- the real env
REAL_CFG = {
    "road_length": 260.0,  # the leaders drive off the end of the road after ~4.4 s
    "initial_position": 150.0,
    "duration": 6.0,  # 30 policy steps, then every agent is truncated
    "spawns": [{"time": 1.0, "position": 20.0, "lane": 0}],  # icv_8 joins after 5 steps
}


def _expert_slot_actions(venv):
    acts = np.zeros((venv.num_envs, 2), dtype=np.float32)
    for c, env in enumerate(venv.envs):
        if env.agents:
            for a, act in env.expert_actions().items():
                if a in env.agents:
                    acts[venv.slot(c, a)] = act
    return acts


def test_real_env_join_crash_truncate_and_reset():
    venv = ParallelVecEnv(lambda: make_parallel_env("highway_formation_v0", REAL_CFG), seed=3)
    assert venv.possible_agents == [f"icv_{i}" for i in range(9)]
    obs = venv.reset()
    assert list(venv.active) == [True] * 8 + [False]
    assert not obs[8].any() and (obs[:8, 0, 0] == 1).all()
    seen = {"spawn": None, "crash": {}, "left_road": [], "time_limit": None}
    for t in range(1, 31):
        acts = _expert_slot_actions(venv)
        acts[0] = [0.0, 1.0]  # icv_0 steers off the road and crashes
        active_before = venv.active.copy()
        obs, rew, done, info = venv.step(acts)
        for i in np.flatnonzero(~active_before):
            assert done[i] and rew[i] == 0 and info[i]["active"] is False
        if info[8].get("spawned"):
            seen["spawn"] = t
            assert obs[8][0, 0] == 1 and venv.active[8]
        for i in range(9):
            if active_before[i] and done[i]:
                assert "terminal_observation" in info[i] and "episode" in info[i]
                if info[i].get("crashed"):
                    assert info[i]["TimeLimit.truncated"] is False  # a termination: no bootstrap
                    seen["crash"][i] = t
                elif info[i].get("left_road"):
                    seen["left_road"].append(i)
                    assert info[i]["TimeLimit.truncated"] is True
                    # the env reports the last observation the vehicle had
                    assert not info[i].get("terminal_observation_substituted")
                    assert info[i]["terminal_observation"][0, 0] == 1
                elif t == 30:
                    assert info[i]["TimeLimit.truncated"] is True
                    assert info[i]["terminal_observation"][0, 0] == 1
                    seen["time_limit"] = t
    assert seen["spawn"] == 5
    assert 0 in seen["crash"]  # icv_0 crashed (maybe into a neighbour)
    assert seen["left_road"], "some leaders should have left the road"
    assert seen["time_limit"] == 30
    assert all(i.get("episode_reset") for i in info) and done.all()
    # the new episode: seed 3 + 1, the initial agents back, icv_8 absent again
    assert list(venv.active) == [True] * 8 + [False]
    venv.close()


def test_real_env_deterministic():
    cfg = dict(REAL_CFG, duration=2.0)  # 10 steps per episode: crosses 3 resets

    def run(seed):
        venv = ParallelVecEnv(lambda: make_parallel_env("highway_formation_v0", cfg), n_copies=2, seed=seed)
        rng = np.random.default_rng(0)
        trace = [venv.reset()]
        for _ in range(35):
            obs, rew, done, _ = venv.step(rng.uniform(-0.3, 0.3, (venv.num_envs, 2)).astype(np.float32))
            trace += [obs, rew, done]
        venv.close()
        return trace

    a, b, c = run(11), run(11), run(12)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_sb3_ppo_runs_on_the_adapter():
    from stable_baselines3 import PPO

    venv = ParallelVecEnv(lambda: make_parallel_env("highway_formation_v0", REAL_CFG), seed=0)
    model = PPO("MlpPolicy", venv, n_steps=40, batch_size=90, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=venv.num_envs * 40)
    assert model.num_timesteps == venv.num_envs * 40
    assert len(model.ep_info_buffer) >= 9  # one entry per finished agent-episode
    venv.close()


def test_placeholder_fraction_counts_absent_slot_steps():
    venv = ParallelVecEnv(ToyEnv, seed=0)
    venv.reset()
    assert venv.placeholder_fraction == 0.0
    for _ in range(4):  # inactive slots per step: b; none; a; a, b
        venv.step(np.zeros((3, 2), dtype=np.float32))
    assert venv.slot_steps == 12 and venv.placeholder_steps == 4
    assert venv.placeholder_fraction == pytest.approx(4 / 12)
