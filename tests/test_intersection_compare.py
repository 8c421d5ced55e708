"""Intersection sweep (CSV + Fig. 14 plots) and benchmark, at toy size."""

import argparse
import csv
import json

import pytest

from icv_envs.experiments import intersection_bench, intersection_compare
from icv_envs.experiments.intersection_compare import CSV_COLUMNS, compare_intersection


def test_sweep_writes_csv_json_and_plots(tmp_path):
    out = tmp_path / "cmp"
    s = compare_intersection(["multi-vp", "fcfs"], [1500.0, 3000.0], 1, 40.0, out, workers=2, progress=False)
    assert s["runs"] == 4 and s["collisions"] == 0 and s["lost"] == 0
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert len(rows) == 4
    for col in ("method", "throughput", "seed", "collisions", "lost", "achieved_throughput", "mean_speed",
                "speed_fluctuation", "mean_delay"):
        assert col in rows[0]
    assert list(rows[0]) == CSV_COLUMNS
    assert {(r["method"], float(r["throughput"])) for r in rows} == {
        ("multi-vp", 1500.0), ("multi-vp", 3000.0), ("fcfs", 1500.0), ("fcfs", 3000.0)}
    for name in ("mean_speed_vs_throughput.png", "speed_fluctuation_vs_throughput.png",
                 "achieved_throughput_vs_throughput.png", "mean_delay_vs_throughput.png"):
        assert (out / name).stat().st_size > 5000
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["table"]) == 4
    assert (out / "runs" / "fcfs_tp3000_seed0.json").exists()


def test_cli_runner_prints_a_line_per_cell(tmp_path):
    lines = []
    ns = argparse.Namespace(methods="single-vp", throughput="2000", seeds="3,", seconds=30.0, out=str(tmp_path),
                            backend="process", workers=1, lane_use="exclusive", warmup=0.0)
    s = intersection_compare.run_cli(ns, echo=lines.append)
    assert len(lines) == 2 and lines[0].startswith("single-vp") and "collisions=0 jammed=0 lost=0" in lines[0]
    assert "capacity=" in lines[1] and s["table"][0]["seed_list"] == [3]
    assert s["out"] == str(tmp_path) and json.dumps(s)
    row = next(csv.DictReader(open(tmp_path / "results.csv")))
    assert row["lane_use"] == "exclusive"


