"""HighwayFormation: ICVs driving in multi-lane interlaced formations.

A highway-env :class:`~highway_env.envs.common.abstract.AbstractEnv` subclass
(``default_config()`` / ``configure()``, highway-env's viewer and
``RecordVideo`` support) over the vectorised core :class:`icv_envs.sim.world.World`.
The single-agent Gymnasium API (``gym.make("icv_envs/HighwayFormation-v0")``)
drives one learned ego ICV among expert-driven ICVs; the multi-agent methods
``ma_reset`` / ``ma_step`` back the PettingZoo module
:mod:`icv_envs.envs.highway_formation_v0`, whose docstring documents
observations, actions, rewards and arguments.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from highway_env.envs.common.abstract import AbstractEnv

from icv_envs._hooks import hook_table, own_hooks
from icv_envs.envs.actions import action_to_controls, controls_to_action  # noqa: F401  (re-exported)
from icv_envs.envs.base import IcvAgentsEnv
from icv_envs.envs.highway_config import INFO_KEYS, UNUSED_KEYS, check_config, config_entries
from icv_envs.envs.highway_rows import OBS_FEATURES, POST_HOOK_NAMES, STATE_FEATURES, HighwayRows
from icv_envs.envs.observations import merge_observation_config
from icv_envs.envs.scenarios import SCENARIOS, scenario_config
from icv_envs.formation.targets import formation_length
from icv_envs.policies.formation_expert import ExpertParams, FormationExpert
from icv_envs.sim.formations import FormationManager
from icv_envs.sim.road import Obstacle, OffRamp, OnRamp, RoadLayout
from icv_envs.sim.world import StepEvents, World

__all__ = ["HighwayFormationEnv", "OBS_FEATURES", "STATE_FEATURES", "action_to_controls", "controls_to_action"]


class HighwayFormationEnv(HighwayRows, IcvAgentsEnv):
    """Multi-lane formation control of ICVs on a straight highway.

    See :mod:`icv_envs.envs.highway_formation_v0` for the full documentation.
    """

    MIN_VEHICLES = 1
    OBS_FEATURES = OBS_FEATURES
    INFO_KEYS = INFO_KEYS

    def _vehicles(self):
        return self.world.traffic

    def _make_viewer(self):
        from icv_envs.envs.rendering import FormationViewer

        return FormationViewer(self)

    # ------------------------------------------------------------------ config
    @classmethod
    def default_config(cls) -> dict:
        config = super().default_config()
        config.update(config_entries())
        return config

    def _apply_config(self, config: dict | None) -> None:
        """highway-env's ``configure``, plus scenario presets: a ``scenario``
        key applies :data:`~icv_envs.envs.scenarios.SCENARIOS` first, then the
        rest of ``config`` on top; nested ``formation``, ``reward`` and
        ``observation`` dicts are merged key by key. (:meth:`configure`
        validates and restores the previous config on an error.)"""
        if config is not None and not isinstance(config, dict):
            raise ValueError(f"config = {config!r} ({type(config).__name__}); allowed: a dict or None")
        config = dict(config or {})
        scen = config.get("scenario")
        if scen is not None:
            if not isinstance(scen, str) or scen not in SCENARIOS:
                raise ValueError(f"unknown scenario {scen!r}; allowed: {sorted(SCENARIOS)}")
            base = self.default_config()
            base.update(scenario_config(scen))
            self.config = base
        for key in ("formation", "reward"):
            if key in config and isinstance(config[key], dict) and isinstance(self.config.get(key), dict):
                merged = dict(self.config[key])
                merged.update(config[key])
                config[key] = merged
        for key in ("observation", "action"):  # same type: merged; another type: replaced
            if key in config:
                config[key] = merge_observation_config(self.config.get(key), config[key])
        AbstractEnv.configure(self, config)

    #: highway-env keys this env does not use: setting them is an error
    UNUSED_KEYS = UNUSED_KEYS

    _AGENTS_FROM = "vehicles_count + len(spawns)"

    def _n_possible_agents(self) -> int:
        c = self.config
        return int(c["vehicles_count"]) + len(c["spawns"])

    def _validate_config(self) -> None:
        c = self.config
        check_config(c, self.default_config(), type(self).__name__, self.UNUSED_KEYS, self.MIN_VEHICLES,
                     self._validate_spaces_config, self._n_possible_agents, self._AGENTS_FROM)
        # vehicles must fit on the road
        self._placement()

    def _placement(self) -> list[tuple[int, float, list[int]]]:
        """(count, anchor, lanes) per initial formation; raises if they do not fit.

        Each formation is sized for the main lanes drivable over the window
        its formation layer will use, ``[anchor - length - 10 m, anchor +
        lookahead]`` (:meth:`FormationManager._lane_set`): a lane that drops
        or is blocked in that window is not used, so the targets the vehicles
        are placed on are the targets the formation layer assigns (sizing for
        the starting lane count but assigning on fewer lanes put vehicles on
        top of each other). Lane set and length depend on each other and on
        the anchors: iterated to a fixed point (at most a few rounds)."""
        c = self.config
        n, size = int(c["vehicles_count"]), int(c["formation_size"])
        k = math.ceil(n / size)
        counts = [n // k + (1 if i < n % k else 0) for i in range(k)]
        f = c["formation"]
        road = self._make_road()
        lane_sets = [list(range(int(c["lanes_count"]))) for _ in counts]
        front = c["initial_position"]
        auto = front is None
        if not auto and (not isinstance(front, (int, float)) or isinstance(front, bool) or not math.isfinite(front)):
            raise ValueError(f"config['initial_position'] = {front!r}; allowed: a number or None (automatic)")

        def layout(sets):
            lengths = [formation_length(m, len(ls), f["spacing"], f["geometry"]) for m, ls in zip(counts, sets)]
            needed = sum(lengths) + c["formation_gap"] * (k - 1) + 10.0
            fr = needed + 10.0 if auto else float(front)
            anchors, a = [], fr
            for length in lengths:
                anchors.append(a)
                a -= length + c["formation_gap"]
            return lengths, needed, fr, anchors

        # lanes only ever shrink (intersection), so this terminates
        for _ in range(int(c["lanes_count"]) * k + 1):
            lengths, needed, fr, anchors = layout(lane_sets)
            new = []
            for a, length, ls in zip(anchors, lengths, lane_sets):
                got = [lane for lane in road.drivable_main_lanes(a - length - 10.0, a + f["lookahead"]) if lane in ls]
                new.append(got or ls[:1])
            if new == lane_sets:
                break
            lane_sets = new
        lengths, needed, fr, anchors = layout(lane_sets)
        lanes = min(len(ls) for ls in lane_sets)
        if fr - needed < 0 or fr > c["road_length"] - 100.0:
            per_m = max(lanes, 1) / (2.0 * f["spacing"]) * 2.0
            cap = int(max(0.0, min(fr, c["road_length"] - 100.0) - 10.0) * per_m * 0.5) + 1
            raise ValueError(
                f"vehicles_count={n} does not fit: {lanes} lanes with spacing {f['spacing']} m need {needed:.0f} m "
                f"behind initial_position={fr} (road_length={c['road_length']}); at most about {cap} vehicles fit "
                + ("there: use fewer vehicles or a longer road" if auto else
                   "there, or set initial_position=None to place them automatically")
            )
        return [(m, a, ls) for m, a, ls in zip(counts, anchors, lane_sets)]

    def _initial_lane_count(self) -> int:
        c = self.config
        n = int(c["lanes_count"])
        if c["obstacle"] is not None and c["obstacle"]["position"] < (c["initial_position"] or 0) + 50:
            n -= 1
        return max(n, 1)

    # ------------------------------------------------------------------ build
    def _make_road(self) -> RoadLayout:
        c = self.config
        n = int(c["lanes_count"])
        ends = np.full(n, np.inf)
        if c["lane_drop"] is not None:
            ends[int(c["lane_drop"]["lanes"]):] = float(c["lane_drop"]["position"])
        on, off, obs = [], [], []
        if c["on_ramp"] is not None:
            r = c["on_ramp"]
            on.append(OnRamp(float(r["position"]), float(r["position"]) + float(r["length"]), float(r.get("approach", 300.0))))
        if c["off_ramp"] is not None:
            r = c["off_ramp"]
            s = float(r["position"])
            off.append(OffRamp(s, s + float(r["length"]), s + float(r["length"]) + float(r.get("ramp_length", 150.0))))
        if c["obstacle"] is not None:
            o = c["obstacle"]
            obs.append(Obstacle(int(o["lane"]), float(o["position"]), float(o.get("length", 4.0))))
        return RoadLayout(n, float(c["road_length"]), float(c["lane_width"]), ends, on, off, obs)

    def _expert_params(self) -> ExpertParams:
        c = self.config
        return ExpertParams(
            wheelbase=float(c["wheelbase"]),
            a_min=float(c["acceleration_range"][0]),
            a_max=float(c["acceleration_range"][1]),
            steer_max=math.radians(c["max_steering_deg"]),
            v_min=float(c["speed_range"][0]),
            v_max=float(c["speed_range"][1]),
            desired_speed=float(c["formation"]["speed"]),
            ramp_speed=float(c["ramp_speed"]),
            exit_lookahead=float(c["formation"]["exit_lookahead"]),
            exit_lookahead_per_lane=float(c["formation"]["exit_lookahead_per_lane"]),
            lane_width=float(c["lane_width"]),
        )

    def _reset(self) -> None:
        c = self.config
        road = self._make_road()
        f = c["formation"]
        manager = FormationManager(
            spacing=f["spacing"], geometry=f["geometry"], w1=f["w1"], w2=f["w2"], speed=f["speed"],
            lookahead=f["lookahead"], join_distance=f["join_distance"], exit_lookahead=f["exit_lookahead"],
            exit_lookahead_per_lane=f["exit_lookahead_per_lane"], max_size=max(int(c["formation_size"]), 1) + 4, max_anchor_lead=f["max_anchor_lead"],
        )
        world = World(road, manager, dt=1.0 / c["simulation_frequency"], wheelbase=c["wheelbase"],
                      v_max=float(c["speed_range"][1]))
        self.world = world
        self.expert = FormationExpert(self._expert_params())
        rng = self.np_random
        tr = world.traffic
        exits = {int(k): int(v) for k, v in c["exits"].items()}
        h = 0.5 * c["wheelbase"]
        idx = 0
        for count, anchor, lanes in self._placement():
            tx, tl = manager.targets(count, len(lanes))  # (formation_targets of its spacing and geometry, memoised)
            lane_arr = np.asarray(lanes)[tl - 1]
            cx = anchor - tx + rng.uniform(-1, 1, count) * c["initial_jitter"]
            speed = f["speed"] + rng.uniform(-1, 1, count) * c["initial_speed_jitter"]
            ex = np.array([exits.get(idx + i, -1) for i in range(count)])
            rows_before = tr.n
            tr.add(cx - h, lane_arr * road.lane_width, speed, exit=ex)
            manager.create(tr, np.arange(rows_before, tr.n), road, anchor=anchor)
            idx += count
        self._pending_spawns = sorted(
            (dict(s) for s in c["spawns"]), key=lambda s: (float(s["time"]), float(s["position"]))
        )
        self.possible_agents = [f"icv_{i}" for i in range(int(c["vehicles_count"]) + len(self._pending_spawns))]
        self._spawn_due()
        self._proxies: dict[int, Any] = {}
        self._last_actions = np.zeros((tr.n, 2))
        self._expert_cache = None
        self._ego_vid = int(c["ego_vehicle"])
        self._ego_done = False
        self._render_road_due()

    def _spawn_due(self) -> list[int]:
        if not self._pending_spawns:  # (nothing scheduled: most worlds)
            return []
        w = self.world
        c = self.config
        new = []
        while self._pending_spawns and float(self._pending_spawns[0]["time"]) <= w.time + 1e-9:
            s = self._pending_spawns.pop(0)
            lane = w.road.ramp_lane if s["lane"] == "ramp" else int(s["lane"])
            speed = float(s.get("speed", c["ramp_speed"] if s["lane"] == "ramp" else c["formation"]["speed"]))
            ids = w.traffic.add(float(s["position"]) - 0.5 * c["wheelbase"], lane * w.road.lane_width, speed,
                                exit=int(s.get("exit", -1)), time=w.time)
            new.extend(int(v) for v in ids)
        if new:
            w.invalidate()
        return new

    # ------------------------------------------------- spaces, observations, rewards
    # features, observations, rewards and the one-pass _post_rows:
    # envs/highway_rows.HighwayRows (a mixin, as the intersection's IntersectionRows)

    # ------------------------------------------------------------------ expert
    # expert_actions(): IcvAgentsEnv's, cached on the vehicle state

    # -------------------------------------------------------------- stepping
    # the step itself is IcvAgentsEnv._ma_advance; these are its hooks
    def _new_events(self) -> StepEvents:
        return StepEvents()

    def _after_frames(self) -> None:
        self.world.record_min_gap()

    def _drivers(self, vids, expert_mask, plan_mask) -> None:
        self.world.set_expert_driven(vids, expert_mask, plan_mask)

    def _policy_drivers(self, vids) -> None:
        if own_hooks(self, self._drivers_hook):  # (a replaced _drivers, on a subclass or the instance, hears of it)
            self.world.set_policy_driven()
        else:
            super()._policy_drivers(vids)

    def _react(self, events: StepEvents) -> list:
        # formations react to what happened; new vehicles appear after the
        # others observed (_spawn_late)
        w = self.world
        w.manager.update(w.traffic, w.road, 1.0 / self.config["policy_frequency"])
        return []

    def _departed(self, events: StepEvents) -> dict:
        # exits are terminal successes, the end of the road is a truncation
        if not events.exited and not events.left_road:  # (nobody left: most steps)
            return {}
        return {vid: {"exited": vid in events.exited, "left_road": vid in events.left_road, "crashed": False}
                for vid in events.exited | events.left_road}

    def _spawn_late(self) -> list:
        return self._spawn_due()

    def _ma_info_columns(self, rows, keys: tuple) -> dict:
        """Per-agent info columns (lists aligned with ``rows``), those named
        in ``keys`` (``config["info_keys"]``), in :data:`INFO_KEYS` order."""
        tr = self.world.traffic
        rows = np.asarray(rows, dtype=np.int64)
        cols = {}
        if "speed" in keys:
            cols["speed"] = tr.speed[rows].tolist()
        if "lane" in keys:
            cols["lane"] = self.world.road.lane_of(tr.center()[1])[rows].tolist()
        if "formation" in keys:
            cols["formation"] = tr.group[rows].tolist()
        if "target_lane" in keys:
            lane_ref = np.where(tr.group >= 0, tr.tgt_lane, -1)  # references()' lane_ref, without the profiles
            cols["target_lane"] = lane_ref[rows].tolist()
        if "crashed" in keys:
            cols["crashed"] = [False] * len(rows)
        return cols

    # ------------------------------------------------------- gymnasium (ego)

    # --------------------------------------------------------------- metrics
    def metrics(self, **kwargs) -> dict:
        """Run metrics so far (see :mod:`icv_envs.sim.metrics`)."""
        from icv_envs.sim.metrics import run_metrics

        return run_metrics(self.world)

    # -------------------------------------------------------------- rendering
    def _sync_render_road(self, force: bool = False) -> None:
        """Refresh highway-env objects (road network, vehicle views) from
        the arrays. Only rendering pays for this."""
        from highway_env.road.road import Road
        from highway_env.vehicle.objects import Obstacle as HEObstacle

        from icv_envs.sim.vehicle import ICVVehicle

        w = self.world
        if force or self.road is None or getattr(self, "_road_world", None) is not w:
            self.road = Road(network=w.road.to_network(), np_random=self.np_random, record_history=False)
            for ob in w.road.obstacles:
                o = HEObstacle(self.road, [ob.x, ob.lane * w.road.lane_width])
                o.LENGTH, o.WIDTH = ob.length, ob.width
                self.road.objects.append(o)
            self._road_world = w
            self._proxies = {}
        tr = w.traffic
        cx, cy = tr.center()
        alive = set(int(v) for v in tr.vid)
        for vid in list(self._proxies):
            if vid not in alive:
                del self._proxies[vid]
        vehicles = []
        palette = [(50, 200, 0), (100, 200, 255), (255, 150, 50), (200, 100, 255), (255, 220, 50), (50, 220, 200)]
        for i, vid in enumerate(tr.vid.tolist()):
            p = self._proxies.get(vid)
            if p is None:
                p = self._proxies[vid] = ICVVehicle.proxy(self.road, vid, tr.length[i], tr.width[i])
            p.position = np.array([cx[i], cy[i]])
            p.heading = float(tr.heading[i])
            p.speed = float(tr.speed[i])
            p.crashed = bool(tr.crashed[i])
            p.action = {"steering": float(tr.steer[i]), "acceleration": float(tr.accel[i])}
            g = int(tr.group[i])
            if p.crashed:
                p.color = (255, 100, 100)
            elif not self._ma_mode and vid == self._ego_vid:
                p.color = (50, 200, 0)
            elif g >= 0:
                p.color = palette[1 + g % (len(palette) - 1)]
            else:
                p.color = (200, 200, 200)
            vehicles.append(p)
        self.road.vehicles = vehicles
        ego = self._proxies.get(self._ego_vid) if hasattr(self, "_ego_vid") else None
        if ego is None and vehicles:
            ego = vehicles[int(np.argmax(cx))] if self._ma_mode else vehicles[0]
        self.controlled_vehicles = [ego] if ego is not None else []


# the hooks HighwayRows._post_rows stands for (icv_envs._hooks.own_hooks)
HighwayFormationEnv._post_hooks = hook_table(HighwayFormationEnv, *POST_HOOK_NAMES)
# the hook HighwayFormationEnv._policy_drivers stands for
HighwayFormationEnv._drivers_hook = hook_table(HighwayFormationEnv, "_drivers")
