"""``info_keys``: the per-step info keys an agent's info carries (issue 10,
item 1: the PettingZoo dict layer; TraCI's subscriptions are the model: a
user pays for the per-agent values it asks for). The selection changes the
infos only: observations, rewards, terminations, truncations and the
trajectory are the same bit for bit, and every selected key holds the value
the full info holds."""

from __future__ import annotations

import functools
import hashlib
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pinned_numpy import at_pinned_level

from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0
from icv_envs.envs.highway_config import INFO_KEYS as HIGHWAY_KEYS
from icv_envs.envs.intersection_config import INFO_KEYS as INTERSECTION_KEYS

# (module, config, steps): short runs; on the short road and at the
# intersection after 120 s of warm-up agents leave (the road's end; the
# departure legs), on the ramps' ring vehicles arrive late
CASES = {
    "highway_formation": (highway_formation_v0, {"vehicles_count": 12, "road_length": 400.0, "duration": 30.0}, 60),
    "highway_ramps": (highway_ramps_v0, {"duration": 40.0}, 40),
    "intersection": (intersection_v0, {"throughput": 2200, "duration": 130.0, "warmup": 120.0}, 40),
}
KEYS = {"highway_formation": HIGHWAY_KEYS, "highway_ramps": HIGHWAY_KEYS, "intersection": INTERSECTION_KEYS}


def _run(name: str, **cfg) -> list:
    """Every step's ``(obs, rewards, terms, truncs, infos)`` of the expert
    driving every agent (a third of the agents a fixed action), and the
    reset's ``(obs, infos)`` first."""
    mod, base, steps = CASES[name]
    env = mod.parallel_env(**base, **cfg)
    out = [env.reset(seed=3)]
    for t in range(steps):
        ex = env.expert_actions()
        acts = {a: (np.array([0.3, -0.1], dtype=np.float32) if i % 3 == t % 3 else ex[a])
                for i, a in enumerate(env.agents)}
        out.append(env.step(acts))
    return out


@functools.lru_cache(maxsize=None)
def _full(name: str) -> list:
    return _run(name)


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and np.array_equal(a, b)
    return type(a) is type(b) and (a == b or (a != a and b != b))


def _info_hash(run: list) -> str:
    """SHA-256 over every info of ``run`` (agent names, keys and values in
    their order; floats by their bits)."""
    h = hashlib.sha256()

    def feed(v):
        if isinstance(v, dict):
            for k, x in v.items():
                h.update(repr(k).encode())
                feed(x)
        elif isinstance(v, np.ndarray):
            h.update(str(v.dtype).encode() + v.tobytes())
        elif isinstance(v, float):
            h.update(b"f" + struct.pack("<d", v))
        else:
            h.update(repr(v).encode())

    for out in run:
        feed(out[-1])
    return h.hexdigest()[:16]


# the full infos of the three runs (every key), from the tree before
# ``info_keys`` existed (9072ecb), NumPy's dispatch capped at AVX2 as for the
# trajectory fingerprints: the default infos did not change
FULL_INFO_HASHES = {"highway_formation": "7fb787fa75f1009a", "highway_ramps": "8b6d0074d8659920",
                    "intersection": "132742b8b8c4b8e5"}


@at_pinned_level
def test_the_default_infos_are_those_before_info_keys():
    assert {name: _info_hash(_full(name)) for name in CASES} == FULL_INFO_HASHES


def _expected(full_info: dict, keys, expert: bool) -> dict:
    """The full info restricted to ``keys`` (and the expert's label with
    ``expert``), in the full info's order; an agent's last info (it left the
    road: ``exited``) keeps its other keys."""
    if "exited" in full_info:
        return {k: v for k, v in full_info.items() if k != "expert_action" or expert}
    return {k: v for k, v in full_info.items() if k in keys or (expert and k == "expert_action")}


@pytest.mark.parametrize("name", list(CASES))
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_selected_keys_hold_the_full_values_and_the_run_is_unchanged(name, data):
    keys = data.draw(st.lists(st.sampled_from(KEYS[name]), unique=True), label="info_keys")
    expert = data.draw(st.booleans(), label="expert_in_info")
    full = _full(name)
    sel = _run(name, info_keys=keys, expert_in_info=expert)
    assert len(sel) == len(full)
    departed = 0
    for t, (f, s) in enumerate(zip(full, sel)):
        for part in range(len(f) - 1):  # obs (and rewards, terminations, truncations) bit for bit
            assert _same(f[part], s[part]), (t, part)
        finf, sinf = f[-1], s[-1]
        assert list(finf) == list(sinf), t
        for a in finf:
            if not expert:
                assert "expert_action" not in sinf[a]
            assert _same(_expected(finf[a], keys, expert), sinf[a]), (t, a)
            departed += "exited" in finf[a]
    assert departed or name == "highway_ramps"  # the runs cover the infos of agents leaving


