"""Tile reservation, first come first served (Dresner & Stone's AIM; docs/intersection.md#reference-methods).

The reference method of the paper's comparison (Sec. 6): the box
``|x|, |y| <= box_half`` is a grid of square tiles; a vehicle asks for the
tiles its buffered footprint covers along its path at every time step of its
crossing; a request is granted only if none of those tiles is held by another
vehicle at that step or within ``time_buffer`` steps of it, and requests are
answered in call order.  A rejected vehicle slows down and asks again.

Tiles: ``n_side = ceil(2 box_half / tile)`` per side; tile ``(col, row)``
covers ``x in [-box_half + col tile, -box_half + (col + 1) tile]`` and the
same for ``y`` with ``row``; its id is ``row * n_side + col`` (row 0 south,
col 0 west).  Time is integer steps of ``dt`` seconds.

Everything is pure numpy / Python and deterministic: no clocks, no
randomness, iteration in insertion or sorted order.
"""

from __future__ import annotations

import math
import numbers
import operator

import numpy as np

from ..formation._validate import finite
from ._kernels import atan2_rows
from .geometry import DEFAULT_BOX_HALF

__all__ = [
    "DEFAULT_TILE",
    "DEFAULT_DT",
    "DEFAULT_TIME_BUFFER",
    "DEFAULT_SPACE_BUFFER",
    "DEFAULT_VEHICLE_LENGTH",
    "DEFAULT_VEHICLE_WIDTH",
    "tile_grid",
    "tile_of_point",
    "footprint_mask",
    "footprint_tiles",
    "ReservationTable",
    "simulate_path_occupancy",
]

#: Tile side in metres ("about 1 m", docs/methods.md#fcfs).
DEFAULT_TILE: float = 1.0
#: Simulation step in seconds (paper Table 2).
DEFAULT_DT: float = 0.04
#: Time buffer in steps either side of every requested step: 5 x 0.04 s = 0.2 s.
DEFAULT_TIME_BUFFER: int = 5
#: Static spatial buffer added on every side of the vehicle rectangle (metres).
DEFAULT_SPACE_BUFFER: float = 0.5
#: Vehicle rectangle used by :func:`simulate_path_occupancy` (highway-env's 5 x 2 m).
DEFAULT_VEHICLE_LENGTH: float = 5.0
DEFAULT_VEHICLE_WIDTH: float = 2.0

_EPS = 1e-9
_DTYPE = operator.attrgetter("dtype")
_INT64_ONLY = {np.dtype(np.int64)}  # (ReservationTable._sorted_tiles' dtypes)


def _pos(name: str, value, allow_zero: bool = False) -> float:
    ok = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    v = float(value) if ok else math.nan
    if not ok or not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        rel = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be a finite real number {rel}, got {value!r}")
    return v


def _int(name: str, value, minimum: int | None = None) -> int:
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be an integer, got {value!r} (a bool)")
    try:
        i = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer, got {value!r}") from None
    if minimum is not None and i < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(i)


def tile_grid(tile: float = DEFAULT_TILE, box_half: float = DEFAULT_BOX_HALF) -> tuple[int, np.ndarray]:
    """``(n_side, centres)``: tiles per side and the ``(n_side**2, 2)`` tile centres by id."""
    t = _pos("tile", tile)
    b = _pos("box_half", box_half)
    n = int(math.ceil(2 * b / t - _EPS))
    c = -b + (np.arange(n) + 0.5) * t
    xx, yy = np.meshgrid(c, c)  # row index = y, col index = x
    return n, np.column_stack([xx.ravel(), yy.ravel()])


