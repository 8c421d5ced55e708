"""highway-env's viewer with the formation and a legend drawn on top.

:class:`FormationViewer` is highway-env's :class:`EnvViewer` that

1. draws every formation's targets (outlined boxes) and the assignment (a
   line from each member to its target) when ``config["show_formation"]`` is
   set;
2. draws an overlay when ``config["show_overlay"]`` is set (the default): the
   env and its scenario (or method and demand) in the top-left corner, the
   simulated time and vehicle count under it, and a legend of every colour
   and mark on the frame along the bottom edge;
3. keeps drawing when ``SDL_VIDEODRIVER=dummy`` is set for off-screen
   ``rgb_array`` rendering (highway-env's viewer turns itself off there and
   returns all-black frames).

The overlay helpers (:func:`draw_title`, :func:`draw_legend`,
:func:`draw_vehicle_markers`) are shared with the intersection's viewer
(``icv_envs.envs.intersection_viewer.viewer_class``). What every colour means is
listed in ``docs/rendering.md``.
4. leaves the process's SIGTERM/SIGINT handling alone: SDL's initialisation
   (``pygame.init()``) installs its own handlers, which turn SIGTERM into a
   queued quit event nobody reads, so a process that rendered once ignored
   ``kill``/``timeout``/pool shutdowns. The handlers in place before are
   restored right after pygame's initialisation (:func:`keep_signal_handlers`).
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

__all__ = ["FormationViewer", "keep_signal_handlers", "font", "draw_title", "draw_legend", "draw_vehicle_markers", "FORMATION_PALETTE"]

#: colours of formations 0, 1, ... on the highway envs (cycled); the env's
#: ``_sync_render_road`` uses the same list.
FORMATION_PALETTE = [(100, 200, 255), (255, 150, 50), (200, 100, 255), (255, 220, 50), (50, 220, 200)]
FREE = (200, 200, 200)
EGO = (50, 200, 0)
CRASHED = (255, 100, 100)
TARGET = (255, 255, 255)
ASSIGNMENT = (255, 200, 0)

_FONTS: dict[int, pygame.font.Font] = {}


def font(size: int) -> pygame.font.Font:
    """pygame's default font at ``size`` px, cached."""
    if not pygame.font.get_init():
        pygame.font.init()
    f = _FONTS.get(size)
    if f is None:
        f = _FONTS[size] = pygame.font.Font(None, size)
    return f


def _panel(surface: pygame.Surface, rect: pygame.Rect, alpha: int = 170) -> None:
    """A translucent dark box behind text, so it reads on road and grass."""
    box = pygame.Surface(rect.size, pygame.SRCALPHA)
    box.fill((20, 20, 20, alpha))
    surface.blit(box, rect.topleft)


def draw_title(surface: pygame.Surface, lines: list[str], pos=(6, 6), size: int = 20) -> pygame.Rect:
    """Draw ``lines`` (first line bold-ish and larger) on a dark panel at
    ``pos`` (top-left); returns the panel's rect."""
    fonts = [font(size + 2)] + [font(size)] * (len(lines) - 1)
    imgs = [f.render(t, True, (255, 255, 255)) for f, t in zip(fonts, lines)]
    w = max(i.get_width() for i in imgs) + 10
    h = sum(i.get_height() for i in imgs) + 4 * len(imgs) + 4
    rect = pygame.Rect(pos, (w, h))
    _panel(surface, rect)
    y = pos[1] + 4
    for img in imgs:
        surface.blit(img, (pos[0] + 5, y))
        y += img.get_height() + 4
    return rect


