"""Batched worlds (icv_envs.vector): shapes, masks, per-world seeding and
auto-reset, bit-identity with separate envs, errors, SB3 training through it."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from icv_envs.envs.highway_formation_v0 import parallel_env
from icv_envs.vector import BatchedWorlds, IcvVectorEnv

CFG = {"vehicles_count": 6, "initial_position": None, "duration": 2.0}


def test_gym_vector_env_shapes_and_same_seed_same_obs():
    v = IcvVectorEnv(num_envs=3, config=CFG)
    obs, info = v.reset(seed=5)
    assert obs.shape == (3,) + v.single_observation_space.shape and v.observation_space.contains(obs)
    assert info["expert_action"].shape == (3, 2)
    w = IcvVectorEnv(num_envs=3, config=CFG)
    obs2, _ = w.reset(seed=5)
    assert np.array_equal(obs, obs2)
    o, r, te, tr, info = v.step(info["expert_action"])
    assert o.shape == obs.shape and r.shape == (3,) and te.dtype == bool and tr.dtype == bool


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_gym_vector_env_autoreset(mode):
    v = IcvVectorEnv(num_envs=2, config=CFG, autoreset_mode=mode)
    obs, info = v.reset(seed=0)
    steps = int(CFG["duration"] * 5)
    for t in range(steps):
        obs, r, te, tr, info = v.step(info["expert_action"])
    assert tr.all()  # time limit on the last step
    if mode == AutoresetMode.SAME_STEP:
        assert info["_final_obs"].all() and info["final_obs"][0].shape == obs[0].shape
        assert not np.array_equal(info["final_obs"][0], obs[0])  # obs is the new episode's first
    obs, r, te, tr, info = v.step(info["expert_action"])
    assert not (te | tr).any()
    if mode == AutoresetMode.NEXT_STEP:
        assert (r == 0).all()  # the reset step


def test_gym_vector_env_bad_input():
    with pytest.raises(ValueError, match="num_envs"):
        IcvVectorEnv(num_envs=0)
    with pytest.raises(ValueError, match="not a single-agent"):
        IcvVectorEnv("highway-v0", num_envs=1)
    v = IcvVectorEnv(num_envs=2, config=CFG)
    v.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3, 2\).*\(2, 2\)"):
        v.step(np.zeros((3, 2)))


def test_batched_worlds_match_separate_envs_bit_for_bit():
    bw = BatchedWorlds(2, config=CFG, seed=3, expert=True)
    obs, mask = bw.reset()
    K = bw.K
    assert obs.shape == (2, K) + bw.single_observation_space.shape and mask.all()
    refs = []
    for b in range(2):
        env = parallel_env(**CFG, expert_in_info=False)
        o, _ = env.reset(seed=bw.episode_seed(b, 0))
        refs.append(env)
        assert np.array_equal(np.stack([o[a] for a in env.possible_agents]), obs[b])
    acts = bw.expert_actions.copy()
    for _ in range(4):
        obs, rew, term, trunc, mask, info = bw.step(acts)
        for b, env in enumerate(refs):
            ex = env.expert_actions()
            o, r, _, _, _ = env.step({a: ex[a] for a in env.agents})
            k = [bw.slot_of[a] for a in o]
            assert np.array_equal(np.stack(list(o.values())), obs[b, k])
            assert np.array_equal(np.array(list(r.values())), rew[b, k])
        acts = info["expert_actions"]


def test_batched_worlds_autoreset_and_masks():
    bw = BatchedWorlds(2, config=CFG, seed=0, expert=True)
    bw.reset()
    acts = bw.expert_actions.copy()
    for t in range(int(CFG["duration"] * 5)):
        obs, rew, term, trunc, mask, info = bw.step(acts)
        acts = info["expert_actions"]
    assert info["reset"].all() and trunc.all()
    assert mask.all() and (np.abs(info["final_obs"]).sum() > 0)
    assert bw._episode.tolist() == [2, 2]


def test_batched_worlds_empty_slots_and_bad_actions():
    bw = BatchedWorlds(1, env="highway_ramps", config={"vgr": 0.5, "duration": 20.0, "max_vehicles": 8},
                       expert=True)
    obs, mask = bw.reset()
    assert mask.sum() < bw.K and (obs[~mask] == 0).all()
    acts = np.zeros((1, bw.K, 2))
    acts[~mask] = np.nan  # ignored: empty slots
    bw.step(acts)
    acts = np.zeros((1, bw.K, 2))
    acts[bw.mask] = np.inf
    with pytest.raises(ValueError, match=r"world 0 slot \d+ \(icv_\d+\).*NaN or inf"):
        bw.step(acts)
    with pytest.raises(ValueError, match="allowed"):
        BatchedWorlds(1, env="nope")


def test_sb3_ppo_trains_through_the_vector_env():
    pytest.importorskip("stable_baselines3")
    torch = pytest.importorskip("torch")
    from stable_baselines3 import PPO

    torch.set_num_threads(1)
    venv = IcvVectorEnv(num_envs=2, config=CFG).to_sb3()
    model = PPO("MlpPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=64)
    assert model.num_timesteps >= 64
    venv.close()


def test_batched_intersection_worlds_keep_going_while_empty():
    bw = BatchedWorlds(1, env="intersection", config={"duration": 4.0}, seed=1, expert=True)
    obs, mask = bw.reset()
    acts = bw.expert_actions.copy()
    resets = 0
    for _ in range(25):  # 5 s: one reset at 4 s, none while the zones are merely empty
        obs, rew, term, trunc, mask, info = bw.step(acts)
        acts = info["expert_actions"]
        resets += int(info["reset"][0])
        assert (obs[0][~mask[0]] == 0).all()
    assert resets == 1


@pytest.mark.parametrize("env_name", ["highway_formation", "intersection"])
def test_batched_worlds_without_expert_never_compute_it_and_match_separate_envs(env_name, monkeypatch):
    """``expert=False``: no step computes the expert (``expert_driven_check`` False), and on learned
    (random) actions the worlds are bit-identical to separate envs that do compare every action."""
    import importlib

    cfg = CFG if env_name == "highway_formation" else {"throughput": 1500, "duration": 3.0, "warmup": 20.0}
    mod = importlib.import_module(f"icv_envs.envs.{env_name}_v0")
    bw = BatchedWorlds(1, env=env_name, config=cfg, seed=2)
    obs, mask = bw.reset()
    env = mod.parallel_env(**cfg, expert_in_info=False)
    o, _ = env.reset(seed=bw.episode_seed(0, 0))
    assert env.core.config["expert_driven_check"] and not bw.envs[0].core.config["expert_driven_check"]
    calls = {"n": 0}
    core = bw.envs[0].core
    real = core.expert_actions

    def counted(*a, **k):
        calls["n"] += 1
        return real(*a, **k)

    monkeypatch.setattr(core, "expert_actions", counted)
    rng = np.random.default_rng(0)
    for _ in range(6):
        acts = rng.uniform(-0.3, 0.3, size=(1, bw.K, 2)).astype(np.float32)
        obs, rew, term, trunc, mask, info = bw.step(acts)
        o, r, _, _, _ = env.step({a: acts[0, bw.slot_of[a]] for a in env.agents})
        k = [bw.slot_of[a] for a in o]
        assert np.array_equal(np.stack(list(o.values())), obs[0, k])
        assert np.array_equal(np.array(list(r.values())), rew[0, k])
    assert calls["n"] == 0


def test_expert_driven_check_is_validated():
    with pytest.raises(ValueError, match="expert_driven_check"):
        parallel_env(**CFG, expert_driven_check="no")


def _dict_step_as_rows(env, acts):
    """The PettingZoo dict step of ``env`` (rows of ``acts`` in vehicle order) as StepRows-like arrays."""
    vid = env.core._vehicles().vid
    obs, rew, term, trunc, _ = env.step({f"icv_{v}": acts[i] for i, v in enumerate(vid.tolist())})
    names = list(obs)
    return (np.array([int(a[4:]) for a in names], dtype=np.int64),
            np.stack(list(obs.values())) if names else None, np.array([rew[a] for a in names]),
            np.array([term[a] for a in names], dtype=bool), np.array([trunc[a] for a in names], dtype=bool))


_META = {"action": {"type": "DiscreteMetaAction"}}


@pytest.mark.parametrize("module, config, steps", [
    ("highway_formation_v0", {"vehicles_count": 12, "duration": 6.0}, 40),
    ("highway_ramps_v0", {"duration": 60.0, "max_cycles": 275}, 300),
    ("intersection_v0", {"duration": 56.0, "throughput": 2500.0}, 300),
    # discrete actions through step_rows (from stop 45): one integer per agent
    ("highway_formation_v0", {"vehicles_count": 12, "duration": 6.0, **_META}, 40),
    ("highway_ramps_v0", {"duration": 60.0, "max_cycles": 275, **_META}, 300),
    ("intersection_v0", {"duration": 56.0, "throughput": 2500.0, **_META}, 300),
])
def test_step_rows_equals_the_dict_step(module, config, steps):
    """``ParallelEnv.step_rows`` (the batch's array path) reports the same
    agents, in the dicts' key order, with the same observations, rewards,
    terminations and truncations, and leaves the same ``agents``, as
    ``step``; departures, late spawns and the end of the episode included."""
    import importlib

    mod = importlib.import_module(f"icv_envs.envs.{module}")
    cfg = dict(config)
    cycles = cfg.pop("max_cycles", None)
    a, b = (mod.parallel_env(max_cycles=cycles, **cfg) for _ in range(2))
    a.reset(seed=3)
    b.reset(seed=3)
    rng = np.random.default_rng(0)
    seen_left = seen_done = 0
    for t in range(steps):
        if a.episode_over and not a.agents:
            break
        n = a.core._vehicles().n
        if "action" in config:  # (meta actions: mostly IDLE and FASTER, a random one every third step)
            acts = rng.integers(0, 5, n) if t % 3 == 0 else np.full(n, 1 + 2 * (t % 2), dtype=np.int64)
        else:
            acts = a.core.expert_actions().astype(np.float64) if t % 3 else rng.uniform(-1, 1, (n, 2))
        want = _dict_step_as_rows(a, acts)
        got = b.step_rows(acts)
        np.testing.assert_array_equal(got.vid, want[0])
        if want[1] is not None:
            np.testing.assert_array_equal(got.obs, want[1])
            assert got.obs.dtype == want[1].dtype
        np.testing.assert_array_equal(got.rewards, want[2])
        np.testing.assert_array_equal(got.terminated, want[3])
        np.testing.assert_array_equal(got.truncated, want[4])
        assert b.agents == a.agents
        seen_left += int(len(got.vid) > b.core._vehicles().n)
        seen_done += int(np.any(got.truncated))
    # the case reached an end of episode, and on the open roads departures (seed 3: from step ~260)
    assert seen_done and (seen_left or module == "highway_formation_v0")


def test_step_rows_bad_input():
    env = parallel_env(vehicles_count=4)
    with pytest.raises(RuntimeError, match="reset"):
        env.step_rows(np.zeros((4, 2)))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3, 2\); allowed: \(4, 2\)"):
        env.step_rows(np.zeros((3, 2)))
    bad = np.zeros((4, 2))
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="icv_2 .*NaN or inf"):
        env.step_rows(bad)
    meta = parallel_env(vehicles_count=4, action={"type": "DiscreteMetaAction"})
    meta.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(4, 2\); allowed: \(4,\), one action of 'DiscreteMetaAction'"):
        meta.step_rows(np.zeros((4, 2)))
    with pytest.raises(ValueError, match=r"action of icv_2 = 7 is invalid; allowed: an integer in \[0, 4\]"):
        meta.step_rows(np.array([1, 1, 7, 1]))
    with pytest.raises(ValueError, match=r"action of icv_0 = 0.5 is invalid"):
        meta.step_rows(np.array([0.5, 1, 1, 1]))


def test_slot_lookup_names_only_the_vehicles_without_a_slot():
    """A vehicle id beyond the slot table, or one that is not a possible
    agent, is named in the error; the vehicles that have slots are not."""
    from icv_envs.vector import BatchedWorlds

    bw = BatchedWorlds(1, config={"vehicles_count": 3, "initial_position": None}, seed=0)
    ids = np.array(sorted(int(a[4:]) for a in bw.possible_agents), dtype=np.int64)
    assert np.array_equal(bw._slots_of_vid(ids), np.arange(len(ids)))
    assert bw._slots_of_vid(np.zeros(0, dtype=np.int64)).shape == (0,)
    beyond = int(ids.max()) + 7
    with pytest.raises(ValueError) as e:
        bw._slots_of_vid(np.append(ids, beyond))
    assert f"[{beyond}]" in str(e.value)
    with pytest.raises(ValueError) as e:
        bw._slots_of_vid(np.append(ids, -1))
    assert "[-1]" in str(e.value)


def _through_step_rows(bw: BatchedWorlds) -> None:
    """Send every world of ``bw`` through its own ``step_rows`` (each checks
    and clips its own rows) instead of the batch's one clip: its action
    type's ``controls`` replaced on the instance by the class's own."""
    for env in bw.envs:
        env.core._act_type.controls = type(env.core._act_type).controls.__get__(env.core._act_type)


@pytest.mark.parametrize("env_name, config", [
    ("highway_formation", {"vehicles_count": 8, "initial_position": None, "duration": 4.0}),
    ("highway_ramps", {"vgr": 0.5, "duration": 20.0, "max_vehicles": 8}),
])
def test_batched_worlds_clip_once_for_the_batch(env_name, config):
    """Stop 43: with plain continuous actions, all finite, the batch clips
    every world's actions at once and each world steps from its rows
    (ParallelEnv._step_controls); otherwise (a NaN in an empty slot) each
    world checks and clips its own (step_rows). Both give what the worlds'
    own step_rows give: the same outputs, bit for bit, for actions far
    outside [-1, 1]."""
    rng = np.random.default_rng(5)
    fast = BatchedWorlds(2, env=env_name, config=config, seed=2)
    slow = BatchedWorlds(2, env=env_name, config=config, seed=2)
    fast.reset(), slow.reset()
    _through_step_rows(slow)
    taken = []
    real = type(fast.envs[0])._step_controls
    for t in range(15):
        acts = rng.uniform(-3.0, 3.0, (2, fast.K, 2))
        slow_acts = acts.copy()
        if t % 3 == 0:
            slow_acts[~slow.mask] = np.nan  # (ignored: empty slots)
        n_before = len(taken)
        for env in fast.envs:
            env._step_controls = lambda c, env=env: taken.append(1) or real(env, c)
        a = fast.step(acts)
        for env in fast.envs:
            del env._step_controls
        b = slow.step(slow_acts)
        assert len(taken) - n_before == 2  # (every world of the fast batch took the batch's clip)
        for x, y in zip(a[:5], b[:5]):
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(a[5]["final_obs"], b[5]["final_obs"])


def test_step_controls_checks_the_shape():
    env = parallel_env(vehicles_count=4)
    with pytest.raises(RuntimeError, match="reset"):
        env._step_controls(np.zeros((4, 2)))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"controls have shape \(3, 2\); allowed: \(4, 2\)"):
        env._step_controls(np.zeros((3, 2)))


def test_batched_worlds_follow_a_changed_action_type():
    """A world whose action type becomes FormationResidual (the same Box
    space, so a reset accepts it) steps through its own controls (the
    expert's action plus the bounded residual), not the batch's plain clip."""
    from icv_envs.envs.highway_formation_v0 import parallel_env as pe

    bw = BatchedWorlds(1, config={"vehicles_count": 6, "initial_position": None, "duration": 4.0}, seed=1)
    bw.reset()
    env = bw.envs[0]
    env.core.configure({"action": {"type": "FormationResidual", "bound": 0.25}})
    bw._reset_world(0)
    ref = pe(vehicles_count=6, initial_position=None, duration=4.0, expert_in_info=False,
             expert_driven_check=False, action={"type": "FormationResidual", "bound": 0.25})
    ref.reset(seed=bw.episode_seed(0, 1))
    acts = np.full((1, bw.K, 2), 0.5)
    obs = bw.step(acts)[0]
    o = ref.step_rows(np.full((ref.core._vehicles().n, 2), 0.5))
    np.testing.assert_array_equal(obs[0, bw._slots_of_vid(o.vid)], o.obs)


# ----------------------------------------------------------------- the spaces
# (stop 45: the batch declared Box(-1, 1, (B, K, ...)) observations and
# Box(-1, 1, (B, K, 2)) actions whatever the worlds' config: an unnormalised
# observation fell outside its space, and with DiscreteMetaAction no action
# of the declared space was accepted; IcvVectorEnv's MultiDiscrete sample was
# refused as having the wrong shape)
_OBS = [{"type": "Kinematics"}, {"type": "Kinematics", "normalize": False}, {"type": "OccupancyGrid"}]
_ACT = [{"type": "ContinuousAction"}, {"type": "DiscreteMetaAction"}, {"type": "FormationResidual", "bound": 0.25}]


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(obs=st.sampled_from(_OBS), act=st.sampled_from(_ACT),
       env_name=st.sampled_from(["highway_formation", "highway_ramps", "intersection"]), seed=st.integers(0, 2**16))
def test_batched_worlds_spaces_hold_what_they_return_and_take(obs, act, env_name, seed):
    """For every observation and action type: the batch's observations lie in
    its ``observation_space`` (dtype included), a sample of its
    ``action_space`` steps it, and each world's live slots hold what a
    separate env with the same seed returns for the same actions."""
    cfg = {"observation": obs, "action": act, "duration": 2.0}
    cfg.update({"highway_formation": {"vehicles_count": 4, "initial_position": None},
                "highway_ramps": {"vgr": 0.5, "max_vehicles": 6}, "intersection": {"throughput": 3000.0}}[env_name])
    bw = BatchedWorlds(2, env=env_name, config=cfg, seed=seed)
    mod = __import__(f"icv_envs.envs.{env_name}_v0", fromlist=["parallel_env"])
    refs = [mod.parallel_env(**cfg, expert_in_info=False, expert_driven_check=False) for _ in range(2)]
    o, mask = bw.reset()
    assert bw.observation_space.contains(o) and o.dtype == bw.single_observation_space.dtype
    for b, env in enumerate(refs):
        env.reset(seed=bw.episode_seed(b, 0))
    bw.action_space.seed(seed)
    for _ in range(3):
        live = bw.mask.copy()
        acts = bw.action_space.sample()
        assert bw.action_space.contains(acts)
        o, rew, term, trunc, mask, info = bw.step(acts)
        assert bw.observation_space.contains(o)
        for b, env in enumerate(refs):
            ro, rr, _, _, _ = env.step({a: acts[b, bw.slot_of[a]] for a in env.agents})
            assert sorted(np.flatnonzero(mask[b]).tolist()) == sorted(bw.slot_of[a] for a in env.agents)
            for a in env.agents:
                np.testing.assert_array_equal(o[b, bw.slot_of[a]], ro[a])
            for a in rr:
                if live[b, bw.slot_of[a]]:
                    assert rew[b, bw.slot_of[a]] == rr[a]


def test_batched_worlds_discrete_actions_bad_input():
    """Discrete actions are ``(B, K)`` integers (integer-valued floats too);
    a value out of range or not an integer in a live slot is an error naming
    the world and slot; empty slots are ignored, whatever they hold."""
    bw = BatchedWorlds(1, env="highway_ramps", config={"vgr": 0.5, "duration": 20.0, "max_vehicles": 8,
                                                       "action": {"type": "DiscreteMetaAction"}})
    _, mask = bw.reset()
    assert isinstance(bw.action_space, spaces.MultiDiscrete) and bw.action_space.shape == (1, bw.K)
    assert mask.sum() < bw.K
    acts = np.ones((1, bw.K))
    acts[~mask] = np.nan  # ignored: empty slots
    bw.step(acts)
    live = np.argwhere(bw.mask)[0]
    for bad in (5, -1, 1.5, np.nan):
        acts = np.ones((1, bw.K))
        acts[tuple(live)] = bad
        with pytest.raises(ValueError, match=rf"world 0 slot {live[1]} .*allowed: an integer in \[0, 4\]"):
            bw.step(acts)
    with pytest.raises(ValueError, match=rf"shape \(1, {bw.K}, 2\); allowed: \(1, {bw.K}\)"):
        bw.step(np.ones((1, bw.K, 2)))
    with pytest.raises(ValueError, match="dtype <U1; allowed: integers"):
        bw.step(np.full((1, bw.K), "a"))
    cont = BatchedWorlds(1, config=CFG)
    cont.reset()
    with pytest.raises(ValueError, match="dtype <U1; allowed: real numbers"):
        cont.step(np.full((1, cont.K, 2), "a"))


def test_gym_vector_env_discrete_actions_match_separate_envs():
    """``IcvVectorEnv`` with ``DiscreteMetaAction``: actions ``(B,)`` from its
    ``MultiDiscrete`` space step it, as separate envs with the same seeds."""
    import gymnasium as gym

    cfg = dict(CFG, action={"type": "DiscreteMetaAction"})
    v = IcvVectorEnv(num_envs=2, config=cfg)
    obs, _ = v.reset(seed=4)
    refs = [gym.make("icv_envs/HighwayFormation-v0", config=cfg) for _ in range(2)]
    for b, env in enumerate(refs):
        assert np.array_equal(env.reset(seed=4 + b)[0], obs[b])
    v.action_space.seed(0)
    for _ in range(4):
        acts = v.action_space.sample()
        obs, rew, term, trunc, _ = v.step(acts)
        assert v.observation_space.contains(obs)
        for b, env in enumerate(refs):
            o, r, te, tr, _ = env.step(acts[b])
            assert np.array_equal(o, obs[b]) and r == rew[b]
            if te or tr:
                break
    with pytest.raises(ValueError, match=r"shape \(2, 2\); allowed: \(2,\)"):
        v.step(np.zeros((2, 2), dtype=np.int64))


@pytest.mark.parametrize("make, match", [
    (lambda: BatchedWorlds(1, seed=-1), r"seed = -1; allowed: an integer >= 0"),
    (lambda: BatchedWorlds(1, seed=1.5), r"seed = 1.5; allowed"),  # (was truncated to 1)
    (lambda: BatchedWorlds(1, seed=True), r"seed = True; allowed"),
    (lambda: BatchedWorlds(1, copy="no"), r"copy = 'no'; allowed: True or False"),  # (was bool('no') = True)
    (lambda: BatchedWorlds(1, expert="yes"), r"expert = 'yes'; allowed: True or False"),
    (lambda: BatchedWorlds(1, config=[("duration", 1.0)]), r"config = .*allowed: None or a dict"),
    (lambda: IcvVectorEnv(num_envs=1, copy=0), r"copy = 0; allowed: True or False"),
    (lambda: IcvVectorEnv(num_envs=1, config=[1]), r"config = \[1\]; allowed: None or a dict"),
    (lambda: IcvVectorEnv(num_envs=1, autoreset_mode="bogus"), r"autoreset_mode = 'bogus'; allowed: .*NEXT_STEP"),
    (lambda: IcvVectorEnv(num_envs=2, config=CFG).reset(seed=-3), r"seed = -3; allowed: an integer >= 0"),
    (lambda: IcvVectorEnv(num_envs=2, config=CFG).reset(seed=[1, -1]), r"seed\[1\] = -1; allowed"),
    (lambda: IcvVectorEnv(num_envs=2, config=CFG).reset(seed=1.5), r"seed = 1.5; allowed: None, an integer"),
    (lambda: IcvVectorEnv(num_envs=2, config=CFG).reset(options=[1]), r"reset options = \[1\]; allowed"),
])
def test_vector_bad_arguments_are_named(make, match):
    """Every argument of the batch constructors and the vector env's reset is
    checked (stop 45: a float seed was truncated, a string flag taken as
    True, other bad values failed deep inside with numpy's or Python's
    message)."""
    with pytest.raises(ValueError, match=match):
        make()
    IcvVectorEnv(num_envs=2, config=CFG).reset(seed=[1, None])  # (one seed per world, None: unseeded)


def _same_tree(a, b, path=""):
    if isinstance(a, dict):
        assert set(a) == set(b), (path, sorted(set(a) ^ set(b)))
        for k in a:
            _same_tree(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        for x, y in zip(a, b):
            _same_tree(x, y, path)
    else:
        assert np.array_equal(np.asarray(a), np.asarray(b)), path


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_gym_vector_env_matches_sync_vector_env_infos_included(mode):
    """Observations, rewards, terminations, truncations and the infos (every
    key, with Gymnasium's ``_key`` masks, ``final_obs`` / ``final_info``) equal
    ``SyncVectorEnv``'s over the same ids and seeds, across episode ends (stop
    45: the infos held ``expert_action`` only)."""
    import gymnasium as gym
    from gymnasium.vector import SyncVectorEnv

    cfg = dict(duration=2.0, vehicles_count=6)
    v = IcvVectorEnv("icv_envs/HighwayFormation-v0", 2, config=cfg, autoreset_mode=mode)
    s = SyncVectorEnv([lambda: gym.make("icv_envs/HighwayFormation-v0", config=cfg)] * 2, autoreset_mode=mode)
    o1, i1 = v.reset(seed=5)
    o2, i2 = s.reset(seed=5)
    assert np.array_equal(o1, o2)
    _same_tree(i1, i2)
    assert "speed" in i1 and "_speed" in i1
    rng = np.random.default_rng(0)
    for _ in range(25):  # (two episode ends)
        a = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        r1, r2 = v.step(a), s.step(a)
        for x, y in zip(r1[:4], r2[:4]):
            assert np.array_equal(x, y)
        _same_tree(r1[4], r2[4])


def test_sb3_adapter_passes_each_worlds_info():
    """``to_sb3()``: each world's info is its env's own info of the step (the
    final step's for a world that ended, with SB3's ``terminal_observation``
    and ``TimeLimit.truncated``), as SB3's DummyVecEnv gives (stop 45: only
    SB3's two keys)."""
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    cfg = dict(duration=2.0, vehicles_count=6)
    ours = IcvVectorEnv("icv_envs/HighwayFormation-v0", 2, config=cfg).to_sb3()
    ref = DummyVecEnv([lambda: gym.make("icv_envs/HighwayFormation-v0", config=cfg)] * 2)
    ours.seed(3)
    ref.seed(3)
    assert np.array_equal(ours.reset(), ref.reset())
    rng = np.random.default_rng(1)
    ended = 0
    for _ in range(12):
        a = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        o1, r1, d1, inf1 = ours.step(a)
        o2, r2, d2, inf2 = ref.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        for x, y in zip(inf1, inf2):
            _same_tree(x, y)
        ended += int(d1.sum())
    assert ended >= 2  # (each world's episode ended: the terminal infos were compared)


def test_owned_rows_report_departures_as_step_rows_do():
    """Stop 51: the batch's step keeps its rows for the next step's
    departures without copies (``_ma_advance(owned=True)``). Against worlds
    that step through ``step_rows`` (copies), on HighwayRamps with the
    expert until an agent exits: the same outputs, bit for bit, the exit's
    last observation included."""
    cfg = {"vgr": 0.5, "duration": 120.0, "max_vehicles": 12}
    fast = BatchedWorlds(2, env="highway_ramps", config=cfg, seed=2, expert=True)
    slow = BatchedWorlds(2, env="highway_ramps", config=cfg, seed=2, expert=True)
    fast.reset(), slow.reset()
    _through_step_rows(slow)  # (step_rows copies the rows it keeps)
    exits = 0
    for t in range(530):
        a = fast.step(fast.expert_actions)
        b = slow.step(slow.expert_actions)
        for x, y in zip(a[:5], b[:5]):
            np.testing.assert_array_equal(x, y)
        exits += int(a[2].sum())
    assert exits >= 1  # (agents exited: their last observations came from the kept rows)
    assert sum(env.core.metrics()["exited"] for env in fast.envs) >= 1


def test_a_replaced_drivers_hook_hears_of_a_learned_step():
    """With ``expert_driven_check`` off the highway env tells its world that
    nobody is expert-driven without masks (``_policy_drivers``, stop 51)
    only while ``_drivers`` is its own: one replaced on the instance still
    gets the zero masks, as before."""
    import types

    from icv_envs.envs.highway_formation import HighwayFormationEnv

    env = HighwayFormationEnv(config={"vehicles_count": 3, "expert_driven_check": False})
    obs, _ = env.ma_reset(seed=0)
    heard = []
    own = HighwayFormationEnv._drivers
    env._drivers = types.MethodType(lambda self, v, e, p: (heard.append((len(v), bool(e.any()), bool(p.any()))),
                                                           own(self, v, e, p)), env)
    env.ma_step({a: np.zeros(2, np.float32) for a in obs})
    assert heard == [(3, False, False)]
    del env._drivers
    env.ma_step({a: np.zeros(2, np.float32) for a in obs})
    assert len(heard) == 1 and env.world._expert_vids == set() and env.world._plan_vids == set()