def tile_of_point(xy, tile: float = DEFAULT_TILE, box_half: float = DEFAULT_BOX_HALF) -> np.ndarray:
    """Id of the tile containing each point ``(..., 2)``; -1 outside the box.

    A point on a tile border gets the tile to its north-east (the last tile
    keeps the box's east / north edge).
    """
    n, _ = tile_grid(tile, box_half)
    p = finite("xy", xy)
    if p.shape[-1:] != (2,):
        raise ValueError(f"xy must have shape (..., 2), got {p.shape}")
    t, b = float(tile), float(box_half)
    col = np.floor((p[..., 0] + b) / t).astype(np.int64)
    row = np.floor((p[..., 1] + b) / t).astype(np.int64)
    inside = (np.abs(p[..., 0]) <= b) & (np.abs(p[..., 1]) <= b)
    col = np.clip(col, 0, n - 1)
    row = np.clip(row, 0, n - 1)
    return np.where(inside, row * n + col, -1)


def footprint_mask(center_xy, heading, length: float, width: float,
                   buffer: float = DEFAULT_SPACE_BUFFER, tile: float = DEFAULT_TILE,
                   box_half: float = DEFAULT_BOX_HALF) -> np.ndarray:
    """Tiles touched by buffered rectangles, as a bool ``(k, n_tiles)`` mask.

    Rectangle ``i`` is centred at ``center_xy[i]``, its long side along
    ``heading[i]`` (radians), of size ``(length + 2 buffer) x (width + 2
    buffer)``.  Exact separating-axis test of rectangle vs. tile on the four
    axes (x, y, heading and its normal), with closed intervals and a 1e-9 m
    slack: a tile that merely touches the rectangle counts (conservative).
    Vectorised over poses and tiles; tiles exist only inside the box.
    """
    c = finite("center_xy", center_xy)
    h = finite("heading", heading)
    if c.ndim == 1:
        c = c[None]
    if c.ndim != 2 or c.shape[1] != 2:
        raise ValueError(f"center_xy must have shape (k, 2) or (2,), got {np.shape(center_xy)}")
    h = np.broadcast_to(h, (c.shape[0],)) if h.ndim == 0 else h
    if h.shape != (c.shape[0],):
        raise ValueError(f"heading must have shape ({c.shape[0]},), got {h.shape}")
    hl = 0.5 * _pos("length", length) + _pos("buffer", buffer, allow_zero=True)
    hw = 0.5 * _pos("width", width) + float(buffer)
    _, centres = tile_grid(tile, box_half)
    half = 0.5 * float(tile)
    co, si = np.abs(np.cos(h))[:, None], np.abs(np.sin(h))[:, None]
    dx = centres[None, :, 0] - c[:, 0, None]
    dy = centres[None, :, 1] - c[:, 1, None]
    ex = hl * co + hw * si
    ey = hl * si + hw * co
    ok = (np.abs(dx) <= half + ex + _EPS) & (np.abs(dy) <= half + ey + _EPS)
    u = dx * np.cos(h)[:, None] + dy * np.sin(h)[:, None]
    v = -dx * np.sin(h)[:, None] + dy * np.cos(h)[:, None]
    tile_r = half * (co + si)
    ok &= (np.abs(u) <= hl + tile_r + _EPS) & (np.abs(v) <= hw + tile_r + _EPS)
    return ok


def footprint_tiles(center_xy, heading, length: float, width: float,
                    buffer: float = DEFAULT_SPACE_BUFFER, tile: float = DEFAULT_TILE,
                    box_half: float = DEFAULT_BOX_HALF):
    """Sorted int64 tile ids touched by each buffered rectangle.

    Same arguments as :func:`footprint_mask`.  Returns one array for a single
    pose (``center_xy`` of shape ``(2,)``), else a list of ``k`` arrays.
    """
    single = np.ndim(center_xy) == 1
    mask = footprint_mask(center_xy, heading, length, width, buffer, tile, box_half)
    out = [np.flatnonzero(row) for row in mask]
    return out[0] if single else out


