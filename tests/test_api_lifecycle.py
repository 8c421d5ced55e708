"""API lifecycle (issue 11, items 2 and 8-12 and the packaging items): each
test reproduces one reported defect."""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import icv_envs  # noqa: F401
from icv_envs.cli import main
from icv_envs.envs import highway_formation_v0, highway_ramps_v0, intersection_v0
from icv_envs.envs.highway_formation import HighwayFormationEnv

ROOT = Path(__file__).resolve().parents[1]
RENDER_ENV = {"SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"}


# ----------------------------------------------------------- item 2: experts
def _fresh(core):
    return core.expert.compute(core.world).astype(np.float32)


def test_expert_actions_not_stale_after_crash_and_spawn_in_one_step():
    """A crashed vehicle removed and a new one spawned in the same step keep
    the vehicle count: the cache must still recompute (labels of the new
    agent and the expert driving missing agents use the current state)."""
    spawns = [{"time": round(0.2 * k, 1), "position": 1200.0 + 40 * (k % 20), "lane": k % 4} for k in range(1, 80)]
    env = highway_formation_v0.parallel_env(vehicles_count=24, duration=30.0, spawns=spawns, missing_action="expert")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    both = stale = 0
    for _ in range(140):
        before = set(env.agents)
        acts = {a: rng.uniform(-1, 1, 2) for a in env.agents if rng.random() < 0.5}  # random agents crash
        obs, _, _, _, infos = env.step(acts)
        core = env.core
        vid = core.world.traffic.vid
        fresh = _fresh(core)
        new = [a for a in obs if a not in before]
        if new and any(infos[a].get("crashed") for a in infos):
            both += 1
        ex = env.expert_actions()
        stale += any(not np.array_equal(ex[f"icv_{v}"], fresh[i]) for i, v in enumerate(vid))
        stale += any(not np.array_equal(infos[a]["expert_action"], fresh[int(np.searchsorted(vid, int(a[4:])))])
                     for a in new)
    assert both >= 5  # the situation of the report happened
    assert stale == 0


@pytest.mark.parametrize("case", ["ramps-spawns", "crash-and-spawn"])
def test_every_info_label_is_the_action_the_expert_takes_next(case):
    """``infos[a]["expert_action"]`` of a step equals ``expert_actions()[a]``
    at the next step for every agent (imitation labels). Before, the labels
    were computed before the step's spawns (and crash removals) and the
    expert again after them: on the ring, 12 of 500 steps had a label that
    was not the expert's next action."""
    rng = np.random.default_rng(0)
    if case == "ramps-spawns":
        env = highway_ramps_v0.parallel_env(vgr=1.0, duration=40.0)
        steps, p_random = 200, 0.0
    else:
        spawns = [{"time": round(0.2 * k, 1), "position": 1200.0 + 40 * (k % 20), "lane": k % 4} for k in range(1, 80)]
        env = highway_formation_v0.parallel_env(vehicles_count=24, duration=30.0, spawns=spawns)
        steps, p_random = 140, 0.5
    obs, infos = env.reset(seed=0)
    mismatched = spawn_steps = crash_steps = 0
    for _ in range(steps):
        if env.episode_over:
            break
        ex = env.expert_actions()
        mismatched += sum(not np.array_equal(infos[a]["expert_action"], ex[a]) for a in env.agents)
        before = set(env.agents)
        acts = {a: (rng.uniform(-1, 1, 2).astype(np.float32) if rng.random() < p_random else ex[a]) for a in env.agents}
        obs, _, _, _, infos = env.step(acts)
        spawn_steps += any(a not in before for a in obs)
        crash_steps += any(i.get("crashed") for i in infos.values())
    assert spawn_steps >= 10
    if case == "crash-and-spawn":
        assert crash_steps >= 3
    assert mismatched == 0


