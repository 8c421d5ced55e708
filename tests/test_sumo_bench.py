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