class ReservationTable:
    """Time-indexed tile reservations, first come first served (AIM).

    Storage: ``{step: int array (n_tiles,) of holder slot, -1 = free}`` for the
    steps that have reservations, plus the steps each vehicle holds.  A
    vehicle holds at most one reservation: a granted request replaces its
    previous one; a rejected request leaves it untouched.

    Args:
        tile: tile side (metres).
        box_half: half side of the box (metres).
        dt: seconds per step (kept for conversions; the table is step-indexed).
        time_buffer: steps either side of each requested step that must also
            be free of other vehicles on the requested tiles (>= 0).
    """

    def __init__(self, tile: float = DEFAULT_TILE, box_half: float = DEFAULT_BOX_HALF,
                 dt: float = DEFAULT_DT, time_buffer: int = DEFAULT_TIME_BUFFER):
        self.tile = _pos("tile", tile)
        self.box_half = _pos("box_half", box_half)
        self.dt = _pos("dt", dt)
        self.time_buffer = _int("time_buffer", time_buffer, 0)
        self.n_side, self.centres = tile_grid(self.tile, self.box_half)
        self.n_tiles = self.n_side * self.n_side
        self.now = 0
        self._occ: dict[int, np.ndarray] = {}
        self._slot: dict = {}  # vehicle id -> int slot
        self._ids: list = []  # slot -> vehicle id
        self._held: dict = {}  # vehicle id -> sorted list of steps it holds

    # ---------------------------------------------------------------- helpers
    def _slot_of(self, vehicle_id) -> int:
        if vehicle_id not in self._slot:
            self._slot[vehicle_id] = len(self._ids)
            self._ids.append(vehicle_id)
        return self._slot[vehicle_id]

    def _check_request(self, time_steps, tiles_per_step):
        steps = np.asarray(time_steps)
        if steps.ndim != 1 or (steps.size and not np.issubdtype(steps.dtype, np.integer)):
            raise ValueError(f"time_steps must be a 1-D array of integer steps, got {time_steps!r}")
        steps = steps.astype(np.int64)
        if len(tiles_per_step) != steps.size:
            raise ValueError(
                f"tiles_per_step must hold one tile array per time step: got "
                f"{len(tiles_per_step)} for {steps.size} steps"
            )
        if steps.size and steps.min() < self.now:
            raise ValueError(f"time_steps must be >= now = {self.now}, got step {int(steps.min())}")
        if np.unique(steps).size != steps.size:
            raise ValueError(f"time_steps must be distinct, got {steps.tolist()}")
        arrs = [np.asarray(t) for t in tiles_per_step]
        fast = self._sorted_tiles(arrs)
        if fast is not None:
            return steps, fast
        tiles = []
        for a in arrs:
            if a.size == 0:
                tiles.append(np.zeros(0, dtype=np.int64))
                continue
            if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer) or a.min() < 0 \
                    or a.max() >= self.n_tiles:
                raise ValueError(
                    f"tile ids must be 1-D integers in 0..{self.n_tiles - 1}, got {a.tolist()}"
                )
            tiles.append(np.unique(a.astype(np.int64)))
        return steps, tiles

    def _sorted_tiles(self, arrs: list):
        """The tile arrays as :meth:`_check_request` makes them, checked in a
        few calls for all steps at once, when every non-empty one is a 1-D
        int64 array of strictly increasing ids in range (what the FCFS
        expert sends: ``np.flatnonzero`` of a tile mask): those arrays, the
        ids ``np.unique`` would return. None for anything else,
        which the per-step checks handle (and name). From stop 42: the
        per-step checks cost FCFS about a tenth of its step."""
        full = [a for a in arrs if a.size]
        if not full:
            return None
        if set(map(_DTYPE, full)) != _INT64_ONLY or set(map(np.ndim, full)) != {1}:
            return None
        flat = np.concatenate(full)
        ends = np.cumsum([a.size for a in full])
        rising = np.diff(flat) > 0
        rising[ends[:-1] - 1] = True  # (from one array to the next is no step within one)
        if not (flat.min() >= 0 and flat.max() < self.n_tiles and rising.all()):
            return None
        empty = np.zeros(0, dtype=np.int64)
        return [a if a.size else empty for a in arrs]  # (the arrays themselves: the table only reads them)

    # -------------------------------------------------------------------- API
    def request(self, vehicle_id, time_steps, tiles_per_step) -> bool:
        """Ask for ``tiles_per_step[i]`` at step ``time_steps[i]`` for every ``i``.

        Granted (True, and the tiles are held) iff no requested tile is held
        by ANOTHER vehicle at the requested step or within ``time_buffer``
        steps of it.  Answered immediately, so calls are served in call order
        (first come, first served).  An empty request is granted and holds
        nothing.

        Raises:
            ValueError: steps not 1-D distinct integers >= ``now``, length
                mismatch, or tile ids outside ``0..n_tiles - 1``.
        """
        steps, tiles = self._check_request(time_steps, tiles_per_step)
        me = self._slot[vehicle_id] if vehicle_id in self._slot else -2
        b = self.time_buffer
        for t, tl in zip(steps.tolist(), tiles):
            if tl.size == 0:
                continue
            for s in range(t - b, t + b + 1):
                occ = self._occ.get(s)
                if occ is None:
                    continue
                h = occ[tl]
                if np.any((h >= 0) & (h != me)):
                    return False
        self.release(vehicle_id)
        slot = self._slot_of(vehicle_id)
        held = []
        for t, tl in zip(steps.tolist(), tiles):
            if tl.size == 0:
                continue
            occ = self._occ.get(t)
            if occ is None:
                occ = self._occ[t] = np.full(self.n_tiles, -1, dtype=np.int64)
            occ[tl] = slot
            held.append(t)
        self._held[vehicle_id] = sorted(held)
        return True

    def release(self, vehicle_id) -> bool:
        """Drop every tile ``vehicle_id`` holds; True if it held any."""
        steps = self._held.pop(vehicle_id, None)
        if not steps:
            return False
        slot = self._slot[vehicle_id]
        for t in steps:
            occ = self._occ.get(t)
            if occ is None:
                continue
            occ[occ == slot] = -1
            if not np.any(occ >= 0):
                del self._occ[t]
        return True

    def advance(self, now_step) -> None:
        """Move the clock to ``now_step`` (never backwards) and drop earlier steps."""
        now = _int("now_step", now_step)
        if now < self.now:
            raise ValueError(f"now_step must be >= the current step {self.now}, got {now}")
        self.now = now
        for t in [t for t in self._occ if t < now]:
            del self._occ[t]
        for vid in list(self._held):
            kept = [t for t in self._held[vid] if t >= now]
            if kept:
                self._held[vid] = kept
            else:
                del self._held[vid]

    def holder(self, step, tile):
        """Vehicle id holding ``tile`` at ``step``, or None."""
        occ = self._occ.get(_int("step", step))
        if occ is None:
            return None
        s = int(occ[_int("tile", tile, 0)])
        return None if s < 0 else self._ids[s]

    def occupancy(self, step) -> np.ndarray:
        """Bool ``(n_tiles,)`` mask of the tiles held at ``step``."""
        occ = self._occ.get(_int("step", step))
        return np.zeros(self.n_tiles, dtype=bool) if occ is None else occ >= 0

    def held_by(self, vehicle_id) -> dict[int, np.ndarray]:
        """``{step: sorted tile ids}`` held by ``vehicle_id`` (empty if none)."""
        if vehicle_id not in self._held:
            return {}
        slot = self._slot[vehicle_id]
        return {t: np.flatnonzero(self._occ[t] == slot) for t in self._held[vehicle_id]}

    @property
    def vehicles(self) -> list:
        """Vehicle ids currently holding a reservation, in first-grant order of their slot."""
        return [v for v in self._ids if v in self._held]