@pytest.mark.parametrize("name", ["ramps", "intersection"])
def test_expert_cache_follows_the_vehicle_set(name):
    """Remove one vehicle and add one (same count, same time): the cached
    actions are recomputed on the open-road envs too."""
    if name == "ramps":
        env = highway_ramps_v0.parallel_env(duration=60.0, vgr=1.0)
    else:
        env = intersection_v0.parallel_env(duration=60.0, throughput=3000.0)
    env.reset(seed=0)
    core = env.core
    for _ in range(25):
        env.step({a: core.expert_actions()[i] for i, a in enumerate(env.agents)})
    core.expert_actions()
    w = core.world
    n = w.traffic.n
    assert n >= 3
    if name == "ramps":
        tr = w.traffic
        tr.crashed[0] = True
        w.remove_crashed_vehicles()
        road = w.road
        tr.add(road.on_ramps[2].start - road.on_ramps[2].approach + 5.0, road.ramp_lane * road.lane_width, 3.0,
               exit=0, time=w.time)  # slow: the expert accelerates it (the others coast at 15 m/s)
        w.invalidate()
    else:
        f = w.fleet
        leg, lane, mv = int(f.leg[0]), 0, int(f.mv[0])
        f.crashed[0] = True
        w.remove_crashed_vehicles()
        vid = w.spawn(leg, lane, mv, 10.0, -(core.layout.R3 - core.layout.box_half), tlane=lane)
        core.expert.on_spawn(w, vid, None, 0.0, lane)
        core.expert.update(w)
    assert w.traffic.n == n
    fresh = _fresh(core)
    assert np.abs(fresh[-1]).max() > 0
    np.testing.assert_array_equal(core.expert_actions(), fresh)


# --------------------------------------------------- item 8: failed reconfig
@pytest.mark.parametrize("make", [
    lambda: highway_ramps_v0.parallel_env(duration=30.0, vgr=0.2),
    lambda: intersection_v0.parallel_env(duration=30.0),
])
def test_rejected_reset_config_leaves_the_env_usable(make):
    env = make()
    env.reset(seed=0)
    before = dict(env.core.config)
    with pytest.raises(ValueError, match="possible agents"):
        env.reset(seed=0, options={"config": {"duration": 60.0}})
    assert env.core.config == before
    obs, _ = env.reset(seed=1)  # later resets keep working
    assert obs
    env.step({a: np.zeros(2) for a in env.agents})


def test_rejected_gym_reset_config_keeps_the_old_one():
    env = gym.make("icv_envs/Intersection-v0").unwrapped
    env.reset(seed=0)
    before = dict(env.config)
    layout = env.layout
    with pytest.raises(ValueError, match="D_t"):
        env.reset(seed=0, options={"config": {"D_t": 5.0, "lane_use": "exclusive"}})
    assert env.config == before and env.layout is layout
    env.reset(seed=0)
    env.step(np.zeros(2, dtype=np.float32))


# --------------------------------------------- item 9: AEC on an open road
def test_aec_env_runs_to_the_end_of_an_open_road_episode():
    """At 100 veh/h the intersection is empty now and then; the AEC env must
    not stop there but run to ``duration``."""
    T = 300.0
    par = intersection_v0.parallel_env(throughput=100.0, duration=T)
    par.reset(seed=0)
    empty_before_end = 0
    while not par.episode_over:
        par.step({a: par.core.expert_actions()[i] for i, a in enumerate(par.agents)})
        empty_before_end += not par.agents and not par.episode_over
    assert empty_before_end > 0  # the situation of the report
    spawned = par.metrics()["spawned"]

    env = intersection_v0.env(throughput=100.0, duration=T)
    env.reset(seed=0)
    for agent in env.agent_iter():
        _, _, term, trunc, info = env.last()
        env.step(None if term or trunc else info["expert_action"])
    core = env.unwrapped.core
    assert core.world.time == pytest.approx(T)
    assert core.metrics()["spawned"] == spawned


# ------------------------------------------------- item 10: spaces once
def test_gym_reset_keeps_the_space_objects():
    env = gym.make("icv_envs/HighwayFormation-v0")
    base = env.unwrapped
    a_space, o_space = base.action_space, base.observation_space
    env.action_space.seed(7)
    env.reset(seed=0)
    first = [env.action_space.sample() for _ in range(3)]
    assert base.action_space is a_space and base.observation_space is o_space
    env.reset(seed=1, options={"config": {"duration": 30.0}})
    assert base.action_space is a_space and base.observation_space is o_space
    ref = gym.spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
    ref.seed(7)
    assert all(np.array_equal(x, ref.sample()) for x in first)



