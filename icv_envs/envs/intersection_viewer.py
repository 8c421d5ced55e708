"""The intersection's viewer: highway-env's viewer (through
:class:`~icv_envs.envs.rendering.FormationViewer`) drawing the scene of
:class:`~icv_envs.envs.intersection.IntersectionEnv` (zones, lanes, stop
lines, tree-layer colours, an inset of the box, the overlay and legend).
Only rendering imports this module (and pygame)."""

from __future__ import annotations

import numpy as np

__all__ = ["viewer_class"]

_VIEWER_CLASS = None


def viewer_class():
    """highway-env's viewer (via :class:`~icv_envs.envs.rendering.FormationViewer`,
    which keeps drawing off-screen) drawing the intersection.

    The main view shows the whole scene out to ``R3`` (default ``scaling``
    0.54 px/m on 900 px): grass, the legs and the box, lane lines
    (highway-env's lane graphics), stop lines, the zone circles ``R1``
    (coordinating), ``R2`` (adjusting) and ``R3`` (generation), and every
    vehicle as a box at least 7 x 4 px (at 0.54 px/m a car is 3 px long)
    coloured by its state: by tree-layer in a virtual-platoon node (fcfs:
    light green with a reservation; light blue: in regrouping or waiting;
    grey: approaching or past the box; green: the Gymnasium ego; red:
    crashed); a line through the members of every group (nodes in their
    layer's colour, sub-formations in white) and a ``T<layer>`` label at
    every node's first vehicle. An inset (bottom right) shows the box and
    +-60 m around it at true size (2.5 px/m). With ``show_overlay`` the
    frame also carries the method, demand and lane use, the simulated time
    and vehicle count, and a legend. The static background (roads, lane
    lines, circles) is drawn once per layout and reused. Built lazily so
    that pygame is only imported to render."""
    global _VIEWER_CLASS
    if _VIEWER_CLASS is not None:
        return _VIEWER_CLASS
    import pygame
    from highway_env.road.graphics import LaneGraphics, RoadGraphics, WorldSurface

    from icv_envs.envs.rendering import FormationViewer, draw_legend, draw_title, draw_vehicle_markers, font

    class IntersectionViewer(FormationViewer):
        GRASS = (70, 110, 60)
        ROAD = (100, 100, 100)
        REGROUPING = (150, 200, 255)
        RESERVED = (120, 230, 90)
        APPROACHING = (200, 200, 200)
        ZONE_COLOURS = ((255, 220, 120), (160, 220, 255), (230, 230, 230))  # R1, R2, R3
        INSET_HALF = 60.0  # m around the centre shown in the inset
        INSET_PX = 300

        def window_position(self) -> np.ndarray:
            return np.array([0.0, 0.0])

        # ------------------------------------------------------ background
        def _background(self, surf, key) -> pygame.Surface:
            cache = self.__dict__.setdefault("_bg_cache", {})
            full_key = (key, id(self.env.layout), id(self.env.road.network), surf.get_size(), float(surf.scaling),
                        tuple(surf.origin), bool(self.env.config.get("show_zones", True)))
            bg = cache.get(key)
            if bg is not None and bg[0] == full_key:
                return bg[1]
            self._draw_static(surf)
            img = surf.copy()
            cache[key] = (full_key, img)
            return img

        def _draw_static(self, surf) -> None:
            env = self.env
            surf.fill(self.GRASS)
            lay = env.layout
            b, far = lay.box_half, lay.R3 + 20.0
            half = 3 * lay.lane_width
            for x0, y0, x1, y1 in ((-half, -far, half, far), (-far, -half, far, half), (-b, -b, b, b)):
                p0 = surf.pos2pix(x0, y0)
                p1 = surf.pos2pix(x1, y1)
                pygame.draw.rect(surf, self.ROAD, pygame.Rect(p0, (p1[0] - p0[0], p1[1] - p0[1])))
            for _from in env.road.network.graph:
                for _to in env.road.network.graph[_from]:
                    for lane in env.road.network.graph[_from][_to]:
                        LaneGraphics.display(lane, surf)
            for leg in range(4):  # stop lines
                o, r = lay.box_half * lay.out[leg], lay.app_right[leg]
                a, c = o, o + half * r
                pygame.draw.line(surf, (255, 255, 255), surf.pos2pix(a[0], -a[1]), surf.pos2pix(c[0], -c[1]),
                                 max(1, surf.pix(0.5)))
            if env.config.get("show_zones", True):
                centre = surf.pos2pix(0.0, 0.0)
                for R, col in zip((lay.R1, lay.R2, lay.R3), self.ZONE_COLOURS):
                    pygame.draw.circle(surf, col, centre, surf.pix(R), 1)

        # ------------------------------------------------------------ frame
        def display(self) -> None:
            if not self.enabled:
                return
            env = self.env
            surf = self.sim_surface
            surf.move_display_window_to(self.window_position())
            surf.blit(self._background(surf, "main"), (0, 0))
            if env.config.get("show_groups", True):
                self._draw_groups(surf, labels=True)
            draw_vehicle_markers(surf, env.road.vehicles)
            if env.config.get("show_overlay", True):
                self._draw_inset()
                draw_title(surf, self.title_lines())
                draw_legend(surf, self.legend_items(), max_width=surf.get_width() - self.INSET_PX - 24)
            if not self.offscreen:
                self.screen.blit(surf, (0, 0))
                if env.config["real_time_rendering"]:
                    self.clock.tick(env.config["simulation_frequency"])
                pygame.display.flip()

        def _draw_inset(self) -> None:
            """The box and +-INSET_HALF m around it at true vehicle size, bottom right."""
            main = self.sim_surface
            n = self.INSET_PX
            if getattr(self, "_inset", None) is None:
                self._inset = WorldSurface((n, n), 0, pygame.Surface((n, n)))
                self._inset.scaling = n / (2.0 * self.INSET_HALF)
                self._inset.centering_position = [0.5, 0.5]
            ins = self._inset
            ins.move_display_window_to(np.array([0.0, 0.0]))
            ins.blit(self._background(ins, "inset"), (0, 0))
            if self.env.config.get("show_groups", True):
                self._draw_groups(ins, labels=False)
            RoadGraphics.display_traffic(self.env.road, ins, simulation_frequency=self.env.config["simulation_frequency"],
                                         offscreen=True)
            ins.blit(font(16).render(f"box, +-{self.INSET_HALF:.0f} m, true size", True, (255, 255, 255)), (4, 4))
            x0, y0 = main.get_width() - n - 6, main.get_height() - n - 6
            main.blit(ins, (x0, y0))
            pygame.draw.rect(main, (255, 255, 255), pygame.Rect(x0 - 1, y0 - 1, n + 2, n + 2), 1)
            # where the inset is on the main view
            a = main.pos2pix(-self.INSET_HALF, -self.INSET_HALF)
            side = main.pix(2 * self.INSET_HALF)
            pygame.draw.rect(main, (255, 255, 255), pygame.Rect(a, (side, side)), 1)

        def title_lines(self) -> list[str]:
            env, c = self.env, self.env.config
            lu = c["lane_use"] if isinstance(c["lane_use"], str) else "custom"
            n = int(env.world.fleet.n)
            return [f"Intersection-v0 | method {c['method']} | {float(c['throughput']):g} veh/h | lane use {lu}",
                    f"t = {float(env.world.time):6.1f} s | {n} vehicles | view +-{env.layout.R3 + 33:.0f} m (R3 = "
                    f"{env.layout.R3:.0f} m)"]

        def legend_items(self) -> list[tuple]:
            env = self.env
            items = []
            if env.config["method"] == "fcfs":
                items.append(("holds a reservation", self.RESERVED, "box"))
            else:
                items.append(("node in tree-layer T1, T2, ...", env.LAYER_COLOURS[:4], "swatches"))
            items += [("regrouping / waiting", self.REGROUPING, "box"),
                      ("approaching / past the box", self.APPROACHING, "box")]
            if not env._ma_mode:
                items.append(("learned ego", (50, 200, 0), "box"))
            items.append(("crashed", (255, 60, 60), "box"))
            if env.config.get("show_groups", True):
                items.append(("sub-formation", (255, 255, 255), "line"))
            if env.config.get("show_zones", True):
                items += [("R1 coordinating", self.ZONE_COLOURS[0], "circle"), ("R2 adjusting", self.ZONE_COLOURS[1], "circle"),
                          ("R3 arrivals", self.ZONE_COLOURS[2], "circle")]
            return items

        def _draw_groups(self, surf, labels: bool = True) -> None:
            env = self.env
            w = env.world
            if not w.fleet.n:
                return
            rs = w.route()
            for kind, gid, rows, depth in env.expert.groups(w):
                rows = rows[rows >= 0]
                if not len(rows):
                    continue
                rows = rows[np.argsort(rs.dist[rows])]
                if kind == "node" and depth > 0:
                    col = env.LAYER_COLOURS[(depth - 1) % len(env.LAYER_COLOURS)]
                elif kind == "reserved":
                    col = self.RESERVED
                else:
                    col = (255, 255, 255)
                pts = [surf.pos2pix(rs.cx[r], -rs.cy[r]) for r in rows]
                if len(pts) > 1 and kind != "reserved":
                    pygame.draw.lines(surf, col, False, pts, 2)
                if labels and kind == "node":
                    label = font(18).render(f"T{depth}", True, col)
                    x, y = pts[0]
                    surf.blit(label, (x + 6, y - 14))

    _VIEWER_CLASS = IntersectionViewer
    return _VIEWER_CLASS