def test_cli_takes_a_seed_list(tmp_path, capsys):
    """``icv-envs compare intersection --seeds 2,4`` runs seeds 2 and 4 (the CLI once accepted only a count)."""
    from icv_envs.cli import main

    assert main(["compare", "intersection", "--methods", "fcfs", "--throughput", "1500", "--seeds", "2,4",
                 "--seconds", "10", "--warmup", "0", "--workers", "1", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["table"][0]["seed_list"] == [2, 4]
    assert {int(r["seed"]) for r in csv.DictReader(open(tmp_path / "results.csv"))} == {2, 4}


def test_bench_reports_agent_steps_per_second():
    """The bench times ``--seconds`` after a fixed warm-up, per seed, and
    adds the seeds up (module docstring of experiments/intersection_bench)."""
    out = []
    res = intersection_bench.run_cli(argparse.Namespace(seconds=4.0, warmup=60.0, seeds=2, throughput=None,
                                                        method=None), echo=out.append)
    assert res["bench"] == "intersection" and res["env_steps"] == 40 and res["seeds"] == 2
    assert [p["seed"] for p in res["per_seed"]] == [0, 1] and all(p["env_steps"] == 20 for p in res["per_seed"])
    assert res["agent_steps"] == sum(p["agent_steps"] for p in res["per_seed"])
    assert res["mean_agents"] == res["agent_steps"] / res["env_steps"] >= 10  # the zones filled in 60 s
    assert res["warmup_seconds"] == 60.0 and res["sim_seconds"] == 4.0
    assert res["agent_steps_per_s"] > 0 and res["env_steps_per_s"] > 0
    lo, hi = res["agent_steps_per_cpu_s_range"]
    assert lo <= hi
    assert res["collisions"] == 0 and res["lost"] == 0
    assert "seed 0" in out[0] and "agent-steps/s" in out[-1]
    json.dumps(res)
    # the defaults: 500 s after 100 s of warm-up, 3 seeds
    import inspect

    sig = inspect.signature(intersection_bench.bench_intersection).parameters
    assert (sig["seconds"].default, sig["warmup"].default, sig["seeds"].default) == (500.0, 100.0, 3)


def test_bench_apis_drive_the_same_intersection():
    """``--api dicts``, ``lean`` and ``rows`` (from stop 47) step the same
    trajectory: the same vehicles in the same states, the same metrics and
    the same agent-steps counted; they differ only in what the API costs."""
    import numpy as np

    from icv_envs.envs.intersection_v0 import parallel_env

    states = {}
    for api, cfg in intersection_bench.APIS.items():
        env = parallel_env(method="multi-vp", throughput=2200.0, duration=80.0, **cfg)
        step = intersection_bench._stepper(env, api)
        step.infos = env.reset(seed=3)[1]
        counted = 0
        while env.core.world.time < 40.0 - 1e-9:
            counted += env.num_agents
            step()
        f = env.core.world.fleet
        states[api] = (f.vid.copy(), np.stack([f.x, f.y, f.speed, f.heading]), env.metrics(), counted)
    ref = states["dicts"]
    assert len(ref[0]) > 10 and ref[3] > 0
    for api, s in states.items():
        assert np.array_equal(s[0], ref[0]) and np.array_equal(s[1], ref[1]), api
        assert s[2] == ref[2] and s[3] == ref[3], api


def test_bench_api_choices(capsys):
    from icv_envs.cli import main

    with pytest.raises(ValueError, match=r"api = 'arrays'; allowed: \['dicts', 'lean', 'rows'\]"):
        intersection_bench.bench_intersection(seconds=1.0, api="arrays")
    res = intersection_bench.run_cli(argparse.Namespace(seconds=1.0, warmup=10.0, seeds=1, throughput=None,
                                                        method=None, api="rows"), echo=lambda s: None)
    assert res["api"] == "rows" and res["env_steps"] == 5
    with pytest.raises(SystemExit) as e:  # argparse's own error for an unknown choice
        main(["bench", "intersection", "--api", "arrays"])
    assert e.value.code == 2 and "'arrays'" in capsys.readouterr().err


def test_conflicts_cli(capsys):
    import json

    from icv_envs.cli import main

    assert main(["conflicts", "--lane-use", "paper", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    m = rep["matrix"]
    assert len(rep["movements"]) == 12 and len(m) == 12 and all(len(r) == 12 for r in m)
    assert all(m[i][i] == 1 for i in range(12)) and all(m[i][j] == m[j][i] for i in range(12) for j in range(12))
    assert main(["conflicts", "--lane-use", "exclusive"]) == 0
    out = capsys.readouterr().out
    rep2 = json.loads(out.strip().splitlines()[-1])
    assert rep2["matrix"] != m and len(out.strip().splitlines()) > 12  # the human-readable matrix comes first
    assert main(["conflicts", "--lane-use", "roundabout"]) == 2
    assert "roundabout" in capsys.readouterr().err


def test_intersection_sweep_on_ray_backend(tmp_path):
    import csv

    import pytest

    pytest.importorskip("ray")
    from icv_envs.experiments.intersection_compare import compare_intersection

    compare_intersection(["fcfs"], [1000.0], 2, 20.0, tmp_path, backend="ray", progress=False)
    rows = list(csv.DictReader(open(tmp_path / "results.csv")))
    assert [r["seed"] for r in rows] == ["0", "1"] and all(r["collisions"] == "0" for r in rows)


def test_capacity_uses_the_served_share_of_the_realised_demand():
    """Seed 0 at 1000 veh/h draws 864 veh/h of arrivals: against the nominal
    demand every method 'failed' there; against what arrived it is served."""
    from icv_envs.experiments.intersection_compare import capacity

    rows = [{"throughput": 1000.0, "achieved_throughput": 864.0, "served_share": 1.0},
            {"throughput": 2000.0, "achieved_throughput": 1950.0, "served_share": 0.99},
            {"throughput": 3000.0, "achieved_throughput": 2500.0, "served_share": 0.85}]
    assert capacity(rows) == {"capacity": 2000.0, "saturated_at": 3000.0, "max_achieved": 2500.0}
    # rows without served_share (older runs): achieved over nominal, as before
    old = [{k: v for k, v in r.items() if k != "served_share"} for r in rows]
    assert capacity(old)["capacity"] is None and capacity(old)["saturated_at"] == 1000.0


def test_served_share_is_one_when_everything_arriving_clears():
    from icv_envs.experiments.intersection_compare import run_intersection

    r = run_intersection("fcfs", 1000.0, 0, 300.0, {"warmup": 100.0})
    assert r["served_share"] == pytest.approx(1.0, abs=0.05)
    assert r["realised_demand"] == pytest.approx(r["achieved_throughput"], rel=0.05)


def test_plot_title_says_how_many_seeds_each_point_has():
    from icv_envs.experiments.intersection_compare import _seed_label

    full = [{"method": "fcfs", "throughput": v, "seed": s} for v in (1000, 2000) for s in range(3)]
    assert _seed_label(full, "mean_speed") == "3 seeds per point, band: 95% CI over seeds"
    assert _seed_label(full, "pet_min") == "3 seeds per point"
    ragged = full + [{"method": "fcfs", "throughput": 3000, "seed": 0}]
    assert _seed_label(ragged, "mean_speed").startswith("1-3 seeds per point")
    assert _seed_label(full[:1], "mean_speed") == "1 seed per point"
