"""The same ring in SUMO, for the speed comparison of ``icv-envs bench
highway-ramps --vs-sumo`` and the scaling curve (optional ``bench`` extra:
``eclipse-sumo`` and ``libsumo``).

The net: a circle of circumference ``length`` (10 km, the paper's ring)
with ``lanes`` main lanes (4) of 4 m, built with SUMO's own ``netconvert``
from four nodes and four arc-shaped edges (no junction logic: the nodes
are plain continuations). Vehicles: SUMO's defaults for the models a
traffic engineer would use on a freeway, Krauss car following and LC2013
lane changing, 5 m long, ``accel = 3``, ``decel = 6`` m/s^2 (the paper's
Sec. 2.2 limits, as in this package), desired speed 25 m/s (Table 1);
time step 0.04 s (this package's physics step, 25 Hz). They are inserted
evenly spaced over the lanes, front first, each at the largest speed that
is safe behind the one ahead (``departSpeed="max"``; at the densest
settings a few wait a step or two at the lap's seam) and circle on a route that repeats
the ring's four edges (enough laps for any run here).

Only stepping is timed (``libsumo.simulationStep``); building the net and
inserting vehicles are not. Vehicle-steps are counted from SUMO's own
vehicle count after each step.
"""

from __future__ import annotations

import math
import os
import subprocess
import tempfile
import time
from pathlib import Path

__all__ = ["SumoRing", "sumo_available"]


def sumo_available() -> bool:
    try:
        import libsumo  # noqa: F401
        import sumo  # noqa: F401
    except ImportError:
        return False
    return True


def _write_net(directory: Path, length: float, lanes: int, lane_width: float, speed_limit: float) -> Path:
    import sumo

    r = length / (2.0 * math.pi)
    nodes, edges = [], []
    for k in range(4):
        ang = 0.5 * math.pi * k
        nodes.append(f'<node id="n{k}" x="{r * math.cos(ang):.3f}" y="{r * math.sin(ang):.3f}" type="priority"/>')
    for k in range(4):
        a0, a1 = 0.5 * math.pi * k, 0.5 * math.pi * (k + 1)
        pts = " ".join(f"{r * math.cos(a0 + (a1 - a0) * t / 40):.3f},{r * math.sin(a0 + (a1 - a0) * t / 40):.3f}"
                       for t in range(41))
        edges.append(f'<edge id="e{k}" from="n{k}" to="n{(k + 1) % 4}" numLanes="{lanes}" speed="{speed_limit}" '
                     f'width="{lane_width}" shape="{pts}"/>')
    (directory / "ring.nod.xml").write_text("<nodes>\n" + "\n".join(nodes) + "\n</nodes>\n")
    (directory / "ring.edg.xml").write_text("<edges>\n" + "\n".join(edges) + "\n</edges>\n")
    net = directory / "ring.net.xml"
    exe = os.path.join(sumo.SUMO_HOME, "bin", "netconvert")
    subprocess.run([exe, "-n", str(directory / "ring.nod.xml"), "-e", str(directory / "ring.edg.xml"),
                    "-o", str(net), "--no-turnarounds", "true", "--no-warnings", "true"],
                   check=True, capture_output=True)
    return net


class SumoRing:
    """A running SUMO (libsumo, in this process) on the ring with ``vehicles``
    vehicles. One instance at a time (libsumo holds one simulation)."""

    def __init__(self, vehicles: int, *, length: float = 10_000.0, lanes: int = 4, lane_width: float = 4.0,
                 dt: float = 0.04, desired_speed: float = 25.0, seed: int = 0) -> None:
        import libsumo

        if not (isinstance(vehicles, int) and vehicles >= 1):
            raise ValueError(f"vehicles = {vehicles!r}; allowed: an integer >= 1")
        self.traci = libsumo
        self._tmp = tempfile.TemporaryDirectory(prefix="icv_sumo_ring_")
        d = Path(self._tmp.name)
        net = _write_net(d, length, lanes, lane_width, speed_limit=30.0)
        (d / "ring.rou.xml").write_text(
            "<routes>\n"
            f'<vType id="car" carFollowModel="Krauss" laneChangeModel="LC2013" length="5" width="2" minGap="2.5" '
            f'accel="3" decel="6" emergencyDecel="9" maxSpeed="{desired_speed}" speedFactor="1" speedDev="0"/>\n'
            + "".join(f'<route id="loop{k}" edges="{" ".join([f"e{(k + j) % 4}" for j in range(4)] * 20)}"/>\n'
                      for k in range(4))
            + "</routes>\n")
        libsumo.start(["sumo", "-n", str(net), "-r", str(d / "ring.rou.xml"), "--step-length", str(dt),
                       "--no-step-log", "true", "--no-warnings", "true", "--seed", str(seed),
                       "--collision.action", "warn", "--time-to-teleport", "-1"])
        self.dt = float(dt)
        # evenly spaced over the ring and its lanes
        per_lane = math.ceil(vehicles / lanes)
        edge_len = libsumo.lane.getLength("e0_0")
        spacing = 4.0 * edge_len / per_lane
        for i in reversed(range(vehicles)):  # front first: each insertion is behind the last (speed 'max' = safe)
            lane, k = i % lanes, i // lanes
            s = (k * spacing + (0.25 + 0.5 * (lane % 2)) * spacing) % (4.0 * edge_len)  # never on an edge end
            e = int(s // edge_len)
            libsumo.vehicle.add(f"v{i}", f"loop{e}", typeID="car", departLane=str(lane),
                                departPos=f"{s - e * edge_len:.2f}", departSpeed="max")
        self.traci.simulationStep()  # insertion
        self.vehicles = vehicles

    def step(self, steps: int) -> dict:
        """Advance ``steps`` time steps; wall time and vehicle-steps."""
        sim = self.traci.simulation
        vs = 0
        t0 = time.perf_counter()
        c0 = time.process_time()
        for _ in range(steps):
            self.traci.simulationStep()
            vs += self.traci.vehicle.getIDCount()
        return {"wall": time.perf_counter() - t0, "cpu": time.process_time() - c0, "vehicle_steps": vs,
                "sim_seconds": steps * self.dt, "vehicles": self.traci.vehicle.getIDCount(),
                "waiting": sim.getMinExpectedNumber() - self.traci.vehicle.getIDCount()}

    def close(self) -> None:
        self.traci.close()
        self._tmp.cleanup()
