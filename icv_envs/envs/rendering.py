"""highway-env's viewer with the formation drawn on top.

:class:`FormationViewer` is highway-env's :class:`EnvViewer` that (1) also
draws every formation's targets (outlined boxes) and the assignment (a line
from each member to its target) when ``config["show_formation"]`` is set, and
(2) keeps drawing when ``SDL_VIDEODRIVER=dummy`` is set for off-screen
``rgb_array`` rendering (highway-env's viewer turns itself off there and
returns all-black frames), and (3) leaves the process's SIGTERM/SIGINT
handling alone: SDL's initialisation (``pygame.init()``) installs its own
handlers, which turn SIGTERM into a queued quit event nobody reads, so a
process that rendered once ignored ``kill``/``timeout``/pool shutdowns. The
handlers in place before are restored right after pygame's initialisation.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading

import numpy as np
import pygame
from highway_env.envs.common.graphics import EnvViewer
from highway_env.road.graphics import RoadGraphics

__all__ = ["FormationViewer", "keep_signal_handlers"]

_SIGNALS = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGINT", "SIGHUP", "SIGQUIT") if hasattr(signal, n))


@contextlib.contextmanager
def keep_signal_handlers():
    """Restore the signal handlers of SIGTERM, SIGINT (and SIGHUP/SIGQUIT)
    after the block (SDL replaces them when pygame initialises)."""
    main = threading.current_thread() is threading.main_thread()
    saved = {s: signal.getsignal(s) for s in _SIGNALS} if main else {}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            if handler is not None:  # None: installed outside Python, cannot be restored
                signal.signal(sig, handler)


class FormationViewer(EnvViewer):
    def __init__(self, env, config=None) -> None:
        cfg = config or env.config
        if cfg.get("offscreen_rendering") and not os.environ.get("DISPLAY"):
            # no screen: render with SDL's dummy video driver (our display()
            # draws regardless, so frames are not black)
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        with keep_signal_handlers():
            super().__init__(env, config)
        if self.offscreen:
            self.enabled = True

    def display(self) -> None:
        if not self.enabled:
            return
        env = self.env
        self.sim_surface.move_display_window_to(self.window_position())
        RoadGraphics.display(env.road, self.sim_surface)
        RoadGraphics.display_road_objects(env.road, self.sim_surface, offscreen=self.offscreen)
        if env.config.get("show_formation", True):
            self._draw_formation()
        RoadGraphics.display_traffic(
            env.road, self.sim_surface, simulation_frequency=env.config["simulation_frequency"], offscreen=self.offscreen
        )
        if not self.offscreen:
            self.screen.blit(self.sim_surface, (0, 0))
            if env.config["real_time_rendering"]:
                self.clock.tick(env.config["simulation_frequency"])
            pygame.display.flip()

    def _draw_formation(self) -> None:
        env = self.env
        w = env.world
        tr = w.traffic
        if not tr.n:
            return
        surf = self.sim_surface
        x_ref, lane_ref, _, member = w.manager.references(tr)
        cx, cy = tr.center()
        W = w.road.lane_width
        for i in np.flatnonzero(member):
            tx, ty = x_ref[i], lane_ref[i] * W
            if not surf.is_visible((tx, ty), margin=50):
                continue
            L, Wd = tr.length[i], tr.width[i]
            rect = pygame.Rect(surf.pos2pix(tx - L / 2, ty - Wd / 2), (surf.pix(L), surf.pix(Wd)))
            pygame.draw.rect(surf, (255, 255, 255), rect, 1)
            pygame.draw.line(surf, (255, 200, 0), surf.pos2pix(cx[i], cy[i]), surf.pos2pix(tx, ty), 1)

    def window_position(self) -> np.ndarray:
        ego = self.env.vehicle
        if ego is not None:
            return np.array([ego.position[0], self.env.world.road.total_lanes * self.env.world.road.lane_width / 2 - 2.0])
        return np.array([0.0, 0.0])
