"""Observation types of the environments, highway-env style (``config["observation"]["type"]``).

``Kinematics`` (the default)
    A ``(vehicles_count, len(features))`` float32 array, highway-env's
    ``KinematicObservation`` layout: row 0 is the observer, rows 1.. the
    ``vehicles_count - 1`` nearest vehicles within ``perception_distance``
    (the highway envs: by longitudinal distance, round the ring on
    HighwayRamps; the intersection: by Euclidean distance of body centres),
    nearest first, zero rows (presence 0) pad. Options, with highway-env's
    names and meanings:

    * ``features``: a list of the env's feature names (default: all of them,
      the table of the module docstring, formation-target features included),
      in the order given; the intersection also offers opt-in features outside
      the default (``lead_gap``, ``lead_dv``: the leader in its corridors);
    * ``vehicles_count`` (8), ``perception_distance`` (150 m highway, 100 m
      intersection);
    * ``absolute`` (False): False gives the other vehicles' ``x, y, vx, vy``
      relative to the observer (row 0 is always absolute); True gives them
      absolute;
    * ``normalize`` (True): divide by the scales of the module docstring;
      False gives SI units (metres, m/s) and a space unbounded in both
      directions;
    * ``clip`` (True): clip normalised values to [-1, 1] (the space is then
      ``Box(-1, 1)``, else unbounded).

``OccupancyGrid``
    A ``(len(features), nx, ny)`` float32 grid around the observer
    (highway-env's ``OccupancyGridObservation``): cell ``(i, j)`` covers
    ``grid_size[0][0] + i * grid_step[0] <= dx < ... + grid_step[0]`` (and the
    same for ``dy``), with ``dx, dy`` the offset of a vehicle's body centre
    from the observer's (world axes, or the observer's own axes with
    ``align_to_vehicle_axes``; round the ring on HighwayRamps). A cell holds
    the features of the nearest vehicle in it (the observer itself is in its
    own cell). Options: ``features`` (subset of ``presence, vx, vy, cos_h,
    sin_h``; default ``presence, vx, vy``), ``grid_size``
    (``[[-27.5, 27.5], [-27.5, 27.5]]`` m), ``grid_step`` (``[5, 5]`` m),
    ``absolute`` (False: velocities relative to the observer's),
    ``align_to_vehicle_axes`` (False), ``clip`` (True). ``vx, vy`` are divided
    by ``2 v_max`` (highway-env's default range ``[-2 v_max, 2 v_max]``);
    headings are unscaled (relative to the observer's with
    ``align_to_vehicle_axes``). highway-env's ``on_road`` feature is not
    available.

An unknown type, option or feature raises ``ValueError`` naming it. The
observation space is built once per configuration and is the one object every
agent shares.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from icv_envs.envs._config import pick_type, real_numbers, typed_options
from icv_envs.sim._kernels import kinematics_rows
from icv_envs._ufuncs import clip as uclip

__all__ = ["OBSERVATION_TYPES", "KINEMATIC_FEATURES", "Kinematics", "OccupancyGrid", "observation_factory",
           "merge_observation_config"]

#: the columns every env's feature rows start with, in this order: the
#: observation types read ``x .. vy`` as columns 1-4 and ``cos_h, sin_h`` as
#: 5-6 (each env's ``OBS_FEATURES`` is this plus its own columns)
KINEMATIC_FEATURES = ("presence", "x", "y", "vx", "vy", "cos_h", "sin_h")


def _bool(o: dict, k: str) -> bool:
    if not isinstance(o[k], (bool, np.bool_)):
        raise ValueError(f"observation {k} = {o[k]!r}; allowed: True or False")
    return bool(o[k])


class ObservationType:
    name = ""
    OPTIONS: dict = {}

    def __init__(self, env, config: dict) -> None:
        self.env = env
        self.options = typed_options("observation", self.name, self.OPTIONS, config)

    def _features(self, allowed, default) -> np.ndarray:
        feats = self.options["features"]
        if feats is None:
            feats = list(default)
        if isinstance(feats, str) or not isinstance(feats, (list, tuple)) or not feats:
            raise ValueError(f"observation features = {feats!r}; allowed: a non-empty list of {list(allowed)}")
        bad = [f for f in feats if f not in allowed]
        if bad:
            raise ValueError(f"unknown observation feature(s) {bad} for {self.name!r}; allowed: {list(allowed)}")
        if len(set(feats)) != len(feats):
            raise ValueError(f"observation features = {list(feats)} repeat a feature; allowed: each at most once")
        self.features = tuple(feats)
        return np.array([list(allowed).index(f) for f in feats], dtype=np.int64)

    # highway-env's ObservationType interface (used by its viewer / wrappers)
    def observe(self):
        return self.env._ego_obs_info()[0]

    def space(self):
        return self.space_


class Kinematics(ObservationType):
    name = "Kinematics"
    OPTIONS = {"features": None, "vehicles_count": 8, "perception_distance": None, "absolute": False,
               "normalize": True, "clip": True}

    def __init__(self, env, config: dict) -> None:
        super().__init__(env, config)
        from icv_envs.envs._config import num as _num

        o = self.options
        if o["perception_distance"] is None:
            o["perception_distance"] = env.PERCEPTION_DISTANCE
        self.V = _num(o, "vehicles_count", 1, 64, integer=True, allowed="an integer in [1, 64]")
        o["vehicles_count"] = self.V
        self.pd = _num(o, "perception_distance", 0.0, lo_open=True, allowed="a number > 0 metres")
        extra = tuple(getattr(env, "OBS_EXTRA_FEATURES", ()))
        self.idx = self._features(tuple(env.OBS_FEATURES) + extra, env.OBS_FEATURES)
        # opt-in columns the env appends to its feature array (all of them when
        # any is asked for), so ``idx`` indexes that array directly
        self.extra = extra if any(k in self.features for k in extra) else ()
        self.absolute, self.normalize, self.clip = _bool(o, "absolute"), _bool(o, "normalize"), _bool(o, "clip")
        if not self.normalize and config.get("clip") is True:
            # (highway-env's convention: clip bounds the normalised values; raw ones are never clipped)
            raise ValueError("observation clip = True with normalize = False; allowed: clip applies to normalised "
                             "observations only (leave clip out, or set normalize = True)")
        bound = 1.0 if self.normalize and self.clip else np.inf
        self.space_ = spaces.Box(-bound, bound, (self.V, len(self.idx)), dtype=np.float32)

    def kernel_options(self) -> tuple:
        """:func:`~icv_envs.sim._kernels.kinematics_rows`' options: ``(idx, V,
        s_abs, s_rel, absolute, normalize, clip)``, the env's feature scales
        (absolute, relative) as float64 (for :meth:`observe_rows` and the
        highway env's one-call step)."""
        s_abs, s_rel = self.env._obs_scales()
        f = np.float64
        return (self.idx, self.V, np.asarray(s_abs, dtype=f), np.asarray(s_rel, dtype=f), self.absolute,
                self.normalize, self.clip)

    def observe_rows(self, rows: np.ndarray, F: np.ndarray) -> np.ndarray:
        env = self.env
        V = self.V
        if not len(rows):
            return np.zeros((0, V, len(self.idx)), dtype=np.float32)
        options = self.kernel_options()
        s_abs, s_rel = options[2], options[3]
        n = len(F)
        if V > 1 and n > 1:
            sel, present = env._neighbours(rows, F, V - 1, self.pd)
        else:
            sel, present = np.zeros((len(rows), 0), dtype=np.int64), np.zeros((len(rows), 0), dtype=bool)
        period = env._wrap_period()
        if period is not None:
            # compiled (icv_envs.sim._kernels.kinematics_rows): the array
            # code below, one pass
            return kinematics_rows(np.ascontiguousarray(F, dtype=np.float64), np.asarray(rows, dtype=np.int64),
                                   np.asarray(sel, dtype=np.int64), np.asarray(present, dtype=bool), *options,
                                   float(period))
        out = np.zeros((len(rows), V, len(self.idx)), dtype=np.float32)
        own = F[rows]
        if self.normalize:
            own = own / s_abs
            if self.clip:
                own = uclip(own, -1, 1)
        out[:, 0, :] = own[:, self.idx]
        if sel.shape[1]:
            K = sel.shape[1]
            other = F[sel].copy()
            if not self.absolute:
                other[..., 1:5] -= F[rows][:, None, 1:5]
                other[..., 1] = env._wrap_dx(other[..., 1])
            if self.normalize:
                other = other / (s_abs if self.absolute else s_rel)
                if self.clip:
                    other = uclip(other, -1, 1)
            other[~present] = 0.0
            out[:, 1:1 + K, :] = other[..., self.idx]
        return out


class OccupancyGrid(ObservationType):
    name = "OccupancyGrid"
    FEATURES = ("presence", "vx", "vy", "cos_h", "sin_h")
    OPTIONS = {"features": None, "grid_size": [[-27.5, 27.5], [-27.5, 27.5]], "grid_step": [5.0, 5.0],
               "absolute": False, "align_to_vehicle_axes": False, "clip": True}

    def __init__(self, env, config: dict) -> None:
        super().__init__(env, config)
        o = self.options
        self.idx = self._features(self.FEATURES, ("presence", "vx", "vy"))
        gs, st = real_numbers(o["grid_size"]), real_numbers(o["grid_step"])
        gs = np.zeros(0) if gs is None else gs
        st = np.zeros(0) if st is None else st
        if gs.shape != (2, 2) or not np.all(np.isfinite(gs)) or np.any(gs[:, 1] <= gs[:, 0]):
            raise ValueError(f"observation grid_size = {o['grid_size']!r}; allowed: [[x_min, x_max], [y_min, y_max]] "
                             f"metres with min < max")
        if st.shape != (2,) or not np.all(np.isfinite(st)) or np.any(st <= 0):
            raise ValueError(f"observation grid_step = {o['grid_step']!r}; allowed: [step_x, step_y] metres > 0")
        self.shape = tuple(int(v) for v in np.floor((gs[:, 1] - gs[:, 0]) / st + 1e-9))
        if min(self.shape) < 1 or self.shape[0] * self.shape[1] > 10000:
            raise ValueError(f"observation grid of {self.shape} cells; allowed: 1 to 10000 cells")
        self.gs, self.st = gs, st
        self.absolute, self.align, self.clip = (_bool(o, "absolute"), _bool(o, "align_to_vehicle_axes"),
                                                _bool(o, "clip"))
        bound = 1.0 if self.clip else np.inf
        self.space_ = spaces.Box(-bound, bound, (len(self.idx), *self.shape), dtype=np.float32)

    def observe_rows(self, rows: np.ndarray, F: np.ndarray) -> np.ndarray:
        env = self.env
        nx, ny = self.shape
        m = len(rows)
        out = np.zeros((m, len(self.FEATURES), nx, ny), dtype=np.float32)
        if not m:
            return out[:, self.idx]
        vmax2 = 2.0 * float(env.config["speed_range"][1])
        dx = env._wrap_dx(F[None, :, 1] - F[rows][:, None, 1])
        dy = F[None, :, 2] - F[rows][:, None, 2]
        vx = F[None, :, 3] - (0.0 if self.absolute else F[rows][:, None, 3])
        vy = F[None, :, 4] - (0.0 if self.absolute else F[rows][:, None, 4])
        ch = np.broadcast_to(F[None, :, 5], dx.shape)
        sh = np.broadcast_to(F[None, :, 6], dx.shape)
        if self.align:
            c, s = F[rows][:, None, 5], F[rows][:, None, 6]
            dx, dy = c * dx + s * dy, -s * dx + c * dy
            vx, vy = c * vx + s * vy, -s * vx + c * vy
            ch, sh = c * ch + s * sh, c * sh - s * ch
        ix = np.floor((dx - self.gs[0, 0]) / self.st[0]).astype(np.int64)
        iy = np.floor((dy - self.gs[1, 0]) / self.st[1]).astype(np.int64)
        ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        o, j = np.nonzero(ok)
        if len(o):
            d2 = dx[o, j] ** 2 + dy[o, j] ** 2
            cell = (o * nx + ix[o, j]) * ny + iy[o, j]
            order = np.lexsort((j, d2, cell))  # per cell: nearest first (ties: lower row)
            cell_sorted = cell[order]
            first = order[np.r_[True, cell_sorted[1:] != cell_sorted[:-1]]]
            o, j = o[first], j[first]
            cx, cy = ix[o, j], iy[o, j]
            vals = np.stack([np.ones(len(o)), vx[o, j] / vmax2, vy[o, j] / vmax2, ch[o, j], sh[o, j]], axis=1)
            if self.clip:
                vals = uclip(vals, -1, 1)
            out[o[:, None], np.arange(len(self.FEATURES))[None, :], cx[:, None], cy[:, None]] = vals
        return out[:, self.idx]


OBSERVATION_TYPES = {c.name: c for c in (Kinematics, OccupancyGrid)}


def observation_factory(env, config: dict) -> ObservationType:
    return pick_type("observation", config, OBSERVATION_TYPES, "Kinematics")(env, config)


def merge_observation_config(old: dict | None, new: dict) -> dict:
    """``configure``'s rule for the ``observation`` (and ``action``) dict: a dict
    of the same type (or without a type) updates the current one key by key;
    a dict of another type replaces it (its options start from that type's
    defaults)."""
    if not isinstance(new, dict) or not isinstance(old, dict):
        return new
    t_old = old.get("type", None)
    t_new = new.get("type", t_old)
    if t_new != t_old:
        return dict(new)
    merged = dict(old)
    merged.update(new)
    return merged
