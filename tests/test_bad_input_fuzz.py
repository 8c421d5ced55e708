"""Property-based tests over the whole config and action surface of every
env: any input gives either a clear error (``ValueError``/``TypeError``
naming the offending key or agent) or a valid run (reset and a few steps
with finite observations and rewards); nothing else (no ``KeyError``,
``AttributeError``, ``OverflowError``, NaN observations, hangs...)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0

MODULES = {"highway_formation": highway_formation_v0, "highway_ramps": highway_ramps_v0,
           "intersection": intersection_v0}
# long episodes of the open-road envs are fine but slow to generate: the
# fuzz scales the numbers it draws around the defaults instead
# CI draws a fixed sample (derandomize); ICV_FUZZ_RANDOM=1 draws a fresh one each run and
# ICV_FUZZ_EXAMPLES sets its size (the closing notes report such runs)
_ENV = __import__("os").environ
SETTINGS = settings(max_examples=int(_ENV.get("ICV_FUZZ_EXAMPLES", "40")), deadline=None,
                    derandomize=_ENV.get("ICV_FUZZ_RANDOM", "0") != "1",
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

ODD = st.one_of(
    st.none(), st.booleans(), st.just(float("nan")), st.just(float("inf")), st.just(-float("inf")),
    st.just(10**30), st.just(-1), st.just(0), st.just(1e9), st.just("abc"), st.just([]), st.just({}),
    st.just(1 + 2j), st.just([1.0, 2.0, 3.0]), st.just({"x": 1}),
)


def _near(v):
    """Values around a default ``v``: itself, scaled, shifted, or odd."""
    if isinstance(v, bool):
        return st.one_of(st.booleans(), ODD)
    if isinstance(v, (int, float)):
        scaled = st.sampled_from([0.0, 0.1, 0.5, 0.9, 1.0, 1.1, 2.0, -1.0]).map(
            lambda s, v=v: type(v)(v * s) if isinstance(v, float) else int(v * s))
        return st.one_of(st.just(v), scaled, st.integers(-3, 3), ODD)
    if isinstance(v, dict):
        if not v:
            return st.one_of(st.just(v), ODD)
        keys = sorted(v)
        return st.one_of(
            st.just(v),
            st.fixed_dictionaries({}, optional={k: _near(v[k]) for k in keys}),
            st.fixed_dictionaries({"bogus_key": st.integers()}),
            ODD,
        )
    if isinstance(v, (list, tuple)) and v and all(isinstance(x, (int, float)) for x in v):
        return st.one_of(st.just(list(v)), st.lists(st.one_of(*[_near(x) for x in v]), min_size=0,
                                                    max_size=len(v) + 1), ODD)
    return st.one_of(st.just(v), ODD)


def _extra(name):
    """Values for keys whose default is None or empty (sections that may be set)."""
    x = {
        "lane_drop": st.fixed_dictionaries({"position": _near(700.0), "lanes": _near(3)}),
        "obstacle": st.fixed_dictionaries({"lane": _near(1), "position": _near(900.0)},
                                          optional={"length": _near(4.0)}),
        "on_ramp": st.fixed_dictionaries({"position": _near(650.0), "length": _near(100.0)},
                                         optional={"approach": _near(350.0)}),
        "off_ramp": st.fixed_dictionaries({"position": _near(900.0), "length": _near(50.0)},
                                          optional={"ramp_length": _near(150.0)}),
        "spawns": st.lists(st.fixed_dictionaries({"time": _near(1.0), "position": _near(320.0),
                                                  "lane": st.one_of(_near(1), st.just("ramp"))},
                                                 optional={"speed": _near(15.0), "exit": _near(0)}), max_size=3),
        "exits": st.dictionaries(st.one_of(st.integers(-2, 10), st.text(max_size=2)), _near(0), max_size=2),
        "initial_position": _near(150.0),
        "max_vehicles": st.one_of(st.integers(1, 50), _near(20)),
        "exit_choices": st.one_of(st.lists(st.integers(-1, 6), max_size=3), ODD),
        "scenario": st.one_of(st.sampled_from(["free", "lane-drop", "lane-change", "off-ramp", "on-ramp", "x"]), ODD),
        "lane_use": st.one_of(st.sampled_from(["paper", "exclusive", "x"]), ODD),
    }
    return x.get(name)


def _config_strategy(module, shrink: dict):
    core_cls = module.parallel_env.__wrapped__ if hasattr(module.parallel_env, "__wrapped__") else None
    env = module.parallel_env(**shrink)
    defaults = env.core.default_config()
    keys = sorted(defaults)

    @st.composite
    def configs(draw):
        chosen = draw(st.lists(st.sampled_from(keys), min_size=1, max_size=3, unique=True))
        cfg = {}
        for k in chosen:
            strat = _extra(k) if defaults[k] in (None, [], {}) or k in ("scenario", "lane_use") else None
            cfg[k] = draw(st.one_of(strat, _near(defaults[k])) if strat is not None else _near(defaults[k]))
        return cfg

    del core_cls
    return configs()


#: keeps generated runs short (each example resets and steps the env)
SHRINK = {
    "highway_formation": {},
    "highway_ramps": {"duration": 20.0},
    "intersection": {"duration": 20.0, "throughput": 1500.0},
}


def _named(exc: Exception, names) -> bool:
    msg = str(exc)
    return any(str(n) in msg for n in names)


RENDER_KEYS = {"screen_width", "screen_height", "scaling", "centering_position", "offscreen_rendering",
               "real_time_rendering", "render_agent", "show_formation", "show_zones", "show_groups"}


def _run(module, config):
    render = bool(RENDER_KEYS & set(config))
    env = module.parallel_env(render_mode="rgb_array" if render else None, **config)
    obs, infos = env.reset(seed=0)
    if render:
        frame = env.render()
        assert frame.ndim == 3 and frame.shape[2] == 3
        env.close()
    for _ in range(3):
        if not env.agents:
            break
        obs, rew, term, trunc, infos = env.step({a: np.zeros(2) for a in env.agents})
        for a, o in obs.items():
            assert np.isfinite(o).all(), (a, o)
            assert math.isfinite(rew[a])
    return env


@pytest.mark.parametrize("name", sorted(MODULES))
def test_config_surface(name, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    monkeypatch.setenv("SDL_AUDIODRIVER", "dummy")
    module = MODULES[name]
    shrink = SHRINK[name]

    @SETTINGS
    @given(_config_strategy(module, shrink))
    def check(cfg):
        config = {**shrink, **cfg}
        try:
            _run(module, config)
        except (ValueError, TypeError) as exc:
            assert _named(exc, cfg), f"error for {cfg!r} does not name the key: {exc}"

    check()


ACTIONS = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=3),
    st.tuples(st.integers(min_value=-(10**40), max_value=10**40), st.integers(-5, 5)),
    st.complex_numbers(), st.text(max_size=3), st.dictionaries(st.text(max_size=2), st.floats(), max_size=2),
    st.none(), st.booleans(), st.just([True, False]), st.just([[0.0, 0.0]]), st.just([1 + 1j, 0.0]),
    st.just(np.zeros(2, dtype=np.float32)), st.just(np.zeros(2, dtype=np.int64)),
    st.just(np.array([b"a", b"b"])), st.just(np.array([None, None])), st.just(np.zeros(2, dtype=np.complex128)),
    st.just([10**400, 0]), st.just(["1", "2"]),
)


@pytest.mark.parametrize("action_type", ["ContinuousAction", "DiscreteMetaAction", "FormationResidual"])
@pytest.mark.parametrize("name", sorted(MODULES))
def test_action_surface(name, action_type):
    module = MODULES[name]
    env = module.parallel_env(**SHRINK[name], action={"type": action_type})
    good = 1 if action_type == "DiscreteMetaAction" else np.zeros(2)

    @SETTINGS
    @given(st.one_of(ACTIONS, st.integers(-10, 10), st.floats(allow_nan=True, allow_infinity=True)))
    def check(action):
        env.reset(seed=0)
        target = env.agents[0]
        acts = {a: good for a in env.agents}
        acts[target] = action
        try:
            obs = env.step(acts)[0]
        except ValueError as exc:
            assert target in str(exc), f"error for {action!r} does not name the agent: {exc}"
            return
        assert all(np.isfinite(o).all() for o in obs.values())

    check()