@pytest.mark.parametrize("name", list(CASES))
def test_no_key_gives_empty_dicts(name):
    mod, base, _ = CASES[name]
    env = mod.parallel_env(**base, info_keys=[], expert_in_info=False)
    _, infos = env.reset(seed=0)
    assert infos and all(i == {} for i in infos.values())
    ex = env.expert_actions()
    *_, infos = env.step({a: ex[a] for a in env.agents})
    assert all(i == {} or "exited" in i for i in infos.values())
    assert len({id(i) for i in infos.values()}) == len(infos)  # one dict per agent, not one shared


def test_the_gym_env_applies_the_selection_to_the_ego():
    import gymnasium as gym

    import icv_envs  # noqa: F401

    env = gym.make("icv_envs/HighwayFormation-v0", config={"info_keys": ["lane", "rewards"], "expert_in_info": False})
    _, info = env.reset(seed=0)
    assert list(info) == ["lane"]  # a reset reports no reward
    *_, info = env.step(np.zeros(2, dtype=np.float32))
    assert list(info) == ["lane", "rewards", "ego_present"]


@pytest.mark.parametrize("bad, match", [
    ("speed", r"info_keys'\] = 'speed' is invalid; allowed: None \(all\) or a list of names"),
    (["expert_action"], "switched by config\\['expert_in_info'\\]"),
    (["spd"], r"unknown names \['spd'\]; allowed: \['speed'"),
    (["speed", "speed"], "names a key twice"),
    ([1], "is invalid; allowed"),
    ({"speed": True}, "is invalid; allowed"),
])
@pytest.mark.parametrize("mod", [highway_formation_v0, highway_ramps_v0, intersection_v0])
def test_bad_info_keys_are_named(mod, bad, match):
    with pytest.raises(ValueError, match=match):
        mod.parallel_env(info_keys=bad)


def test_an_intersection_key_is_not_a_highway_key():
    with pytest.raises(ValueError, match=r"unknown names \['movement'\]"):
        highway_formation_v0.parallel_env(info_keys=["movement"])
    intersection_v0.parallel_env(info_keys=["movement", "tree_layer"])


@pytest.mark.parametrize("cfg, match", [
    ({"info_keys": ["speed"]}, r"the dataset records \['speed', 'crashed', 'rewards'\]"),
    ({"expert_in_info": False}, "records the expert's actions"),
])
def test_the_expert_dataset_refuses_infos_it_cannot_record(tmp_path, cfg, match):
    pytest.importorskip("minari")
    from icv_envs.rl.dataset import record_expert_dataset

    with pytest.raises(ValueError, match=match):
        record_expert_dataset("highway_formation_v0", 1, tmp_path, config=cfg)


@pytest.mark.parametrize("keys", [None, ["crashed"], ["speed", "crashed", "rewards"]])
def test_an_agent_that_crashes_reports_it(keys):
    """Agents steering off and into each other: the step they crash in, their
    info says ``crashed`` (with the key selected), as their termination does."""
    env = highway_formation_v0.parallel_env(vehicles_count=12, info_keys=keys)
    env.reset(seed=0)
    crashed = 0
    for _ in range(30):
        acts = {a: np.array([1.0, 0.6 if i % 2 else -0.6], dtype=np.float32) for i, a in enumerate(env.agents)}
        _, _, term, _, infos = env.step(acts)
        for a, info in infos.items():
            assert info["crashed"] == (term[a] and "exited" not in info)
            crashed += info["crashed"]
    assert crashed == 12


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("max_cycles", [None, 7])
def test_agents_are_the_observed_agents_still_live(name, max_cycles):
    """``env.agents`` after a step (made from the core's rows) is exactly
    PettingZoo's definition: the agents of the step's dicts neither
    terminated nor truncated, in their order; empty once ``max_cycles``
    steps are taken."""
    mod, base, steps = CASES[name]
    # the episode runs out (every agent truncated at time-up: none left live though their vehicles are on the road)
    cfg = dict(base, duration={"highway_formation": 8.0, "highway_ramps": 6.0, "intersection": 8.0}[name])
    env = mod.parallel_env(**cfg, max_cycles=max_cycles)
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    for t in range(200):
        if env.episode_over:
            break
        ex = env.expert_actions()
        acts = {a: (rng.uniform(-1, 1, 2).astype(np.float32) if rng.random() < 0.3 else ex[a]) for a in env.agents}
        obs, _, term, trunc, _ = env.step(acts)
        assert env.agents == [a for a in obs if not (term[a] or trunc[a])], t
        assert env.num_agents == len(env.agents)
    assert env.episode_over and env.agents == []