@pytest.mark.parametrize("env_id", ["icv_envs/HighwayFormation-v0", "icv_envs/Intersection-v0",
                                    "icv_envs/HighwayRamps-v0"])
def test_configure_then_reset_applies_the_observation_and_action_config(env_id):
    """highway-env's convention, ``env.unwrapped.configure(...)`` then
    ``reset()``, applies a new observation and action config (until stop
    42 the types built at construction stayed: a new perception distance
    or action type was accepted and ignored). The observations equal those
    of an env made with that config; a new action type gives its space."""
    change = {"observation": {"type": "Kinematics", "perception_distance": 40.0, "vehicles_count": 4}}
    made = gym.make(env_id, config=dict(change))
    env = gym.make(env_id)
    env.reset(seed=0)
    env.unwrapped.configure(dict(change))
    outs = []
    for e in (made, env):
        obs, _ = e.reset(seed=3)
        steps = [obs]
        for _ in range(4):
            obs, *_ = e.step(np.zeros(2, dtype=np.float32))
            steps.append(obs)
        outs.append(steps)
    assert env.unwrapped._obs_type.pd == 40.0 and env.unwrapped.observation_space.shape[0] == 4
    assert all(np.array_equal(a, b) for a, b in zip(*outs))
    env.unwrapped.configure({"action": {"type": "DiscreteMetaAction"}})
    env.reset(seed=4)
    assert isinstance(env.unwrapped.action_space, gym.spaces.Discrete)


def test_parallel_env_refuses_a_core_config_that_changes_its_spaces():
    """A PettingZoo env's spaces are fixed at construction: a config given
    to its core that changes them raises at reset, naming both ways in;
    one that keeps them (a new perception distance) is applied."""
    env = intersection_v0.parallel_env()
    env.reset(seed=0)
    space = env.observation_space(env.possible_agents[0])
    env.core.configure({"observation": {"type": "Kinematics", "perception_distance": 40.0}})
    env.reset(seed=1)
    assert env.core._obs_type.pd == 40.0 and env.observation_space(env.possible_agents[0]) is space
    env.core.configure({"observation": {"type": "Kinematics", "vehicles_count": 3}})
    with pytest.raises(ValueError, match=r"or core.configure\(\)\) may not change the observation or action space"):
        env.reset(seed=2)


# ------------------------------------------- item 11: duration and traffic
def test_ramps_traffic_does_not_depend_on_duration():
    short = highway_ramps_v0.parallel_env(duration=60.0, vgr=0.5, max_vehicles=400)
    long = highway_ramps_v0.parallel_env(duration=300.0, vgr=0.5, max_vehicles=400)
    short.reset(seed=3)
    long.reset(seed=3)
    a_s = [a for a in short.core._arrivals]
    a_l = [a for a in long.core._arrivals if a[0] < 60.0]
    assert a_s == a_l and len(a_s) > 50
    for _ in range(20):
        o1 = short.step({a: short.core.expert_actions()[i] for i, a in enumerate(short.agents)})[0]
        o2 = long.step({a: long.core.expert_actions()[i] for i, a in enumerate(long.agents)})[0]
        assert o1.keys() == o2.keys() and all(np.array_equal(o1[a], o2[a]) for a in o1)


def test_intersection_traffic_does_not_depend_on_duration():
    short = intersection_v0.parallel_env(duration=60.0, max_vehicles=500)
    long = intersection_v0.parallel_env(duration=240.0, max_vehicles=500)
    short.reset(seed=5)
    long.reset(seed=5)
    a_s = list(short.core._pending)
    a_l = [a for a in long.core._pending if a[0] < 60.0]
    assert a_s == a_l and len(a_s) > 10


