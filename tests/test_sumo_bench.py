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
