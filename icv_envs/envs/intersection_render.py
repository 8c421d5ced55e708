"""The intersection env's bridge to highway-env's renderer (a mixin of
:class:`icv_envs.envs.intersection.IntersectionEnv`): highway-env vehicle
proxies synced from the fleet's arrays, and their colours by state (the
viewer itself: :mod:`icv_envs.envs.intersection_viewer`). Only rendering
calls these."""

from __future__ import annotations

import numpy as np

__all__ = ["IntersectionRendering"]


class IntersectionRendering:
    """Vehicle proxies and colours of :class:`~icv_envs.envs.intersection.IntersectionEnv` (module docstring)."""

    def _sync_render_road(self, force: bool = False) -> None:
        """Refresh highway-env objects (road network, vehicle views) from the arrays."""
        from highway_env.road.road import Road

        from icv_envs.sim.vehicle import ICVVehicle

        w = self.world
        if force or self.road is None or getattr(self, "_road_world", None) is not w:
            self.road = Road(network=self.layout.to_network(), np_random=self.np_random, record_history=False)
            self._road_world = w
            self._proxies = {}
        f = w.fleet
        rs = w.route()
        alive = set(int(v) for v in f.vid)
        for vid in list(self._proxies):
            if vid not in alive:
                del self._proxies[vid]
        colours = self._colours()
        vehicles = []
        for i, vid in enumerate(f.vid.tolist()):
            p = self._proxies.get(vid)
            if p is None:
                p = self._proxies[vid] = ICVVehicle.proxy(self.road, vid, f.length[i], f.width[i])
            p.position = np.array([rs.cx[i], -rs.cy[i]])  # highway-env's screen frame: y down
            p.heading = float(-f.heading[i])
            p.speed = float(f.speed[i])
            p.crashed = bool(f.crashed[i])
            p.action = {"steering": float(-f.steer[i]), "acceleration": float(f.accel[i])}
            p.color = colours[i]
            vehicles.append(p)
        self.road.vehicles = vehicles
        ego = self._proxies.get(self._ego_vid)
        self.controlled_vehicles = [ego] if ego is not None else []

    #: colours of tree-layers 1, 2, ... (cycled)
    LAYER_COLOURS = [(255, 200, 0), (0, 190, 255), (255, 90, 200), (120, 230, 90), (255, 140, 40), (170, 120, 255)]

    def _colours(self) -> list:
        f = self.world.fleet
        cols = [(200, 200, 200)] * f.n
        stage = getattr(f, "stage", np.zeros(f.n, dtype=np.int64))
        node = getattr(f, "node", np.full(f.n, -1))
        depth = self.expert.node_depth if self.expert is not None else {}
        reserved = set(getattr(self.expert, "plans", {}))
        for i in range(f.n):
            if f.crashed[i]:
                cols[i] = (255, 60, 60)
            elif not self._ma_mode and int(f.vid[i]) == self._ego_vid:
                cols[i] = (50, 200, 0)
            elif int(f.vid[i]) in reserved:
                cols[i] = (120, 230, 90)
            elif node[i] >= 0 and depth.get(int(node[i]), 0) > 0:
                cols[i] = self.LAYER_COLOURS[(depth[int(node[i])] - 1) % len(self.LAYER_COLOURS)]
            elif stage[i] >= 1 and not f.cleared[i]:
                cols[i] = (150, 200, 255)
        return cols