def draw_legend(surface: pygame.Surface, items: list[tuple], pos=None, size: int = 16,
                max_width: int | None = None) -> pygame.Rect:
    """Draw a legend of ``(label, colour, kind)`` items, ``kind`` one of
    ``"box"`` (filled vehicle), ``"outline"`` (target box), ``"line"``,
    ``"circle"`` (zone boundary) or ``"swatches"`` (``colour`` is a list: one
    box per colour). Items flow left to right and wrap at ``max_width``
    (default: the surface width - 12). ``pos`` is the top-left corner; None
    puts the legend at the bottom-left. Returns the panel's rect."""
    fnt = font(size)
    max_width = max_width or surface.get_width() - 12
    sw, gap, pad = 14, 12, 5
    entries = []
    for label, colour, kind in items:
        img = fnt.render(label, True, (255, 255, 255))
        n_sw = len(colour) if kind == "swatches" else 1
        entries.append((img, colour, kind, n_sw * (sw + 2) + 4 + img.get_width()))
    rows, row, width = [], [], 0
    for e in entries:
        if row and width + e[3] > max_width - 2 * pad:
            rows.append(row)
            row, width = [], 0
        row.append(e)
        width += e[3] + gap
    if row:
        rows.append(row)
    line_h = max(sw, fnt.get_height()) + 4
    w = min(max_width, max(sum(e[3] + gap for e in r) - gap for r in rows) + 2 * pad)
    h = line_h * len(rows) + 2 * pad - 4
    if pos is None:
        pos = (6, surface.get_height() - h - 6)
    rect = pygame.Rect(pos, (w, h))
    _panel(surface, rect)
    y = pos[1] + pad
    for r in rows:
        x = pos[0] + pad
        for img, colour, kind, ew in r:
            cy = y + line_h // 2 - 2
            if kind == "swatches":
                for c in colour:
                    pygame.draw.rect(surface, c, pygame.Rect(x, cy - 4, sw, 8))
                    x += sw + 2
                x -= sw + 2
            elif kind == "box":
                pygame.draw.rect(surface, colour, pygame.Rect(x, cy - 4, sw, 8))
            elif kind == "outline":
                pygame.draw.rect(surface, colour, pygame.Rect(x, cy - 4, sw, 8), 1)
            elif kind == "line":
                pygame.draw.line(surface, colour, (x, cy), (x + sw, cy), 2)
            elif kind == "circle":
                pygame.draw.circle(surface, colour, (x + sw // 2, cy), 6, 1)
            x += sw + 4
            surface.blit(img, (x, cy - img.get_height() // 2))
            x += img.get_width() + gap
        y += line_h
    return rect


def draw_vehicle_markers(wsurf, vehicles, min_length_px: float = 7.0, min_width_px: float = 4.0) -> None:
    """Draw every vehicle as a rotated box in its colour, at least
    ``min_length_px`` x ``min_width_px`` pixels (its true size when that is
    larger), with a dark outline: a view zoomed out to the whole scene still
    shows every vehicle. ``wsurf`` is a highway-env ``WorldSurface``;
    vehicles have ``position``, ``heading``, ``LENGTH``, ``WIDTH``, ``color``."""
    if not vehicles:
        return
    s = float(wsurf.scaling)
    pos = np.array([v.position for v in vehicles], dtype=float)
    h = np.array([v.heading for v in vehicles], dtype=float)
    half_l = 0.5 * np.maximum([v.LENGTH for v in vehicles], min_length_px / s)
    half_w = 0.5 * np.maximum([v.WIDTH for v in vehicles], min_width_px / s)
    c, sn = np.cos(h), np.sin(h)
    corners = []
    for dl, dw in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
        corners.append(pos + np.stack([dl * half_l * c - dw * half_w * sn, dl * half_l * sn + dw * half_w * c], axis=1))
    corners = np.stack(corners, axis=1)  # (N, 4, 2) world
    pix = (corners - np.asarray(wsurf.origin, dtype=float)) * s
    w_px, h_px = wsurf.get_width(), wsurf.get_height()
    for k, v in enumerate(vehicles):
        pts = pix[k]
        if pts[:, 0].max() < 0 or pts[:, 1].max() < 0 or pts[:, 0].min() > w_px or pts[:, 1].min() > h_px:
            continue
        col = v.color or FREE
        poly = [(float(x), float(y)) for x, y in pts]
        pygame.draw.polygon(wsurf, col, poly)
        pygame.draw.polygon(wsurf, (30, 30, 30), poly, 1)


def _sim_time(env) -> float:
    w = getattr(env, "world", None)
    return float(getattr(w, "time", getattr(env, "time", 0.0)) or 0.0)


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
        _FONTS.clear()  # fonts made before a pygame.quit() (env.close()) are invalid
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
        if env.config.get("show_overlay", True):
            self._draw_overlay()
        if not self.offscreen:
            self.screen.blit(self.sim_surface, (0, 0))
            if env.config["real_time_rendering"]:
                self.clock.tick(env.config["simulation_frequency"])
            pygame.display.flip()

    # ------------------------------------------------------------- overlay
    def title_lines(self) -> list[str]:
        """Env and scenario (or method and demand), then time and counts."""
        env, c = self.env, self.env.config
        if "vgr" in c:  # HighwayRamps
            head = f"HighwayRamps-v0 | method {c['method']} | VGR {float(c['vgr']):.3g} veh/s per on-ramp"
        else:
            head = f"HighwayFormation-v0 | scenario {c.get('scenario', 'free')}"
        w = env.world
        n = int(w.traffic.n)
        groups = int(len(np.unique(w.traffic.group[w.traffic.group >= 0]))) if n else 0
        x = float(self.window_position()[0])
        where = f" | view x = {x:,.0f} m"
        return [head, f"t = {_sim_time(env):6.1f} s | {n} vehicles | {groups} formations{where}"]

    def legend_items(self) -> list[tuple]:
        items = [("formation members (one colour per formation)", FORMATION_PALETTE, "swatches"),
                 ("free vehicle", FREE, "box")]
        if not getattr(self.env, "_ma_mode", True):
            items.append(("learned ego", EGO, "box"))
        items.append(("crashed", CRASHED, "box"))
        if self.env.config.get("show_formation", True):
            items += [("target", TARGET, "outline"), ("member -> target", ASSIGNMENT, "line")]
        return items

    def _draw_overlay(self) -> None:
        draw_title(self.sim_surface, self.title_lines())
        draw_legend(self.sim_surface, self.legend_items())

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
            pygame.draw.rect(surf, TARGET, rect, 1)
            pygame.draw.line(surf, ASSIGNMENT, surf.pos2pix(cx[i], cy[i]), surf.pos2pix(tx, ty), 1)

    def window_position(self) -> np.ndarray:
        ego = self.env.vehicle
        if ego is not None:
            return np.array([ego.position[0], self.env.world.road.total_lanes * self.env.world.road.lane_width / 2 - 2.0])
        return np.array([0.0, 0.0])