# ----------------------------------- item 12: signals, reset before step
def test_sigterm_still_ends_the_process_after_render(tmp_path):
    script = tmp_path / "s.py"
    script.write_text(textwrap.dedent("""
        import os, signal, time
        from icv_envs import intersection_v0
        env = intersection_v0.parallel_env(render_mode="rgb_array")
        env.reset(seed=0)
        assert env.render().ndim == 3
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
        print("survived SIGTERM")
    """))
    env = {**os.environ, **RENDER_ENV, "PYTHONPATH": str(ROOT)}
    res = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=120)
    assert "survived" not in res.stdout
    assert res.returncode == -signal.SIGTERM, res.stderr[-2000:]


@pytest.mark.parametrize("env_id", ["icv_envs/HighwayFormation-v0", "icv_envs/HighwayRamps-v0",
                                    "icv_envs/Intersection-v0"])
def test_step_before_reset_raises(env_id):
    env = gym.make(env_id).unwrapped  # without Gymnasium's order enforcing
    assert env.world is None  # the constructor does not reset
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        env.step(np.zeros(2, dtype=np.float32))
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        env.ma_step({})


def test_parallel_step_before_reset_raises():
    env = highway_formation_v0.parallel_env()
    assert env.possible_agents == [f"icv_{i}" for i in range(8)]
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        env.step({})


# ------------------------------------------------------------ packaging
def test_submodule_import():
    code = ("import icv_envs.highway_formation_v0 as a, icv_envs.highway_ramps_v0 as b, "
            "icv_envs.intersection_v0 as c; from icv_envs.intersection_v0 import parallel_env; "
            "import icv_envs.envs.highway_formation_v0 as d; assert a is d; print(parallel_env().metadata['name'])")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120,
                         cwd="/")
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == "intersection_v0"


@pytest.mark.parametrize("make", [
    lambda: highway_formation_v0.parallel_env(render_mode="rgb_array", scenario="on-ramp"),
    lambda: intersection_v0.parallel_env(render_mode="rgb_array"),
    lambda: gym.make("icv_envs/HighwayRamps-v0", render_mode="rgb_array").unwrapped,
])
def test_pickle_after_render(make, monkeypatch):
    for k, v in RENDER_ENV.items():
        monkeypatch.setenv(k, v)
    env = make()
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3
    clone = pickle.loads(pickle.dumps(env))
    if isinstance(env, HighwayFormationEnv):
        a = env.step(np.zeros(2, dtype=np.float32))[0]
        b = clone.step(np.zeros(2, dtype=np.float32))[0]
        np.testing.assert_array_equal(a, b)
    else:
        acts = {a: np.zeros(2) for a in env.agents}
        o1, o2 = env.step(acts)[0], clone.step(acts)[0]
        assert all(np.array_equal(o1[a], o2[a]) for a in o1)
    assert clone.render().shape == frame.shape


# ------------------------------------------------ item 14: the command line
@pytest.mark.parametrize("argv, match", [
    (["run", "highway-formation", "--method", "idm", "--vgr", "0.9"], r"--method 'idm' does not apply to run "
                                                                       r"highway-formation.*highway-ramps"),
    (["run", "highway-formation", "--vgr", "0.9"], r"--vgr 0.9 does not apply"),
    (["run", "highway-ramps", "--scenario", "on-ramp"], r"--scenario 'on-ramp' does not apply to run highway-ramps"),
    (["run", "highway-ramps", "--policy", "random"], r"--policy 'random' does not apply to run highway-ramps"),
    (["run", "highway-ramps", "--video", "--out", "x"], r"--video True does not apply to run highway-ramps"),
    # a given 0 is given (until stop 44 ``run`` took 0 for "not given", as a flag's False, and ran without it)
    (["run", "highway-formation", "--vgr", "0"], r"--vgr 0.0 does not apply to run highway-formation"),
])
def test_cli_options_of_another_env_are_errors(argv, match, capsys):
    assert main(argv + ["--seconds", "1"]) == 2
    assert pytest.importorskip("re").search(match, capsys.readouterr().err)


