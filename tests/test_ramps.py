"""HighwayRamps: the ring with five on/off-ramps, its methods, metrics, sweep and bad input."""

import csv
import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

from icv_envs import highway_ramps_v0
from icv_envs.cli import main
from icv_envs.experiments.compare import compare_highway_ramps, run_ramps
from icv_envs.sim.road import OffRamp, OnRamp, RoadLayout
from icv_envs.sim.traffic import find_collisions, lane_index, leaders


def test_parallel_api():
    parallel_api_test(highway_ramps_v0.parallel_env(vgr=0.3, duration=40.0), num_cycles=200)


def test_gym_check_env_and_ids():
    import icv_envs  # noqa: F401

    env = gym.make("icv_envs/HighwayRamps-v0", config={"duration": 20.0, "vgr": 0.2})
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=0)
    assert obs.shape == (8, 13) and "expert_action" in info
    import pettingzoo

    p = pettingzoo.make("parallel", "icv_envs/highway_ramps-v0", duration=10.0)
    assert isinstance(p, highway_ramps_v0.HighwayRampsParallelEnv)


@pytest.mark.parametrize("method", ["formation", "lane-lp", "idm"])
def test_short_runs_account_for_every_vehicle(method):
    m = run_ramps(method, 0.33, 0, 150.0)
    assert m["lost"] == 0
    assert m["spawned"] == m["exited"] + m["remaining"] + m["crashed_removed"]
    assert m["spawned"] > 200 and m["exited"] > 0
    assert len(m["timeseries"]) == 151
    heat = np.asarray(m["heatmap_final"])
    assert heat.shape == (4, 20)
    assert 0.8 * m["remaining"] <= heat.sum() <= m["remaining"]  # main-lane vehicles (ramp ones not counted)
    assert m["timeseries"][-1]["remaining"] == m["remaining"]
    if method == "formation":
        assert m["collisions"] == 0


@pytest.mark.parametrize("method", ["lane-lp-close", "idm-close"])
def test_close_references_follow_at_the_members_gap(method):
    """The equal-margin references (issue 8): the base reference's controller
    with the IDM time gap the formation's members keep; measurably closer
    car following than the default reference on the same arrivals."""
    from icv_envs.policies.formation_expert import ExpertParams
    from icv_envs.policies.reference import IdmMobilPolicy, LaneLpPolicy

    env = highway_ramps_v0.parallel_env(method=method, vgr=0.33, duration=10.0)
    env.reset(seed=0)
    ex = env.core.expert
    assert type(ex) is (LaneLpPolicy if method.startswith("lane-lp") else IdmMobilPolicy)
    assert ex.p.idm_T == ExpertParams().member_time_gap == 0.5
    base = highway_ramps_v0.parallel_env(method=method.removesuffix("-close"), vgr=0.33, duration=10.0)
    base.reset(seed=0)
    assert base.core.expert.p.idm_T == ExpertParams().idm_T == 1.0
    assert env.core.metrics()["method"] == method
    close = run_ramps(method, 0.33, 0, 200.0)
    default = run_ramps(method.removesuffix("-close"), 0.33, 0, 200.0)
    assert close["lost"] == 0 and close["spawned"] == default["spawned"]
    # closer following where following binds (at 200 s the idm reference's
    # 5th percentile is set by free traffic: 1.46 s either way)
    assert close["min_time_headway"] < 0.8 * default["min_time_headway"]
    assert close["time_headway_p05"] <= default["time_headway_p05"]


def test_formation_method_forms_formations_on_the_left_three_lanes():
    env = highway_ramps_v0.parallel_env(vgr=0.33, duration=120.0)
    env.reset(seed=1)
    while not env.episode_over:
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    w = env.core.world
    assert len(w.manager.anchor) > 5
    assert all(set(f["lanes"]) <= {0, 1, 2} for f in w.manager.summary())
    _, lane_ref, _, member = w.manager.references(w.traffic)
    assert member.sum() > 0.5 * w.traffic.n and set(lane_ref[member]) <= {0, 1, 2}


def test_determinism():
    a = run_ramps("formation", 0.25, 3, 60.0)
    b = run_ramps("formation", 0.25, 3, 60.0)
    c = run_ramps("formation", 0.25, 4, 60.0)
    for k in ("spawned", "remaining", "mean_speed", "speed_fluctuation", "timeseries"):
        assert a[k] == b[k]
    assert a["timeseries"] != c["timeseries"]


