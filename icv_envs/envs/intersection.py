"""Intersection: the multi-lane unsignalized intersection of the paper (Sec. 4-5, Table 2).

A highway-env :class:`~highway_env.envs.common.abstract.AbstractEnv` subclass
(``default_config()`` / ``configure()``, highway-env's road network, viewer
and ``RecordVideo`` support) over the vectorised core
:class:`icv_envs.sim.intersection_world.IntersectionWorld`.  The
single-agent Gymnasium API (``gym.make("icv_envs/Intersection-v0")``) drives
one learned ego among expert-driven vehicles; ``ma_reset`` / ``ma_step``
back the PettingZoo module :mod:`icv_envs.envs.intersection_v0`, whose
docstring documents observations, actions, rewards and arguments.

Traffic generation (our choices where the paper is silent): on every leg,
formations of ``formation_size`` vehicles arrive at ``R3`` in the interlaced
layout of :func:`icv_envs.formation.targets.interlaced_targets` (3 lanes,
``L_s = 15 m``) at ``v0 = 10 m/s``; each vehicle appears when its slot passes
``R3`` (a slot ``x_g`` behind the front appears ``x_g / v0`` later).  The
requested ``throughput`` (vehicles/h entering the intersection, all legs) is
split evenly over the four legs; formation heads follow a shifted
exponential (``arrivals="poisson"``: a minimum headway of the formation's
length plus two slots, at ``v0``, plus an exponential with the rest of the
mean) or a constant interval (``"fixed"``), legs 1-3 with a random phase,
leg N's first formation at t = 0 (its front vehicle is the Gymnasium ego).
Movements are drawn per vehicle with ``turn_shares`` (left, straight,
right).  A vehicle whose spawn point is occupied (a vehicle within 8 m
behind or 14 m ahead in its lane) waits in a queue for its (leg, lane); it
appears at ``min(v0, speed of the vehicle ahead within 50 m)``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from highway_env.envs.common.abstract import AbstractEnv

from icv_envs.envs.base import IcvAgentsEnv
from icv_envs.envs.intersection_config import (  # noqa: F401  (METHODS, FCFS_TIGHT, MAX_THROUGHPUT re-exported)
    FCFS_TIGHT,
    INFO_KEYS,
    MAX_THROUGHPUT,
    METHODS,
    check_config,
    config_entries,
)
from icv_envs.envs.intersection_render import IntersectionRendering
from icv_envs.envs.intersection_report import IntersectionReport
from icv_envs.envs.intersection_rows import POST_HOOK_NAMES, IntersectionRows
from icv_envs._hooks import hook_table
from icv_envs.envs.observations import KINEMATIC_FEATURES, merge_observation_config
from icv_envs.formation.targets import formation_length, interlaced_targets
from icv_envs.platoon.conflicts import required_layer_gap
from icv_envs.platoon.geometry import LEGS, movement_name
from icv_envs.policies.fcfs import FcfsExpert
from icv_envs.policies.platoon_expert import PlatoonExpert, PlatoonParams
from icv_envs.sim.intersection_world import IntersectionLayout, IntersectionWorld, StepEvents, validate_radii
from icv_envs._ufuncs import clip as uclip

__all__ = ["IntersectionEnv", "METHODS", "OBS_FEATURES", "OBS_EXTRA_FEATURES", "MAX_THROUGHPUT"]

OBS_FEATURES = KINEMATIC_FEATURES + (
    "dist",
    "ref_dx",
    "ref_dv",
    "lane_err",
    "turn",
    "zone",
    "go",
)
STATE_FEATURES = OBS_FEATURES
#: Kinematics features outside the default set (ask for them in
#: ``observation["features"]``): the leader the safety reward and the
#: experts' envelope see, in the vehicle's corridors (lane, the lane it
#: signals into, its path in the box): ``lead_gap`` = bumper gap in metres
#: (the perception distance when there is none), ``lead_dv`` = own speed -
#: the leader's (0 when there is none)
OBS_EXTRA_FEATURES = ("lead_gap", "lead_dv")

class IntersectionEnv(IntersectionRows, IntersectionReport, IntersectionRendering, IcvAgentsEnv):
    """Four-leg, three-lane unsignalized intersection with the paper's coordination methods.

    See :mod:`icv_envs.envs.intersection_v0` for the full documentation.
    """

    OBS_FEATURES = OBS_FEATURES
    INFO_KEYS = INFO_KEYS
    OBS_EXTRA_FEATURES = OBS_EXTRA_FEATURES

    def _vehicles(self):
        return self.world.fleet

    def _make_viewer(self):
        from icv_envs.envs.intersection_viewer import viewer_class

        return viewer_class()(self)

    # ------------------------------------------------------------------ config
    @classmethod
    def default_config(cls) -> dict:
        config = super().default_config()
        config.update(config_entries())
        return config

    _CONFIG_DERIVED = ("layout", "D_t")

    def _apply_config(self, config: dict | None) -> None:
        """highway-env's ``configure``; nested ``fcfs``, ``reward`` and
        ``observation`` dicts are merged key by key (:meth:`configure` then
        validates, restoring the previous config on an error)."""
        if config is not None and not isinstance(config, dict):
            raise ValueError(f"config = {config!r} ({type(config).__name__}); allowed: a dict or None")
        config = dict(config or {})
        for key in ("fcfs", "reward"):
            if key in config and isinstance(config[key], dict) and isinstance(self.config.get(key), dict):
                merged = dict(self.config[key])
                merged.update(config[key])
                config[key] = merged
        for key in ("observation", "action"):  # same type: merged; another type: replaced
            if key in config:
                config[key] = merge_observation_config(self.config.get(key), config[key])
        AbstractEnv.configure(self, config)

    def _validate_config(self) -> None:
        c = self.config
        check_config(c, self.default_config(), self._validate_spaces_config, self._n_possible_agents)
        lu = c["lane_use"]
        # geometry, lane use, radii (raise ValueError with their own messages)
        validate_radii(c["R1"], c["R2"], c["R3"], c["box_half"])
        try:
            self.layout = IntersectionLayout(
                lu, c["lane_width"], c["box_half"], c["R1"], c["R2"], c["R3"], c["departure_length"],
                bool(c["opposing_left_conflict"]),
            )
        except (ValueError, TypeError) as exc:  # the radii are fine: the lane-use table is not
            raise ValueError(f"config['lane_use'] = {lu!r} is invalid: {exc}") from None
        need = required_layer_gap(self.layout.model)
        self.layout.model_gap = need
        if c["D_t"] == "auto":
            # the hard spacing plus the reaction margin of the safe-speed cap at v0
            self.D_t = need + float(c["desired_speed"]) / float(c["policy_frequency"])
        else:
            self.D_t = float(c["D_t"])
        if self.D_t < need - 1e-9:
            raise ValueError(
                f"config['D_t'] = {c['D_t']!r} m is too small for this geometry; allowed: D_t >= {need:.2f} m "
                f"(vehicle length + 2 m + the largest conflict-point offset, see required_layer_gap)"
            )

    # ------------------------------------------------------------------ build
    def _params(self) -> PlatoonParams:
        c = self.config
        return PlatoonParams(
            v0=float(c["desired_speed"]), v_max=float(c["speed_range"][1]),
            a_min=float(c["acceleration_range"][0]), a_max=float(c["acceleration_range"][1]),
            comfort=(max(float(c["acceleration_range"][0]), -3.0), min(float(c["acceleration_range"][1]), 2.0)),
            wheelbase=float(c["wheelbase"]), steer_max=math.radians(c["max_steering_deg"]),
            gap_out=float(c["gap_outside"]), gap_in=float(c["gap_inside"]), D_t=float(self.D_t),
            merge_range=float(c["merge_range"]), max_node_size=int(c["max_node_size"]),
            envelope_in_box=bool(c["envelope_in_box"]), anticipate=bool(c["vp_anticipation"]),
            zone_advisory=bool(c["vp_zone_advisory"]), D_safe=float(self.layout.model_gap),
            cap_tau=1.0 / float(c["policy_frequency"]),
        )

    def _arrivals(self) -> list[tuple]:
        """All vehicle arrivals ``(due_time, leg, lane, movement, formation_key, slot)`` of the episode."""
        c = self.config
        rng = self.np_random
        T = float(c["duration"]) + float(c["warmup"])
        v0 = float(c["desired_speed"])
        n = int(c["formation_size"])
        gap = float(c["gap_outside"])
        lam = float(c["throughput"]) / 4.0 / 3600.0  # vehicles/s per leg
        mean_h = n / lam
        h_min = (formation_length(n, 3, gap) + 2.0 * gap) / v0
        xg, lane_id = interlaced_targets(n, 3, gap)
        shares = np.asarray(c["turn_shares"], dtype=np.float64)
        shares = shares / shares.sum()
        out = []
        # each leg draws its formation heads and its movements from two
        # streams of its own (seeded by a fixed number of draws from the env's
        # RNG, consumed in blocks): the traffic does not depend on the horizon
        seeds = rng.integers(0, 2**63 - 1, size=(4, 2))
        B = 64
        poisson = c["arrivals"] == "poisson" and mean_h > h_min
        for leg in range(4):
            g_h, g_m = np.random.default_rng(int(seeds[leg, 0])), np.random.default_rng(int(seeds[leg, 1]))
            phase = 0.0 if leg == 0 else float(g_h.uniform(0.0, mean_h))
            heads, base = [np.array([phase])], phase
            while heads[-1][-1] < T:
                gaps = h_min + g_h.exponential(mean_h - h_min, size=B) if poisson else np.full(B, mean_h)
                heads.append(base + np.cumsum(gaps))
                base = float(heads[-1][-1])
            heads = np.concatenate(heads)
            heads = heads[heads < T]
            for fi, t0 in enumerate(heads):
                mvs = 3 * leg + g_m.choice(3, size=n, p=shares)
                for j in range(n):
                    due = float(t0 + xg[j] / v0)
                    if due < T:
                        out.append((due, leg, int(lane_id[j] - 1), int(mvs[j]), (leg, fi), float(xg[j])))
        out.sort(key=lambda a: (a[0], a[1], a[2]))
        return out

    def _n_possible_agents(self) -> int:
        return self._max_vehicles()

    def _max_vehicles(self) -> int:
        """Possible agents: ``max_vehicles`` or, independent of the seed, the mean
        number of arrivals plus six standard deviations (formations arrive
        together: variance ``formation_size * mean``) plus four formations."""
        c = self.config
        if c["max_vehicles"] is not None:
            return int(c["max_vehicles"])
        mean = float(c["throughput"]) * (float(c["duration"]) + float(c["warmup"])) / 3600.0
        n = int(c["formation_size"])
        return int(math.ceil(mean + 6.0 * math.sqrt(n * mean) + 4 * n + 20))

    def _reset(self) -> None:
        c = self.config
        lay = self.layout
        world = IntersectionWorld(lay, dt=1.0 / c["simulation_frequency"], wheelbase=c["wheelbase"],
                                  v_max=float(c["speed_range"][1]), v_free=float(c["desired_speed"]))
        self.world = world
        params = self._params()
        if c["method"] in ("fcfs", "fcfs-tight"):
            fc = dict(c["fcfs"])
            if c["method"] == "fcfs-tight":
                fc.update(FCFS_TIGHT)
            self.expert = FcfsExpert(lay, params, frames=self._frames(), dt=world.dt, tile=fc["tile"],
                                     time_buffer=int(fc["time_buffer"]), space_buffer=fc["space_buffer"],
                                     request_distance=fc["request_distance"], a_plan=fc["a_plan"])
        else:
            self.expert = PlatoonExpert(lay, params, method=c["method"], frames=self._frames())
        self.expert.attach(world)
        arrivals = self._arrivals()
        cap = self._max_vehicles()
        self._not_spawned = 0
        if len(arrivals) > cap:
            self._not_spawned = len(arrivals) - cap
            arrivals = arrivals[:cap]
        self._pending = arrivals
        # due times of every arrival (clock of the statistics: the warm-up ends at 0)
        self._due = np.sort(np.array([a[0] for a in arrivals], dtype=np.float64)) - float(c["warmup"])
        self._queues: dict[tuple[int, int], list] = {(lg, ln): [] for lg in range(4) for ln in range(3)}
        self.possible_agents = [f"icv_{i}" for i in range(cap)]
        self._proxies: dict[int, Any] = {}
        self._last_actions = np.zeros((0, 2))
        self._expert_cache = None
        self._leaders_cache = None
        self._ego_vid = 0
        self._ego_done = False
        self.warmup_collisions = 0
        self.warmup_jammed = 0
        self._last_obs = None
        self._series: list[dict] = []
        self._spawn_due()
        self.expert.update(world)
        if c["warmup"] > 0:
            self._warm_up(float(c["warmup"]))
        self._render_road_due()

    def _warm_up(self, seconds: float) -> None:
        """Run the expert for ``seconds`` before the episode starts, then restart
        the clock at 0 and the run statistics with the vehicles present as
        spawned; the Gymnasium ego is then the vehicle spawned last."""
        w = self.world
        while w.time < seconds - 1e-9:
            self._advance(self.expert.compute(w))
            w.remove_crashed_vehicles()
            self._spawn_due()
            self.expert.update(w)
        f = w.fleet
        shift = w.time
        w.time = 0.0
        f.spawn_time = f.spawn_time - shift
        f.enter_time = f.enter_time - shift
        self._pending = [(a[0] - shift,) + tuple(a[1:]) for a in self._pending]
        for q in self._queues.values():
            q[:] = [(a[0] - shift,) + tuple(a[1:]) for a in q]
        self.warmup_collisions = int(w.stats["collisions"])
        self.warmup_jammed = int(w.jams.summary()["jammed"])
        for k in w.stats:
            w.stats[k] = math.inf if k == "min_speed_in_box" else (0.0 if isinstance(w.stats[k], float) else 0)
        w.stats["spawned"] = int(f.n)
        w.collision_log.clear()
        w.reset_metrics()
        for k in self.expert.stats:
            self.expert.stats[k] = 0.0 if isinstance(self.expert.stats[k], float) else 0
        self._ego_vid = int(f.vid[-1]) if f.n else int(f.next_vid)
        self._expert_cache = None
        self._leaders_cache = None

    def _spawn_due(self) -> list[int]:
        """Move due arrivals into their lane queues and spawn queue heads whose spawn point is free."""
        c = self.config
        w = self.world
        lay = self.layout
        t = w.time
        while self._pending and self._pending[0][0] <= t + 1e-9:
            a = self._pending.pop(0)
            self._queues[(a[1], a[2])].append(a)
        if not any(self._queues.values()):
            return []
        f = w.fleet
        s_spawn = -(lay.R3 - lay.box_half)
        v0 = float(c["desired_speed"])
        new = []
        rs = w.route() if f.n else None
        for (leg, lane), q in self._queues.items():
            if not q:
                continue
            if f.n:
                on = (f.leg == leg) & (rs.phase == 0) & (np.abs(rs.lat_leg - (lane + 0.5) * lay.lane_width)
                                                          < 0.5 * (lay.lane_width + f.width))
                d = rs.u[on] - s_spawn
                if np.any((d > -8.0) & (d < 14.0)):
                    continue
                ahead = (d >= 14.0) & (d < 50.0)
                speed = min(v0, float(f.speed[on][ahead].min())) if ahead.any() else v0
            else:
                speed = v0
            due, lg, ln, mv, key, slot = q.pop(0)
            default_lane = lay.lane_use[mv][-1]
            vid = w.spawn(lg, ln, mv, speed, s_spawn, tlane=default_lane)
            self.expert.on_spawn(w, vid, key, slot, ln)
            new.append(vid)
            rs = w.route()
        return new

    # ------------------------------------------------------------------ spaces

    def global_state(self, slots: list[str]) -> np.ndarray:
        """One row per possible agent (slot order), absolute normalised features, zeros for absent vehicles."""
        out = np.zeros((len(slots), len(STATE_FEATURES)), dtype=np.float32)
        f = self.world.fleet
        if f.n:
            F = self._features()
            slot_of = {name: i for i, name in enumerate(slots)}
            idx = np.array([slot_of.get(f"icv_{v}", -1) for v in f.vid])
            ok = idx >= 0
            k = len(STATE_FEATURES)
            out[idx[ok]] = uclip(F[ok, :k] / self._scales(False)[:k], -1, 1)
        return out

    # ------------------------------------------------------------------ expert
    # expert_actions(): IcvAgentsEnv's, cached on the vehicle state

    # -------------------------------------------------------------- stepping
    # the step itself is IcvAgentsEnv._ma_advance; these are its hooks
    def _drivers(self, vids, expert_mask, plan_mask) -> None:
        self.world.set_expert_driven(vids, expert_mask)
        self.expert.set_plan_carriers(vids, plan_mask)

    def _new_events(self) -> StepEvents:
        return StepEvents()

    def _react(self, events: StepEvents) -> list:
        # new arrivals appear and the coordination layer reacts, then everyone observes
        new = self._spawn_due()
        self.expert.update(self.world)
        return new

    def _truncations(self, truncated_all: bool, crashed_now: np.ndarray):
        return bool(truncated_all) & ~crashed_now

    def _departed(self, events: StepEvents) -> dict:
        # the departure end is a terminal success, driving back out of the
        # approach road a truncation
        return {vid: {"exited": vid in events.removed, "left_road": vid in events.left_road, "crashed": False,
                      "wrong_exit": vid in events.wrong_exit}
                for vid in events.removed | events.left_road}

    def _after_removal(self) -> None:
        self.expert.update(self.world)

    def _ma_info_columns(self, rows, keys: tuple) -> dict:
        """Per-agent info columns (lists aligned with ``rows``, non-empty),
        those named in ``keys`` (``config["info_keys"]``), in
        :data:`INFO_KEYS` order."""
        f = self.world.fleet
        rows = np.asarray(rows, dtype=np.int64)
        cols = {}
        if "speed" in keys:
            cols["speed"] = f.speed[rows].tolist()
        if "movement" in keys:
            cols["movement"] = f.mv[rows].tolist()
        if "distance" in keys:
            cols["distance"] = np.asarray(self.world.route().dist)[rows].tolist()
        if "node" in keys or "tree_layer" in keys:
            nodes = f.node[rows].tolist()
            if "node" in keys:
                cols["node"] = nodes
            if "tree_layer" in keys:
                depth = self.expert.node_depth
                cols["tree_layer"] = [depth.get(nd, -1) for nd in nodes]
        if "crashed" in keys:
            cols["crashed"] = [False] * len(rows)
        return cols

    # --------------------------------------------- metrics, rendering (mixins)
    # metrics(): envs/intersection_report.py; _sync_render_road(), _colours():
    # envs/intersection_render.py

    def describe(self) -> dict:
        """Geometry summary: legs, lanes, movements with their allowed lanes, radii, D_t."""
        lay = self.layout
        return {
            "legs": list(LEGS),
            "lane_use": lay.lane_use_name,
            "movements": [{"id": m, "name": movement_name(m), "lanes": list(lay.lane_use[m])} for m in range(12)],
            "R1": lay.R1, "R2": lay.R2, "R3": lay.R3, "box_half": lay.box_half,
            "D_t": float(self.D_t), "required_layer_gap": float(lay.model_gap),
        }


# the one-pass _post_rows is taken while these hooks are this class's own (intersection_rows)
IntersectionEnv._post_hooks = hook_table(IntersectionEnv, *POST_HOOK_NAMES)