@pytest.mark.parametrize("argv, match", [
    (["bench", "highway-formation", "--throughput", "3000"], r"--throughput 3000.0 does not apply to bench "
                                                              r"highway-formation: it is an option of bench intersection"),
    (["bench", "intersection", "--sizes", "50"], r"--sizes \[50\] does not apply to bench intersection"),
    (["bench", "intersection", "--vgr", "0.5"], r"--vgr 0.5 does not apply to bench intersection"),
    (["bench", "highway-ramps", "--method", "fcfs"], r"--method 'fcfs' does not apply to bench highway-ramps"),
    (["bench", "highway-ramps", "--warmup", "10"], r"--warmup 10.0 does not apply to bench highway-ramps"),
    (["bench", "highway-formation", "--seeds", "2"], r"--seeds 2 does not apply to bench highway-formation"),
    (["bench", "train", "--seconds", "5"], r"--seconds 5.0 does not apply to bench train"),
    (["bench", "highway-ramps", "--stock-seconds", "2"], r"--stock-seconds 2.0 does not apply to bench highway-ramps"),
    (["bench", "train", "--warmup", "0"], r"--warmup 0.0 does not apply to bench train"),
    (["bench", "intersection", "--throughput", "0"], r"throughput 0.0 is invalid; allowed: 0 < throughput"),
    (["bench", "intersection", "--seeds", "0"], r"--seeds must be an integer >= 1, got '0'"),
    (["bench", "intersection", "--warmup", "-1"], r"--warmup must be a finite number >= 0, got '-1'"),
])
def test_cli_bench_options_of_another_target_are_errors(argv, match, capsys):
    """Until stop 43 ``bench`` accepted every target's options and ignored
    those of the others (``bench highway-formation --throughput 3000`` ran
    the highway bench as if it had not been given)."""
    assert _cli_code(argv) == 2
    assert pytest.importorskip("re").search(match, capsys.readouterr().err)