def test_fixed_arrivals_count():
    env = highway_ramps_v0.parallel_env(vgr=0.2, arrivals="fixed", duration=100.0)
    env.reset(seed=0)
    arrivals = len(env.core._arrivals) + env.core._spawned + sum(len(q) for q in env.core._queues)
    assert 5 * 19 <= arrivals <= 5 * 21


@pytest.mark.parametrize(
    "config, match",
    [
        ({"vgr": 0.0}, r"vgr = 0\.0 .*0 < vgr <= 1"),
        ({"vgr": -0.2}, r"vgr = -0\.2"),
        ({"vgr": 50.0}, r"vgr = 50\.0"),
        ({"method": "platoon"}, r"unknown method 'platoon'.*formation"),
        ({"exit_choices": [0, 7]}, r"exit_choices \[7\] do not exist.*\[0, 1, 2, 3, 4\]"),
        ({"exit_choices": []}, r"exit_choices"),
        ({"arrivals": "burst"}, r"arrivals = 'burst'"),
        ({"duration": 0.0}, r"duration"),
        ({"lane_speeds": [25.0, 25.0]}, r"lane_speeds"),
        ({"seam": 0.0}, r"ring road.*seam"),
    ],
)
def test_bad_config(config, match):
    with pytest.raises(ValueError, match=match):
        highway_ramps_v0.parallel_env(**config)


@pytest.mark.parametrize(
    "argv, match",
    [
        (["compare", "highway-ramps", "--methods", "formation,teleport", "--seconds", "5"], "unknown methods"),
        (["compare", "highway-ramps", "--vgr", "0,0.2", "--seconds", "5"], r"vgr 0\.0 is invalid"),
        (["compare", "highway-ramps", "--vgr", "9", "--seconds", "5"], r"vgr 9\.0 is invalid"),
        (["compare", "highway-ramps", "--seconds", "-1"], r"seconds = -1\.0"),
        (["compare", "highway-ramps", "--seconds", "0"], r"seconds = 0\.0"),
        (["compare", "highway-ramps", "--seeds", "0", "--seconds", "5"], r"seeds = '?0"),
        (["run", "highway-ramps", "--method", "warp", "--seconds", "5"], "unknown methods"),
        (["run", "highway-ramps", "--vgr", "-1", "--seconds", "5"], r"vgr -1\.0"),
        (["run", "highway-ramps", "--config", '{"exit_choices": [5]}', "--seconds", "5"], r"exit_choices \[5\]"),
    ],
)
def test_cli_bad_input(argv, match, capsys):
    try:  # argparse-level checks (--seeds) exit 2 themselves, the others return 2
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    assert rc == 2
    assert pytest.importorskip("re").search(match, capsys.readouterr().err)


def test_compare_writes_csv_and_plots(tmp_path):
    summary = compare_highway_ramps(["formation", "idm"], [0.2], 1, 30.0, tmp_path, workers=1, progress=False)
    assert summary["runs"] == 2
    rows = list(csv.DictReader(open(tmp_path / "results.csv")))
    assert [r["method"] for r in rows] == ["formation", "idm"]
    for col in ("method", "vgr", "seed", "collisions", "lost", "remaining", "mean_speed", "speed_fluctuation"):
        assert col in rows[0]
    for name in ("remaining_vs_vgr.png", "mean_speed_vs_vgr.png", "speed_fluctuation_vs_vgr.png",
                 "remaining_vs_time.png", "heatmap_formation.png", "heatmap_idm.png"):
        assert (tmp_path / name).stat().st_size > 5000
    run = json.loads((tmp_path / "runs" / "formation_vgr0.2_seed0.json").read_text())
    assert len(run["timeseries"]) == 31


def test_cli_run_and_bench(capsys, tmp_path):
    assert main(["run", "highway-ramps", "--method", "idm", "--vgr", "0.2", "--seconds", "20", "--out", str(tmp_path)]) == 0
    m = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert m["method"] == "idm" and m["lost"] == 0
    assert main(["bench", "highway-ramps", "--seconds", "20"]) == 0
    b = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for k in ("real_time_factor", "vehicles", "vehicle_steps_per_s", "peak_rss_mb"):
        assert b[k] > 0
    assert b["jit_seconds_excluded"] >= 0.0 and b["jit_compiles"] >= 0  # (from stop 54)


# the LP alone: tests/test_lane_lp.py


# ------------------------------------------------------------- ring geometry
def ring():
    return RoadLayout(4, 1000.0, 4.0, None, [OnRamp(500.0, 600.0, 100.0)], [OffRamp(100.0, 150.0, 250.0)], [],
                      periodic=True)


