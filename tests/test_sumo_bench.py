"""The SUMO ring of the speed comparison (optional extra 'bench') and the CLI
option that runs it. No wall-clock assertions."""

from __future__ import annotations

import pytest

from icv_envs.cli import main


def test_vs_sumo_only_for_highway_ramps(capsys):
    assert main(["bench", "intersection", "--vs-sumo"]) == 2
    assert "--vs-sumo is an option of 'bench highway-ramps', not of 'bench intersection'" in capsys.readouterr().err


def test_sumo_ring_holds_its_vehicles():
    pytest.importorskip("libsumo")
    pytest.importorskip("sumo")
    from icv_envs.experiments.sumo_ring import SumoRing

    ring = SumoRing(40)
    try:
        r = ring.step(25)
        assert r["vehicles"] == 40 and r["waiting"] == 0
        assert r["vehicle_steps"] == 40 * 25 and abs(r["sim_seconds"] - 1.0) < 1e-9
        speeds = [ring.traci.vehicle.getSpeed(v) for v in ring.traci.vehicle.getIDList()]
        assert min(speeds) > 15.0  # free flow at 40 vehicles on 40 lane-km
        lanes = {ring.traci.vehicle.getLaneIndex(v) for v in ring.traci.vehicle.getIDList()}
        assert lanes == {0, 1, 2, 3}
        assert abs(ring.traci.lane.getLength("e0_0") * 4 - 10_000.0) < 50.0  # the 10 km ring
    finally:
        ring.close()


def test_sumo_ring_bad_count():
    pytest.importorskip("libsumo")
    from icv_envs.experiments.sumo_ring import SumoRing

    with pytest.raises(ValueError, match="vehicles = 0"):
        SumoRing(0)


def test_ramps_vs_sumo_runs_end_to_end():
    """The whole --vs-sumo path on a short run (it once read a statistics key
    the world no longer had and failed after its warm-up)."""
    pytest.importorskip("libsumo")
    pytest.importorskip("sumo")
    from icv_envs.experiments.sumo_bench import ramps_vs_sumo

    res = ramps_vs_sumo(seconds=6.0, measure=2.0, chunks=2, sumo_warmup=1.0, echo=lambda s: None)
    assert res["bench"] == "highway-ramps-vs-sumo"
    assert res["icv_vehicle_steps_per_cpu_s"] > 0 and res["sumo_vehicle_steps_per_cpu_s"] > 0
    assert res["ratio_cpu"] == pytest.approx(res["icv_vehicle_steps_per_cpu_s"] / res["sumo_vehicle_steps_per_cpu_s"])
    # each pair of slices' own ratio (from stop 54): one per pair
    ch = res["ratio_cpu_chunks"]
    assert len(ch) == 2 and all(r > 0 for r in ch)
    assert res["ratio_cpu_chunks_median"] == pytest.approx(sum(ch) / 2)


def test_time_icv_formation_counts_vehicle_steps():
    from icv_envs.experiments.sumo_bench import time_icv_formation

    r = time_icv_formation(12, seconds=0.4, warmup=0.2)
    # 12 vehicles, 0.4 s at 25 Hz physics: 10 physics steps each
    assert r["vehicle_steps_per_s"] > 0 and r["ms_per_sim_s"] > 0


def test_highway_formation_bench_times_after_its_warmup():
    """``icv-envs bench highway-formation`` times ``seconds`` after an untimed
    warm-up (the first steps of a process load the compiled kernels; at 50
    vehicles they doubled the figure)."""
    from icv_envs.experiments.bench import time_icv

    r = time_icv(12, seconds=0.4, warmup=0.2)
    assert r["sim_seconds"] == pytest.approx(0.4, abs=1e-6)
    assert r["wall_per_sim_s"] > 0 and r["collisions"] == 0


def test_api_only_with_vs_sumo(capsys):
    assert main(["bench", "highway-ramps", "--api", "rows"]) == 2
    assert "--api rows is an option of 'bench highway-ramps --vs-sumo' and 'bench intersection'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # argparse's own error (exit 2) for an unknown choice
        main(["bench", "highway-ramps", "--vs-sumo", "--api", "arrays"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "'arrays'" in err and "dicts" in err and "rows" in err, err


def test_the_three_apis_drive_the_same_ring():
    """``--api dicts``, ``lean`` and ``rows`` step the same trajectory (the
    comparison with SUMO differs only in the API's cost)."""
    import numpy as np

    from icv_envs.envs.highway_ramps_v0 import parallel_env
    from icv_envs.experiments.sumo_bench import APIS, _icv_steps

    states = {}
    for api, cfg in APIS.items():
        env = parallel_env(vgr=1.0 / 3.0, duration=60.0, method="formation", **cfg)
        env.reset(seed=1)
        _icv_steps(env, 150, api)
        tr = env.core.world.traffic
        states[api] = (tr.vid.copy(), np.stack([tr.x, tr.y, tr.speed, tr.heading]), env.core.metrics())
    ref = states["dicts"]
    assert len(ref[0]) > 20
    for api, s in states.items():
        assert np.array_equal(s[0], ref[0]) and np.array_equal(s[1], ref[1]), api
        assert s[2] == ref[2], api


def test_ramps_vs_sumo_through_the_array_path():
    pytest.importorskip("libsumo")
    pytest.importorskip("sumo")
    from icv_envs.experiments.sumo_bench import ramps_vs_sumo

    res = ramps_vs_sumo(seconds=6.0, measure=2.0, chunks=2, sumo_warmup=1.0, api="rows", echo=lambda s: None)
    assert res["api"] == "rows" and res["icv_vehicle_steps_per_cpu_s"] > 0
    with pytest.raises(ValueError, match=r"api = 'x'; allowed: \['dicts', 'lean', 'rows'\]"):
        ramps_vs_sumo(seconds=6.0, measure=2.0, api="x")


def test_vs_sumo_too_short_names_the_cli_option(capsys):
    """``--seconds`` at most the timed 100 s: the error names ``--seconds``
    and the bound (stop 45: it named the internal ``measure`` only)."""
    pytest.importorskip("libsumo")
    pytest.importorskip("sumo")
    assert main(["bench", "highway-ramps", "--vs-sumo", "--seconds", "50"]) == 2
    assert "--seconds must exceed 100" in capsys.readouterr().err


def test_scaling_bad_input_names_the_value():
    from icv_envs.experiments.sumo_bench import scaling

    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "5"):
        with pytest.raises(ValueError, match=r"seconds = .*allowed: a finite number"):
            scaling([50], seconds=bad, echo=lambda s: None)
    for sizes in ([], [0], [50, -3], [2.5], [True]):
        with pytest.raises(ValueError, match=r"sizes = .*allowed: a non-empty list of vehicle counts"):
            scaling(sizes, seconds=1.0, echo=lambda s: None)