def _cli_code(argv) -> int:
    """The command line's exit code (argparse's own check of a value exits)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def test_parallel_reset_builds_no_ego_observation_and_keeps_a_replaced_reset(monkeypatch):
    """Stop 43: the multi-agent reset no longer builds the single ego's
    observation and info (it discarded them), and gives the same
    observations and infos as before; a ``reset`` replaced on a subclass or
    the instance is still the one called."""
    from icv_envs.envs import highway_formation_v0
    from icv_envs.envs.ego import EgoEnv

    a = highway_formation_v0.parallel_env(vehicles_count=6)
    calls = []
    real = EgoEnv._ego_obs_info
    monkeypatch.setattr(EgoEnv, "_ego_obs_info", lambda self: calls.append(1) or real(self))
    obs_a, inf_a = a.reset(seed=4)
    assert calls == []
    b = highway_formation_v0.parallel_env(vehicles_count=6)
    b.core.reset = lambda **kw: (calls.append("own"), EgoEnv.reset(b.core, **kw))[1]
    obs_b, inf_b = b.reset(seed=4)
    assert calls[0] == "own" and 1 in calls  # the replaced reset ran, and with it the ego's observation
    assert list(obs_a) == list(obs_b) and all(np.array_equal(obs_a[k], obs_b[k]) for k in obs_a)
    assert all(np.array_equal(inf_a[k]["expert_action"], inf_b[k]["expert_action"]) for k in inf_a)


@pytest.mark.parametrize("make", [
    lambda: gym.make("icv_envs/HighwayFormation-v0"), lambda: gym.make("icv_envs/Intersection-v0"),
    lambda: highway_formation_v0.parallel_env(), lambda: highway_ramps_v0.parallel_env(),
    lambda: intersection_v0.parallel_env(), lambda: intersection_v0.env(),
])
def test_reset_options_other_than_config_are_named(make):
    """``reset(options=...)`` reads ``{"config": {...}}`` only (stop 45: any
    other key was ignored silently, a typo such as ``"confg"`` reset with the
    old config). Other keys are ignored with a warning naming them (an error
    would fail PettingZoo's own API test, which resets with
    ``options={"options": 1}``); a non-dict is an error."""
    env = make()
    with pytest.warns(UserWarning, match=r"reset option\(s\) \['confg'\] are not used by this env"):
        env.reset(seed=0, options={"confg": {"duration": 5.0}})
    with pytest.raises(ValueError, match=r"reset options = \[1\]; allowed: None or a dict"):
        env.reset(seed=0, options=[1])
    env.reset(seed=0, options={})  # (empty: nothing to apply)
    env.close()


@pytest.mark.parametrize("argv, match", [
    # a negative seed crashed with gymnasium's own error type (exit 1, a traceback)
    (["run", "highway-formation", "--seconds", "1", "--seed", "-1"], r"--seed must be an integer >= 0, got '-1'"),
    (["demo", "--seed", "-1", "--no-video"], r"--seed must be an integer >= 0, got '-1'"),
    (["dataset", "--env", "highway_formation_v0", "--episodes", "1", "--out", "x", "--seed", "-2"],
     r"--seed must be an integer >= 0"),
    # --config keys the run's own options set: highway-ramps crashed (multiple values), highway-formation let the
    # config win (and reported the option's scenario), intersection let the option win
    (["run", "highway-ramps", "--seconds", "1", "--config", '{"duration": 100}'],
     r"config key\(s\) 'duration' \(set by seconds \(--seconds\)\)"),
    (["run", "highway-ramps", "--seconds", "1", "--config", '{"vgr": 0.5}'], r"'vgr' \(set by vgr \(--vgr\)\)"),
    (["run", "highway-ramps", "--seconds", "1", "--config", "[1]"], r"--config must be a JSON object"),
    (["run", "highway-ramps", "--seconds", "1", "--config", "notjson"], r"--config is not valid JSON"),
    (["run", "highway-formation", "--seconds", "1", "--scenario", "free", "--config", '{"scenario": "lane-drop"}'],
     r"'scenario' \(set by scenario \(--scenario\)\)"),
    (["run", "highway-formation", "--seconds", "2", "--config", '{"duration": 100}'], r"'duration' \(set by seconds"),
    (["run", "intersection", "--seconds", "1", "--config", '{"method": "fcfs", "lane_use": "exclusive"}'],
     r"'method' \(set by method \(--method\)\), 'lane_use' \(set by --lane-use\)"),
    # compare took the other target's options and ignored them, and an empty list for the defaults
    (["compare", "highway-ramps", "--seconds", "1", "--throughput", "1000"],
     r"--throughput '1000' does not apply to compare highway-ramps: it is an option of compare intersection"),
    (["compare", "highway-ramps", "--seconds", "1", "--lane-use", "exclusive"], r"--lane-use 'exclusive' does not"),
    (["compare", "highway-ramps", "--seconds", "1", "--warmup", "5"], r"--warmup 5.0 does not apply"),
    (["compare", "intersection", "--seconds", "1", "--vgr", "0.9"], r"--vgr \[0.9\] does not apply to compare inters"),
    (["compare", "intersection", "--seconds", "1", "--methods", ","], r"--methods: the list is empty"),
    (["compare", "intersection", "--seconds", "1", "--methods", "fcfs,fcfs"], r"--methods: the list repeats a name"),
    (["compare", "intersection", "--seconds", "1", "--throughput", ""], r"--throughput is empty"),
    (["compare", "intersection", "--seconds", "1", "--throughput", "1000,1000"], r"repeats a demand"),
    (["compare", "highway-ramps", "--seconds", "1", "--workers", "0"], r"--workers must be an integer >= 1"),
    (["compare", "highway-ramps", "--seconds", "1", "--workers", "2", "--backend", "ray"],
     r"workers = 2 applies to backend 'process' only"),
])
def test_cli_misread_options_are_errors(argv, match, capsys, tmp_path, monkeypatch):
    """Options that were misread, ignored or crashed deep inside (stop 45's review of the command line)."""
    monkeypatch.chdir(tmp_path)  # (nothing may be written; if it were, not into the checkout)
    assert _cli_code(argv) == 2
    assert pytest.importorskip("re").search(match, capsys.readouterr().err)


def test_experiment_runners_check_their_arguments(tmp_path, monkeypatch):
    """The Python API behind the commands: a float seed was truncated, a bare
    string of methods split into letters, a bool taken as a number, a config
    key that an argument also sets silently won or lost."""
    monkeypatch.chdir(tmp_path)  # (the sweeps' "x" outputs, had a check been missed)
    from icv_envs.experiments.compare import compare_highway_ramps, run_ramps, validate_grid
    from icv_envs.experiments.intersection_compare import (compare_intersection, parse_throughputs,
                                                          run_intersection, validate_grid as validate_tp)
    from icv_envs.experiments.run import run_highway_formation

    cases = [
        (lambda: run_ramps("formation", 0.3, 1.5, 1.0), r"seed = 1.5; allowed: an integer >= 0"),
        (lambda: run_intersection("multi-vp", 1000.0, 1.5, 1.0), r"seed = 1.5; allowed"),
        (lambda: run_highway_formation("free", seed=1.5, seconds=1.0), r"seed = 1.5; allowed"),
        (lambda: run_highway_formation("free", seconds=True), r"seconds = True; allowed: a finite number > 0"),
        (lambda: run_highway_formation("free", seconds=1.0, config={"scenario": "lane-drop"}), r"'scenario' \(set by"),
        (lambda: run_highway_formation("free", seconds=1.0, config=[1]), r"config = \[1\]; allowed: None or a dict"),
        (lambda: run_highway_formation("free", seconds=1.0, video=True), r"video=True needs out"),
        (lambda: run_intersection("multi-vp", 1000.0, 0, 1.0, {"throughput": 3000.0}), r"'throughput' \(set by"),
        (lambda: validate_grid("idm", [0.3], 1, 1.0), r"methods = 'idm'; allowed: a list"),
        (lambda: validate_grid(["idm"], 0.5, 1, 1.0), r"vgrs = 0.5; allowed: a list"),
        (lambda: validate_grid(["idm"], [True], 1, 1.0), r"vgr True is invalid"),
        (lambda: validate_grid(["idm"], [0.3], 1, True), r"seconds = True"),
        (lambda: validate_grid(["idm", "idm"], [0.3], 1, 1.0), r"repeat a method"),
        (lambda: validate_tp("fcfs", [1000.0], 1, 1.0), r"methods = 'fcfs'; allowed: a list"),
        (lambda: validate_tp(["fcfs"], [1000.0, 1000.0], 1, 1.0), r"repeat a value"),
        (lambda: parse_throughputs("1000,1000"), r"repeats a demand"),
        (lambda: compare_highway_ramps(["idm"], [0.3], 1, 1.0, "x", workers=0), r"workers = 0; allowed"),
        (lambda: compare_intersection(["fcfs"], [1000.0], 1, 1.0, "x", workers=True), r"workers = True; allowed"),
        (lambda: compare_intersection(["fcfs"], [1000.0], 1, 1.0, "x", config={"duration": 5.0}), r"'duration'"),
    ]
    for make, match in cases:
        with pytest.raises(ValueError, match=match):
            make()


def test_gym_make_with_a_config_key_as_keyword_points_to_config():
    """``gym.make(id, duration=2)``: the error names the key and where it goes
    (stop 45: Python's own "unexpected keyword argument" only)."""
    with pytest.raises(TypeError, match=r"unknown keyword argument\(s\) \['duration'\]; the env takes config="):
        gym.make("icv_envs/HighwayFormation-v0", duration=2.0)


def test_aec_env_takes_an_agent_that_arrives_truncated_in_the_last_step():
    """HighwayRamps and the intersection: a vehicle spawned in the episode's
    last step is reported once, already truncated; PettingZoo's conversion
    then deleted an action it never had (KeyError until stop 45, seeds 1-3 of
    0-4 at 20 s; PettingZoo's api_test on the intersection failed so)."""
    from pettingzoo.test import api_test

    for seed in (1, 2, 3):
        env = highway_ramps_v0.env(duration=20.0, missing_action="expert")
        env.reset(seed=seed)
        for a in env.agent_iter():
            _, _, te, tr, _ = env.last()
            env.step(None if te or tr else np.zeros(2, np.float32))
    api_test(intersection_v0.env(duration=5.0, throughput=2000.0), num_cycles=200)


def test_a_rejected_reset_config_is_not_applied():
    """``reset(options={"config": ...})`` that would change a PettingZoo env's
    spaces is refused before it is applied (stop 45: it was applied, then
    refused, and every later reset failed)."""
    env = highway_formation_v0.parallel_env(duration=3.0, vehicles_count=4)
    o0, _ = env.reset(seed=0)
    with pytest.raises(ValueError, match="changes the spaces"):
        env.reset(seed=0, options={"config": {"observation": {"type": "OccupancyGrid"}}})
    assert env.core.config["observation"]["type"] == "Kinematics"
    o1, _ = env.reset(seed=0)
    assert all(np.array_equal(o0[a], o1[a]) for a in o0)


def test_expert_actions_cannot_be_changed_by_the_caller():
    """``expert_actions()``: the PettingZoo dict holds rows of a copy (adding
    noise to them changed what a FormationResidual env then applied, stop
    45), the core's array is read-only."""
    def run(noise):
        env = highway_formation_v0.parallel_env(duration=3.0, vehicles_count=4, action={"type": "FormationResidual"})
        env.reset(seed=0)
        out = []
        for _ in range(8):
            ex = env.expert_actions()
            for a in ex:
                ex[a] += noise
            out.append(np.stack(list(env.step({a: np.zeros(2, np.float32) for a in env.agents})[0].values())))
        return out, env

    clean, _ = run(0.0)
    noisy, env = run(0.5)
    assert all(np.array_equal(x, y) for x, y in zip(clean, noisy))
    with pytest.raises(ValueError, match="read-only"):
        env.core.expert_actions()[0] += 1.0


def test_step_after_the_episode_names_reset():
    """A step after the episode ended says so (stop 45: it named the agents
    already reported done as live agents without actions)."""
    env = highway_formation_v0.parallel_env(duration=1.0, vehicles_count=4)
    env.reset(seed=0)
    while env.agents:
        env.step({a: np.zeros(2, np.float32) for a in env.agents})
    with pytest.raises(RuntimeError, match="the episode is over .*call reset"):
        env.step({})
    with pytest.raises(RuntimeError, match="the episode is over"):
        env.step_rows(np.zeros((0, 2)))


def test_a_config_edited_in_place_is_validated_at_reset():
    """``env.unwrapped.config[key] = value`` then ``reset()`` (highway-env's
    habit) is validated as ``configure()`` is (stop 45: a 9-lane road was
    built); a valid edit is applied."""
    env = gym.make("icv_envs/HighwayFormation-v0")
    env.unwrapped.config["lanes_count"] = 9
    with pytest.raises(ValueError, match=r"config\['lanes_count'\] = 9 is invalid"):
        env.reset(seed=0)
    env.unwrapped.config["lanes_count"] = 3
    env.reset(seed=0)
    assert env.unwrapped.config["lanes_count"] == 3


@pytest.mark.parametrize("make", [highway_formation_v0.parallel_env, highway_ramps_v0.parallel_env,
                                  intersection_v0.parallel_env])
def test_highway_env_road_and_ego_are_built_when_read_after_a_reset(make):
    """Stop 52: a reset no longer builds highway-env's road and vehicle
    views (a quarter of a reset's time, paid by training's many resets
    without rendering); reading ``road``, ``controlled_vehicles`` or
    ``vehicle`` after a reset builds them for the new world, with one view
    per vehicle at its current place."""
    env = make()
    env.reset(seed=3)
    core = env.core
    assert core.__dict__.get("_road") is None  # not built by the reset
    road = core.road
    assert road is not None and len(road.vehicles) == core._vehicles().n
    cx = core.world.route().cx if hasattr(core.world, "route") else core.world.traffic.center()[0]
    assert sorted(float(v.position[0]) for v in road.vehicles) == sorted(np.asarray(cx).tolist())
    assert core.controlled_vehicles and core.vehicle is core.controlled_vehicles[0]
    env.reset(seed=4)  # a new world: a new road when read
    assert core.road is not road
    gym_env = gym.make("icv_envs/HighwayFormation-v0")
    gym_env.reset(seed=0)
    assert gym_env.unwrapped.vehicle is not None