def test_ring_wrap_and_exit_ahead():
    r = ring()
    np.testing.assert_allclose(r.wrap(np.array([980.0, -980.0, 10.0])), [-20.0, 20.0, 10.0])
    np.testing.assert_allclose(r.exit_ahead(0, np.array([50.0, 120.0, 160.0, 900.0])), [50.0, -20.0, 940.0, 200.0])
    assert r.available(4, 1550.0) and not r.available(4, 1700.0)  # the ramp lane repeats every lap


def test_ring_neighbours_and_collisions_across_the_seam():
    cx = np.array([995.0, 3.0, 500.0])
    cy = np.zeros(3)
    idx = lane_index(cx, cy, np.full(3, 2.0), 4.0, 5, 1000.0, periodic=True)
    lead, lx = leaders(idx, np.array([0]), np.array([0]), cx, return_x=True)
    assert lead[0] == 1 and lx[0] == pytest.approx(1003.0)
    i, j = find_collisions(np.array([998.0, 1.5]), np.zeros(2), np.zeros(2), np.full(2, 5.0), np.full(2, 2.0),
                           period=1000.0)
    assert list(zip(i, j)) == [(0, 1)]
    i, j = find_collisions(np.array([990.0, 5.0]), np.zeros(2), np.zeros(2), np.full(2, 5.0), np.full(2, 2.0),
                           period=1000.0)
    assert len(i) == 0


def test_compare_on_ray_backend(tmp_path):
    pytest.importorskip("ray")
    summary = compare_highway_ramps(["idm"], [0.2], 2, 10.0, tmp_path, backend="ray", progress=False)
    assert summary["runs"] == 2
    rows = list(csv.DictReader(open(tmp_path / "results.csv")))
    assert [r["seed"] for r in rows] == ["0", "1"]


def test_compare_unknown_backend(tmp_path):
    with pytest.raises(ValueError, match="backend 'spark'"):
        compare_highway_ramps(["idm"], [0.2], 1, 10.0, tmp_path, backend="spark")


def _merge_script():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "scripts" / "merge_highway_runs.py"
    spec = importlib.util.spec_from_file_location("merge_highway_runs", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_merged_sweeps_equal_one_sweep(tmp_path):
    """A grid run in two pieces and merged gives the rows one sweep gives; a run
    met twice with different figures, or an unknown method, is refused."""
    merge = _merge_script()
    compare_highway_ramps(["idm"], [0.2], [0, 1], 10.0, tmp_path / "one", workers=1, progress=False)
    compare_highway_ramps(["idm"], [0.2], [1], 10.0, tmp_path / "b", workers=1, progress=False)
    compare_highway_ramps(["idm", "lane-lp"], [0.2], [0], 10.0, tmp_path / "a", workers=1, progress=False)
    assert merge.main([str(tmp_path / "a"), str(tmp_path / "b"), "--methods", "idm", "--out", str(tmp_path / "m")]) == 0
    timing = {"wall_seconds", "real_time_factor"}
    read = lambda d: [{k: v for k, v in r.items() if k not in timing}
                      for r in csv.DictReader(open(tmp_path / d / "results.csv"))]
    assert read("m") == read("one")
    assert json.loads((tmp_path / "m" / "summary.json").read_text())["table"] == \
        json.loads((tmp_path / "one" / "summary.json").read_text())["table"]
    run = tmp_path / "b" / "runs" / "idm_vgr0.2_seed1.json"
    r = json.loads(run.read_text())
    r["remaining"] += 1
    run.write_text(json.dumps(r))
    with pytest.raises(SystemExit, match="found twice with different figures"):
        merge.main([str(tmp_path / "one"), str(tmp_path / "b"), "--out", str(tmp_path / "x")])
    with pytest.raises(SystemExit, match="unknown methods"):
        merge.main([str(tmp_path / "one"), "--methods", "idmm", "--out", str(tmp_path / "x")])


def test_merge_plots_only_writes_only_plots(tmp_path):
    merge = _merge_script()
    compare_highway_ramps(["idm"], [0.2], [0], 10.0, tmp_path / "a", workers=1, progress=False)
    assert merge.main([str(tmp_path / "a"), "--plots-only", "--out", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p" / "mean_speed_vs_vgr.png").stat().st_size > 5000
    assert not (tmp_path / "p" / "results.csv").exists() and not (tmp_path / "p" / "runs").exists()