def _pose_along(path: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and headings at arc lengths ``s`` of a polyline, extended straight beyond both ends."""
    seg = np.diff(path, axis=0)
    ln = np.linalg.norm(seg, axis=1)
    keep = ln > 0
    seg, ln = seg[keep], ln[keep]
    cum = np.concatenate([[0.0], np.cumsum(ln)])
    starts = path[:-1][keep]
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(ln) - 1)
    t = (s - cum[i]) / ln[i]  # < 0 before the start, > 1 past the end (straight extension)
    xy = starts[i] + t[:, None] * seg[i]
    # (the headings' atan2 libm's from stop 50, _kernels.atan2_rows: NumPy's at X86_V3)
    return xy, atan2_rows(np.ascontiguousarray(seg[i, 1], dtype=np.float64), np.ascontiguousarray(seg[i, 0],
                                                                                                  dtype=np.float64))


def simulate_path_occupancy(path, s0: float, speed: float, dt: float = DEFAULT_DT,
                            accel=0.0, start_step: int = 0,
                            length: float = DEFAULT_VEHICLE_LENGTH,
                            width: float = DEFAULT_VEHICLE_WIDTH,
                            buffer: float = DEFAULT_SPACE_BUFFER, tile: float = DEFAULT_TILE,
                            box_half: float = DEFAULT_BOX_HALF, v_max: float = 20.0,
                            max_steps: int = 10_000) -> tuple[np.ndarray, list[np.ndarray]]:
    """Steps and tiles a vehicle would occupy crossing the box (request builder).

    The vehicle's centre moves along ``path`` (an in-box lane path from
    :func:`~icv_envs.platoon.geometry.lane_path`; before its start and after
    its end it continues straight along the first / last segment, i.e. the
    approach and departure lanes).  ``s`` is the arc length of the centre
    from the stop line (negative before it).  Kinematics per step ``k``
    (``t = (start_step + k) dt``)::

        v_{k+1} = clip(v_k + a_k dt, 0, v_max)
        s_{k+1} = s_k + (v_k + v_{k+1}) dt / 2

    with ``a_k = accel`` (scalar) or ``accel[k]`` (array; 0 after its end).
    Simulation stops once the buffered rear has left the box
    (``s - length / 2 - buffer > path length``).

    Returns:
        ``(steps, tiles)``: int64 ``(T,)`` steps (from ``start_step``) whose
        buffered footprint touches at least one tile, and the sorted tile ids
        per step.

    Raises:
        ValueError: bad arguments, or the vehicle does not clear the box
            within ``max_steps`` (e.g. it stops).
    """
    p = finite("path", path, ndim=2)
    if p.shape[1] != 2 or p.shape[0] < 2:
        raise ValueError(f"path must have shape (K >= 2, 2), got {p.shape}")
    s = float(finite("s0", s0, ndim=0))
    v = _pos("speed", speed, allow_zero=True)
    h = _pos("dt", dt)
    vmax = _pos("v_max", v_max)
    n_max = _int("max_steps", max_steps, 1)
    k0 = _int("start_step", start_step)
    acc = finite("accel", accel)
    if acc.ndim > 1:
        raise ValueError(f"accel must be a scalar or a 1-D per-step array, got shape {acc.shape}")
    hl = 0.5 * _pos("length", length) + _pos("buffer", buffer, allow_zero=True)
    total = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))
    v = min(v, vmax)
    ss = []
    for k in range(n_max):
        ss.append(s)
        if s - hl > total:
            break
        a = float(acc) if acc.ndim == 0 else (float(acc[k]) if k < acc.size else 0.0)
        v1 = min(max(v + a * h, 0.0), vmax)
        s += 0.5 * (v + v1) * h
        v = v1
    else:
        raise ValueError(
            f"the vehicle does not clear the box within max_steps = {n_max} steps "
            f"(s = {s:.3f} m of {total:.3f} m, speed {v:.3f} m/s)"
        )
    s_arr = np.asarray(ss)
    xy, hd = _pose_along(p, s_arr)
    mask = footprint_mask(xy, hd, length, width, buffer, tile, box_half)
    rows = np.flatnonzero(mask.any(axis=1))
    steps = (k0 + rows).astype(np.int64)
    return steps, [np.flatnonzero(mask[r]) for r in rows]
