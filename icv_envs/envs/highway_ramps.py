"""HighwayRamps: the paper's highway experiment (Sec. 6.1, Table 1).

A 10,000 m four-lane road whose end joins its start, plus a ramp lane;
five on-ramps every 2000 m (the first at 0 m; merge segments 100 m) and five
off-ramps every 2000 m (the first at 1600 m; diverge segments 50 m).
Vehicles appear on every on-ramp at the vehicle generating rate (VGR,
vehicles/s per ramp; Poisson or fixed-interval arrivals), each with a random
exit among the off-ramps, and leave the road at their exit. The coordination
method is a config choice:

* ``formation``: the formation layer of :mod:`icv_envs.sim.formations` builds
  interlaced formations on the left three lanes; the fourth lane is a
  transition lane used only to join or leave (paper Sec. 6.1 remark); the
  :class:`~icv_envs.policies.FormationExpert` drives;
* ``lane-lp``: optimal lane assignment at the ramps (Dao et al. 2007, see
  :mod:`icv_envs.policies.lane_lp`), IDM car following;
* ``idm``: IDM/MOBIL, no coordination;
* ``lane-lp-close``, ``idm-close``: the same references at the formation's
  car-following margin (issue 8, equal safety): every vehicle follows with
  the IDM time gap the formation's members keep
  (``ExpertParams.member_time_gap`` = 0.5 s) instead of the free-vehicle 1.0
  s (``ExpertParams.idm_T``), in car following, in lane-change gap
  acceptance and in the LP's lane capacities alike.  The formation drives
  most of its vehicles at that gap, so at the default margins its measured
  5th-percentile time headway is about half the references' (0.62-0.73 s
  against 1.07-1.34 s); the ``-close`` variants compare the methods at
  (nearly) equal margins, the way ``fcfs`` and ``fcfs-tight`` do at the
  intersection.  The default ``lane-lp`` / ``idm`` keep the 1.0 s gap.

Positions: the simulation's ``x = 0`` (the ring's seam) lies at the paper's
1000 m, a plain stretch between the first on-ramp and the first off-ramp, so
no ramp straddles the seam (config ``seam``). Metrics and heat maps are
reported in the paper's coordinates (0 m = first on-ramp).

Ramp vehicles may drive 5..25 m/s on the ramp (desired 15 m/s); main-road
speeds are 15..30 m/s with desired 25 m/s on the left three lanes and 20 m/s
on the fourth (Table 1): ``lane_speeds``.  With another ``lanes_count`` the
same rule gives the defaults (``lane_speeds=None``, ``formation_lanes=None``):
25 m/s on every main lane but the rightmost, 20 m/s there; formations on
every main lane but the rightmost (on the only one when there is one).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from icv_envs.envs._kernels import ramp_spawns_blocked
from icv_envs.envs._config import MAX_AGENTS, _is_real as _is_number, check_unused, num as _num, speed_range
from icv_envs.envs.highway_formation import HighwayFormationEnv
from icv_envs.policies.formation_expert import FormationExpert
from icv_envs.policies.reference import IdmMobilPolicy, LaneLpPolicy
from icv_envs.sim.formations import FormationManager
from icv_envs.sim.road import OffRamp, OnRamp, RoadLayout
from icv_envs.sim.world import World

__all__ = ["HighwayRampsEnv", "METHODS"]

METHODS = ("formation", "lane-lp", "idm", "lane-lp-close", "idm-close")
#: the references whose IDM time gap is the formation members' (``member_time_gap``)
CLOSE_SUFFIX = "-close"
MAX_VGR = 1.0  # vehicles/s per ramp: a single ramp lane carries at most ~0.6 veh/s



def lane_speeds_for(lanes_count: int) -> list[float]:
    """Default desired speeds per main lane (Table 1's rule: 25 m/s, the rightmost 20 m/s)."""
    n = int(lanes_count)
    return [25.0] * (n - 1) + [20.0] if n > 1 else [25.0]


def formation_lanes_for(lanes_count: int) -> list[int]:
    """Default lanes for formations: every main lane but the rightmost (the paper's left three of four)."""
    n = int(lanes_count)
    return list(range(n - 1)) if n > 1 else [0]

class HighwayRampsEnv(HighwayFormationEnv):
    """The 10 km ring with five on/off-ramps; see the module docstring and
    :mod:`icv_envs.envs.highway_ramps_v0`."""

    MIN_VEHICLES = 0

    @classmethod
    def default_config(cls) -> dict:
        config = super().default_config()
        # 600 m for the last lane change onto the ramp lane, 300 m (12 s at the
        # 25 m/s lane speed, four 3 s lane changes) for every further lane to
        # cross: with one 600 m for everybody, vehicles in the two left lanes
        # missed their exit (lane-lp, VGR 1/3, seed 5, 300 s: 17 missed, all
        # from lanes 1-3 counted from the left, none from the lane next to the ramp)
        config["formation"].update({"exit_lookahead": 600.0, "exit_lookahead_per_lane": 300.0,
                                    "join_distance": 60.0})
        config.update(
            {
                "scenario": None,
                "vehicles_count": 0,
                "lanes_count": 4,
                "road_length": 10000.0,
                "ramps": 5,
                "ramp_spacing": 2000.0,
                "first_on_ramp": 0.0,
                "first_off_ramp": 1600.0,
                "merge_length": 100.0,
                "diverge_length": 50.0,
                "on_ramp_approach": 200.0,
                "off_ramp_length": 100.0,
                "seam": 1000.0,
                "vgr": 1.0 / 3.0,
                "arrivals": "poisson",
                "exit_choices": None,
                "method": "formation",
                "max_vehicles": None,
                "duration": 600.0,
                "speed_range": [15.0, 30.0],
                "ramp_speed": 15.0,
                # None: derived from lanes_count (lane_speeds_for / formation_lanes_for)
                "lane_speeds": None,
                "formation_lanes": None,
                "formation_size": 12,
                "sample_period": 1.0,
                "heatmap_bin": 500.0,
                "initial_position": None,
            }
        )
        return config

    # ------------------------------------------------------------- validation
    #: keys of HighwayFormation this env does not use: setting them is an error
    RAMPS_UNUSED = {
        "vehicles_count": "vehicles arrive on the on-ramps at the VGR",
        "initial_position": "vehicles arrive on the on-ramps at the VGR",
        "formation_gap": "no initial formations: vehicles arrive on the on-ramps",
        "initial_jitter": "no initial formations: vehicles arrive on the on-ramps",
        "initial_speed_jitter": "no initial formations: vehicles arrive on the on-ramps",
        "spawns": "vehicles arrive at the VGR",
        "exits": "each arrival draws its exit among exit_choices",
        "lane_drop": "the layout is fixed by 'ramps', 'ramp_spacing', ...",
        "obstacle": "the layout is fixed by 'ramps', 'ramp_spacing', ...",
        "on_ramp": "the layout is fixed by 'ramps', 'ramp_spacing', ...",
        "off_ramp": "the layout is fixed by 'ramps', 'ramp_spacing', ...",
        "scenario": "HighwayRamps has no scenarios",
        "ego_vehicle": "the Gymnasium ego is the first arrival, vehicle 0",
    }

    _AGENTS_FROM = "max_vehicles (default: the mean arrivals over duration x vgr x ramps + 6 sigma + 20)"

    def _n_possible_agents(self) -> int:
        return self._max_vehicles()

    def _apply_config(self, config: dict | None) -> None:
        # HighwayFormation's scenario presets would expand a scenario into
        # keys this env does not use (and blame those): reject it by name first
        if isinstance(config, dict) and config.get("scenario") is not None:
            raise ValueError(f"config['scenario'] = {config['scenario']!r} is not used by HighwayRamps "
                             f"(HighwayRamps has no scenarios; they are HighwayFormation's); leave it at its "
                             f"default None")
        super()._apply_config(config)

    def _validate_config(self) -> None:
        c = self.config
        d = self.default_config()
        unknown_top = set(c) - set(d)
        if unknown_top:
            raise ValueError(f"unknown config keys {sorted(map(str, unknown_top))}; allowed: {sorted(d)}")
        check_unused(c, d, self.RAMPS_UNUSED, "HighwayRamps", self.RAMPS_UNUSED)
        if not isinstance(c["method"], str) or c["method"] not in METHODS:
            raise ValueError(f"unknown method {c['method']!r}; allowed: {list(METHODS)}")
        vgr = c["vgr"]
        if not _is_number(vgr) or not math.isfinite(vgr) or not 0 < vgr <= MAX_VGR:
            raise ValueError(f"vgr = {vgr!r} vehicles/s per ramp is invalid; allowed: 0 < vgr <= {MAX_VGR} "
                             f"(one ramp lane carries at most about 0.6 vehicles/s)")
        if not isinstance(c["arrivals"], str) or c["arrivals"] not in ("poisson", "fixed"):
            raise ValueError(f"arrivals = {c['arrivals']!r}; allowed: 'poisson', 'fixed'")
        L = _num(c, "road_length", 100.0, 1e5, allowed="a number in [100, 100000] metres")
        _num(c, "lanes_count", 1, 6, integer=True, allowed="an integer in [1, 6]")
        n = _num(c, "ramps", 1, 20, integer=True, allowed="an integer in [1, 20]")
        ex = c["exit_choices"]
        if ex is not None:
            if not isinstance(ex, (list, tuple)) or not ex:
                raise ValueError(f"exit_choices = {ex!r}; allowed: None (all exits) or a non-empty list of exit indices")
            bad = [e for e in ex if not (isinstance(e, (int, np.integer)) and not isinstance(e, bool) and 0 <= e < n)]
            if bad:
                raise ValueError(f"exit_choices {bad} do not exist; allowed exit indices: {list(range(n))}")
        for key in ("merge_length", "diverge_length", "on_ramp_approach", "off_ramp_length"):
            _num(c, key, 0.0, L, lo_open=True, allowed=f"a number of metres in (0, road_length = {L:g}]")
        _num(c, "ramp_spacing", 0.0, L / n, lo_open=True,
             allowed=f"a number of metres in (0, road_length / ramps = {L / n:g}] (the ramps repeat around the ring)")
        for key in ("first_on_ramp", "first_off_ramp", "seam"):
            _num(c, key, 0.0, L, allowed=f"a position in [0, road_length = {L:g}) metres (paper coordinates)")
            if c[key] >= L:
                raise ValueError(f"config[{key!r}] = {c[key]!r} is invalid; allowed: a position in "
                                 f"[0, road_length = {L:g}) metres (paper coordinates)")
        _num(c, "sample_period", 0.0, 3600.0, lo_open=True, allowed="a number of seconds in (0, 3600]")
        _num(c, "heatmap_bin", 1.0, L, allowed=f"a number of metres in [1, road_length = {L:g}]")
        sr = speed_range(c)
        ls = c["lane_speeds"]
        if ls is not None and not (isinstance(ls, (list, tuple)) and len(ls) == c["lanes_count"] and all(
                _is_number(v) and 0 < v <= sr[1] for v in ls)):
            raise ValueError(f"lane_speeds = {ls!r}; allowed: None (derived from lanes_count) or one speed in "
                             f"(0, v_max = {sr[1]:g}] per main lane (lanes_count = {c['lanes_count']!r})")
        if ls is None and max(lane_speeds_for(c["lanes_count"])) > sr[1]:
            raise ValueError(f"speed_range = {c['speed_range']!r}: the default lane speeds "
                             f"{lane_speeds_for(c['lanes_count'])} exceed its v_max; allowed: v_max >= 25, "
                             f"or give lane_speeds")
        fl = c["formation_lanes"]
        if fl is not None and not (isinstance(fl, (list, tuple)) and fl and all(
                isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 0 <= v < c["lanes_count"]
                for v in fl)):
            raise ValueError(f"formation_lanes = {fl!r}; allowed: None (derived from lanes_count) or a non-empty "
                             f"list of lane indices in [0, {c['lanes_count'] - 1}] (lanes_count = "
                             f"{c['lanes_count']!r})")
        mv = c["max_vehicles"]
        if mv is not None and not (isinstance(mv, (int, np.integer)) and not isinstance(mv, bool)
                                   and 1 <= mv <= MAX_AGENTS):
            raise ValueError(f"max_vehicles = {mv!r}; allowed: None (automatic) or an integer in [1, {MAX_AGENTS}] "
                             f"(MAX_AGENTS)")
        super()._validate_config()
        self._make_road()  # raises if the layout does not fit the ring

    def _placement(self):
        return []

    # ------------------------------------------------------------------ build
    def _internal(self, paper_x: float) -> float:
        c = self.config
        return float(np.mod(paper_x - c["seam"], c["road_length"]))

    def paper_position(self, x) -> np.ndarray:
        """Simulation x -> the paper's coordinates (0 m = the first on-ramp)."""
        c = self.config
        return np.mod(np.asarray(x) + c["seam"], c["road_length"])

    def _make_road(self) -> RoadLayout:
        c = self.config
        n, sp = int(c["ramps"]), float(c["ramp_spacing"])
        on = []
        off = []
        for k in range(n):
            s = self._internal(c["first_on_ramp"] + k * sp)
            on.append(OnRamp(s, s + c["merge_length"], c["on_ramp_approach"]))
            d = self._internal(c["first_off_ramp"] + k * sp)
            off.append(OffRamp(d, d + c["diverge_length"], d + c["diverge_length"] + c["off_ramp_length"]))
        return RoadLayout(int(c["lanes_count"]), float(c["road_length"]), float(c["lane_width"]),
                          np.full(int(c["lanes_count"]), np.inf), on, off, [], periodic=True)

    def _expert_params(self):
        p = super()._expert_params()
        c = self.config
        speeds = lane_speeds_for(c["lanes_count"]) if c["lane_speeds"] is None else c["lane_speeds"]
        p.lane_speeds = tuple(float(v) for v in speeds) + (float(c["ramp_speed"]),)
        p.exit_speed = float(speeds[-1])
        return p

    def _max_vehicles(self) -> int:
        c = self.config
        if c["max_vehicles"] is not None:
            return int(c["max_vehicles"])
        mean = c["duration"] * c["vgr"] * c["ramps"]
        return int(math.ceil(mean + 6.0 * math.sqrt(mean) + 20))

    ARRIVAL_CHUNK = 256  # arrivals drawn per block from each ramp's streams

    def _ramp_arrivals(self, rng: np.random.Generator) -> list[tuple[float, int, int]]:
        """Arrivals ``(time, ramp, exit)`` before ``duration``: per ramp,
        Poisson (exponential gaps) or a fixed interval with a random phase;
        the first arrival at ramp 0 is at t = 0 (the Gymnasium ego).

        Each ramp draws its gaps and its exits from two streams of its own,
        seeded by a fixed number of draws from the env's RNG and consumed in
        blocks of :attr:`ARRIVAL_CHUNK`, so the traffic does not depend on
        ``duration``: a shorter episode is a prefix of a longer one."""
        c = self.config
        T, vgr, n = float(c["duration"]), float(c["vgr"]), int(c["ramps"])
        choices = np.asarray(list(range(n)) if c["exit_choices"] is None else [int(e) for e in c["exit_choices"]])
        seeds = rng.integers(0, 2**63 - 1, size=(n, 2))
        B = self.ARRIVAL_CHUNK
        arrivals = []
        for k in range(n):
            g_t, g_e = np.random.default_rng(int(seeds[k, 0])), np.random.default_rng(int(seeds[k, 1]))
            blocks = [np.zeros(1)] if k == 0 and c["arrivals"] == "poisson" else []
            base = 0.0
            phase = float(g_t.uniform(0.0, 1.0 / vgr)) if k and c["arrivals"] == "fixed" else 0.0
            j = 0
            while not blocks or blocks[-1][-1] < T:
                if c["arrivals"] == "poisson":
                    times = base + np.cumsum(g_t.exponential(1.0 / vgr, size=B))
                    base = float(times[-1])
                else:
                    times = phase + (j * B + np.arange(B)) / vgr
                blocks.append(times)
                j += 1
            times = np.concatenate(blocks)
            times = times[times < T]
            nb = -(-len(times) // B)
            exits = choices[np.concatenate([g_e.integers(0, len(choices), size=B) for _ in range(max(nb, 1))])]
            arrivals += [(float(t), k, int(e)) for t, e in zip(times, exits)]
        return arrivals

    def _reset(self) -> None:
        c = self.config
        road = self._make_road()
        f = c["formation"]
        method = c["method"]
        manager = FormationManager(
            spacing=f["spacing"], geometry=f["geometry"], w1=f["w1"], w2=f["w2"], speed=f["speed"],
            lookahead=f["lookahead"], join_distance=f["join_distance"], exit_lookahead=f["exit_lookahead"],
            exit_lookahead_per_lane=f["exit_lookahead_per_lane"], max_size=int(c["formation_size"]), max_anchor_lead=f["max_anchor_lead"],
            allowed_lanes=(formation_lanes_for(c["lanes_count"]) if c["formation_lanes"] is None
                           else c["formation_lanes"]), create=(method == "formation"),
        )
        self.world = World(road, manager, dt=1.0 / c["simulation_frequency"], wheelbase=c["wheelbase"],
                           v_max=float(c["speed_range"][1]))
        params = self._expert_params()
        if method.endswith(CLOSE_SUFFIX):
            # equal margins: the references follow at the gap formation members keep
            params = dataclasses.replace(params, idm_T=params.member_time_gap)
            method = method[: -len(CLOSE_SUFFIX)]
        self.expert = {"formation": FormationExpert, "idm": IdmMobilPolicy, "lane-lp": LaneLpPolicy}[method](params)
        arrivals = self._ramp_arrivals(self.np_random)
        arrivals.sort()
        cap = self._max_vehicles()
        self._not_spawned = max(0, len(arrivals) - cap)
        self._arrivals = arrivals[:cap]
        self._queues: list[list[tuple[float, int]]] = [[] for _ in range(int(c["ramps"]))]
        self._spawned = 0
        self.possible_agents = [f"icv_{i}" for i in range(cap)]
        self._series: list[dict] = []
        self._heat_sum = None
        self._heat_samples = 0
        self._next_sample = 0.0
        self._spawn_due()
        self._proxies = {}
        self._last_actions = np.zeros((self.world.traffic.n, 2))
        self._expert_cache = None
        self._ego_vid = int(c["ego_vehicle"])
        self._ego_done = False
        self._record()
        self._render_road_due()

    # ---------------------------------------------------------------- arrivals
    def _spawn_due(self) -> list[int]:
        w = self.world
        c = self.config
        road = w.road
        tr = w.traffic
        while self._arrivals and self._arrivals[0][0] <= w.time + 1e-9:
            t, k, e = self._arrivals.pop(0)
            self._queues[k].append((t, e))
        new = []
        if not any(self._queues):
            return new
        x0s = self._spawn_points(road)
        h = 0.5 * c["wheelbase"]
        blocked = None
        for k, q in enumerate(self._queues):
            if not q:
                continue
            x0 = float(x0s[k])
            # the spawn point must be free: nobody on the ramp lane within (-10, +25) m
            # (every ramp's test in one compiled call, again after each spawn: envs/_kernels.ramp_spawns_blocked)
            if blocked is None:
                cx, cy = tr.center()
                blocked = ramp_spawns_blocked(cx, cy, float(road.lane_width), int(road.total_lanes),
                                              int(road.ramp_lane), x0s,
                                              float(road.length) if road.periodic else -1.0, -10.0, 25.0)
            if blocked[k]:
                continue
            t, e = q.pop(0)
            ids = tr.add(x0 - h, road.ramp_lane * road.lane_width, float(c["ramp_speed"]), exit=e, time=w.time)
            new.extend(int(v) for v in ids)
            self._spawned += 1
            blocked = None
        if new:
            w.invalidate()
        return new

    def _spawn_points(self, road) -> np.ndarray:
        """Each on-ramp's spawn point (the vehicle's front, 5 m into the
        ramp's approach), read-only, kept per road (a reset builds a new one)."""
        kept = getattr(self, "_spawn_points_kept", None)
        if kept is not None and kept[0] is road:
            return kept[1]
        x0s = np.array([r.start - r.approach + 5.0 for r in road.on_ramps], dtype=np.float64)
        x0s.setflags(write=False)
        self._spawn_points_kept = (road, x0s)
        return x0s

    # --------------------------------------------------------------- metrics
    def _on_step_end(self, events) -> None:
        if self.world.time + 1e-9 >= self._next_sample:
            self._record()

    def _record(self) -> None:
        c = self.config
        w = self.world
        tr = w.traffic
        road = w.road
        st = w.stats
        cx, cy = tr.center()
        lane = road.lane_of(cy) if tr.n else np.zeros(0, dtype=np.int64)
        main = lane < road.n_lanes
        nb = int(math.ceil(c["road_length"] / c["heatmap_bin"]))
        heat = np.zeros((road.n_lanes, nb))
        if main.any():
            b = np.minimum((self.paper_position(cx[main]) // c["heatmap_bin"]).astype(int), nb - 1)
            np.add.at(heat, (lane[main], b), 1.0)
        self._heat_sum = heat if self._heat_sum is None else self._heat_sum + heat
        self._heat_samples += 1
        self._heat_last = heat
        self._series.append(
            {
                "t": round(w.time, 6),
                "remaining": int(tr.n),
                "queued": int(sum(len(q) for q in self._queues)),
                "mean_speed": float(tr.speed.mean()) if tr.n else None,
                "mean_abs_accel": float(np.abs(tr.accel).mean()) if tr.n else None,
                "spawned": int(self._spawned),
                "exited": int(st["exited"]),
                "missed_exits": int(st["missed_exits"]),
                "collisions": int(st["collisions"]),
                "stopped": int((tr.speed < 0.1).sum()),
                "jammed": int(st["jammed"]),
                "formations": w.manager.n_formations,
            }
        )
        self._next_sample += float(c["sample_period"])

    def metrics(self, series: bool = False) -> dict:
        """Run totals (and with ``series`` the 1 Hz time series and heat maps).

        ``lost`` = spawned - exited - remaining - removed after a crash: a
        bookkeeping check that must be 0 (no vehicle disappears unaccounted)."""
        from icv_envs.sim.metrics import run_metrics

        m = run_metrics(self.world)
        st = self.world.stats
        remaining = int(self.world.traffic.n)
        m.update(
            {
                "method": self.config["method"],
                "vgr": float(self.config["vgr"]),
                "spawned": int(self._spawned),
                "remaining": remaining,
                "queued": int(sum(len(q) for q in self._queues)),
                "not_spawned": int(self._not_spawned),
                "missed_exits": int(st["missed_exits"]),
                "crashed_removed": int(st["crashed_removed"]),
                "lost": int(self._spawned - st["exited"] - remaining - st["crashed_removed"]),
            }
        )
        if series:
            m["timeseries"] = list(self._series)
            m["heatmap_mean"] = (self._heat_sum / max(self._heat_samples, 1)).round(4).tolist()
            m["heatmap_final"] = self._heat_last.tolist()
            m["heatmap_bin"] = float(self.config["heatmap_bin"])
        return m
