"""The highway envs' configuration (:class:`icv_envs.envs.highway_formation.HighwayFormationEnv`,
and through it :class:`~icv_envs.envs.highway_ramps.HighwayRampsEnv`): their
keys over highway-env's defaults (:func:`config_entries`, documented in
:mod:`icv_envs.envs.highway_formation_v0`) and their checks
(:func:`check_config`), each error naming the key, the bad value and what is
allowed. Whether the vehicles fit on the road the config describes is
checked by the env (its placement)."""

from __future__ import annotations

import numpy as np
from highway_env.envs.common.abstract import AbstractEnv

from icv_envs.envs._config import (
    MAX_AGENTS,
    MAX_DURATION,
    UNUSED_COMMON,
    accel_range,
    check_keys,
    check_possible_agents,
    check_render,
    check_unused,
    flag,
    info_keys,
    num as _num,
    section,
    speed_range,
)

__all__ = ["INFO_KEYS", "VEHICLE_LENGTH", "JAM_DISTANCE", "UNUSED_KEYS", "config_entries", "check_config"]

#: The per-step keys of an agent's info dict, in their order (``info_keys``
#: selects among them; ``expert_action`` is switched by ``expert_in_info``)
INFO_KEYS = ("speed", "lane", "formation", "target_lane", "crashed", "rewards")

_FORMATION_DEFAULTS = {
    "geometry": "interlaced",
    "spacing": 20.0,
    "w1": 1.0,
    "w2": 10.0,
    "speed": 25.0,
    "lookahead": 200.0,
    "join_distance": 60.0,
    "exit_lookahead": 400.0,
    "exit_lookahead_per_lane": 0.0,
    "max_anchor_lead": 15.0,
}
#: body length of every vehicle [m] (paper Table 1) and the IDM jam distance s0 [m]
VEHICLE_LENGTH = 5.0
JAM_DISTANCE = 2.0
_REWARD_DEFAULTS = {"progress": 0.4, "safety": 1.0, "comfort": 0.1, "formation": 0.5}

#: highway-env keys these envs do not use: setting them is an error
UNUSED_KEYS = {
    "other_vehicles_type": "every vehicle is an ICV driven by the env's expert or an agent",
    **UNUSED_COMMON,
}


def config_entries() -> dict:
    """The env's own config keys and their defaults (over highway-env's)."""
    return {
        "scenario": "free",
        "lanes_count": 4,
        "lane_width": 4.0,
        "road_length": 2000.0,
        "lane_drop": None,
        "obstacle": None,
        "on_ramp": None,
        "off_ramp": None,
        "vehicles_count": 8,
        "formation_size": 12,
        "formation_gap": 60.0,
        "initial_position": None,
        "initial_jitter": 1.5,
        "initial_speed_jitter": 1.0,
        "spawns": [],
        "exits": {},
        "formation": dict(_FORMATION_DEFAULTS),
        "speed_range": [10.0, 30.0],
        "ramp_speed": 15.0,
        "acceleration_range": [-6.0, 3.0],
        "max_steering_deg": 30.0,
        "wheelbase": 2.8,
        "simulation_frequency": 25,
        "policy_frequency": 5,
        "duration": 60.0,
        "ego_vehicle": 0,
        "observation": {"type": "Kinematics", "vehicles_count": 8, "perception_distance": 150.0},
        "action": {"type": "ContinuousAction"},
        "reward": dict(_REWARD_DEFAULTS),
        "expert_in_info": True,
        "info_keys": None,
        "expert_driven_check": True,
        "missing_action": "error",
        "show_formation": True,
        "show_overlay": True,
        "screen_width": 1200,
        "screen_height": 260,
        "scaling": 4.0,
        "centering_position": [0.5, 0.5],
    }


def check_config(c: dict, known: dict, env_name: str, unused_keys: dict, min_vehicles: int, validate_spaces,
                 n_possible_agents, agents_from: str) -> None:
    """Every key of ``c`` checked, in the order a user meets the errors:
    unknown and unused keys, the sections, then key by key. ``known``: the
    env's defaults; ``min_vehicles``: the least ``vehicles_count`` (0 on the
    ramps' open road, whose vehicles arrive); ``validate_spaces()`` checks the
    observation and action configs; ``n_possible_agents()`` counts the agents
    the config asks for (``agents_from`` says from what, in the error)."""
    unknown_top = set(c) - set(known)
    if unknown_top:
        raise ValueError(f"unknown config keys {sorted(map(str, unknown_top))}; allowed: {sorted(known)}")
    check_unused(c, AbstractEnv.default_config(), unused_keys, env_name, unused_keys)
    for key in ("formation", "reward", "observation", "action", "exits"):
        section(c, key)
    for key in ("lane_drop", "obstacle", "on_ramp", "off_ramp"):
        section(c, key, optional=True)
    n_lanes = _num(c, "lanes_count", 1, 6, integer=True, allowed="an integer in [1, 6]")
    _num(c, "lane_width", 2.5, 6.0, allowed="a number in [2.5, 6] metres")
    L = _num(c, "road_length", 100.0, 1e5, allowed="a number in [100, 100000] metres")
    _num(c, "vehicles_count", min_vehicles, 5000, integer=True,
         allowed=f"an integer in [{min_vehicles}, 5000]")
    _num(c, "formation_size", 1, 64, integer=True, allowed="an integer in [1, 64]")
    _num(c, "formation_gap", 0.0, L, allowed=f"a number of metres in [0, road_length = {L:g}]")
    _num(c, "initial_jitter", 0.0, 5.0, allowed="a number in [0, 5] metres")
    _num(c, "initial_speed_jitter", 0.0, 5.0, allowed="a number in [0, 5] m/s")
    _num(c, "simulation_frequency", 0, 1000, lo_open=True, integer=True, allowed="an integer in (0, 1000] [Hz]")
    _num(c, "policy_frequency", 0, 1000, lo_open=True, integer=True, allowed="an integer in (0, 1000] [Hz]")
    if c["simulation_frequency"] % c["policy_frequency"]:
        raise ValueError(
            f"policy_frequency={c['policy_frequency']} must divide simulation_frequency={c['simulation_frequency']}"
        )
    T = _num(c, "duration", 0.0, MAX_DURATION, lo_open=True,
             allowed=f"a number of seconds in (0, {MAX_DURATION:g}] (MAX_DURATION, one simulated day)")
    _num(c, "wheelbase", 0.5, 10.0, allowed="a number in [0.5, 10] metres")
    _num(c, "max_steering_deg", 0.0, 60.0, lo_open=True, allowed="a number in (0, 60] degrees")
    sr = speed_range(c)
    _num(c, "ramp_speed", 0.0, sr[1], lo_open=True, allowed=f"a number in (0, v_max = {sr[1]:g}] m/s")
    accel_range(c)
    f = c["formation"]
    check_keys(f, "formation", _FORMATION_DEFAULTS)
    if f["geometry"] not in ("interlaced", "parallel"):
        raise ValueError(f"formation geometry {f['geometry']!r} is invalid; allowed: 'interlaced', 'parallel'")
    _num(f, "spacing", 0.0, 1000.0, lo_open=True, allowed="a number > 0 metres (at most 1000)", where="['formation']")
    # two targets in one lane are ``spacing`` apart (one lane, or the
    # parallel geometry): the bodies (5 m) plus the IDM jam distance s0
    # (2 m) must fit, even after the initial jitter moved both towards
    # each other
    min_spacing = VEHICLE_LENGTH + JAM_DISTANCE + 2.0 * float(c["initial_jitter"])
    if f["spacing"] < min_spacing:
        raise ValueError(
            f"formation.spacing = {f['spacing']} m is below the physical minimum {min_spacing:g} m "
            f"(vehicle length {VEHICLE_LENGTH:g} m + jam distance s0 {JAM_DISTANCE:g} m + "
            f"2 x initial_jitter {c['initial_jitter']} m): vehicles one target apart in a lane would overlap"
        )
    _num(f, "w1", 0.0, 1e6, allowed="a number in [0, 1e6]", where="['formation']")
    _num(f, "w2", 0.0, 1e6, allowed="a number in [0, 1e6]", where="['formation']")
    _num(f, "speed", sr[0], sr[1], allowed=f"a number within speed_range {list(sr)}", where="['formation']")
    for k in ("lookahead", "join_distance", "exit_lookahead", "exit_lookahead_per_lane", "max_anchor_lead"):
        _num(f, k, 0.0, 1e5, allowed="a number in [0, 100000] metres", where="['formation']")
    r = c["reward"]
    check_keys(r, "reward", _REWARD_DEFAULTS)
    for k in _REWARD_DEFAULTS:
        _num(r, k, -1e6, 1e6, allowed="a finite number in [-1e6, 1e6]", where="['reward']")
    validate_spaces()
    if c["missing_action"] not in ("error", "expert"):
        raise ValueError(f"config['missing_action'] = {c['missing_action']!r}; allowed: 'error', 'expert'")
    flag(c, "expert_in_info")
    info_keys(c, INFO_KEYS)
    flag(c, "expert_driven_check")
    check_render(c, flags=("show_formation", "show_overlay"))
    if c["lane_drop"] is not None:
        d = c["lane_drop"]
        check_keys(d, "lane_drop", {"position", "lanes"}, {"position", "lanes"})
        _num(d, "position", 0.0, L, allowed=f"a position in [0, road_length={L}]", where="['lane_drop']")
        _num(d, "lanes", 1, n_lanes - 1 if n_lanes > 1 else 0, integer=True,
             allowed=f"an integer in [1, lanes_count - 1 = {n_lanes - 1}]", where="['lane_drop']")
    if c["obstacle"] is not None:
        d = c["obstacle"]
        check_keys(d, "obstacle", {"lane", "position", "length"}, {"lane", "position"})
        _num(d, "lane", 0, n_lanes - 1, integer=True, allowed=f"a lane index in [0, {n_lanes - 1}]",
             where="['obstacle']")
        _num(d, "position", 0.0, L, allowed=f"a position in [0, road_length={L}]", where="['obstacle']")
        if "length" in d:
            _num(d, "length", 0.0, L, lo_open=True, allowed=f"a number of metres in (0, road_length={L:g}]",
                 where="['obstacle']")
    for key, extra in (("on_ramp", "approach"), ("off_ramp", "ramp_length")):
        if c[key] is not None:
            d = c[key]
            check_keys(d, key, {"position", "length", extra}, {"position", "length"})
            _num(d, "position", 0.0, L, allowed=f"a position in [0, road_length={L}]", where=f"[{key!r}]")
            _num(d, "length", 0.0, L, lo_open=True, allowed=f"a number of metres in (0, road_length={L:g}]",
                 where=f"[{key!r}]")
            if extra in d:
                _num(d, extra, 0.0, L, lo_open=True, allowed=f"a number of metres in (0, road_length={L:g}]",
                     where=f"[{key!r}]")
    n_exits = 1 if c["off_ramp"] is not None else 0
    exits = c["exits"]
    for k, e in exits.items():
        if not (isinstance(k, (int, np.integer, str)) and not isinstance(k, bool) and str(k).isdigit()
                and int(k) < c["vehicles_count"]):
            raise ValueError(f"exits key {k!r} is not a vehicle index in [0, {c['vehicles_count'] - 1}]")
        if not (isinstance(e, (int, np.integer)) and not isinstance(e, bool) and 0 <= e < n_exits):
            why = "" if n_exits else " (this road has no off-ramp: set config['off_ramp'] or a scenario with one)"
            raise ValueError(f"config['exits'][{k!r}] = {e!r}: exit {e!r} for vehicle {k} does not exist; "
                             f"allowed exit indices: {list(range(n_exits))}{why}")
    if not isinstance(c["spawns"], (list, tuple)):
        raise ValueError(f"config['spawns'] = {c['spawns']!r}; allowed: a list of dicts")
    if len(c["spawns"]) > MAX_AGENTS:
        raise ValueError(f"config['spawns'] has {len(c['spawns'])} entries; allowed: at most {MAX_AGENTS}")
    for i, s in enumerate(c["spawns"]):
        where = f"['spawns'][{i}]"
        if not isinstance(s, dict):
            raise ValueError(f"config{where} = {s!r} is invalid; allowed: a dict with 'time', 'position', "
                             f"'lane'[, 'speed', 'exit']")
        check_keys(s, f"spawns[{i}]", {"time", "position", "lane", "speed", "exit"}, {"time", "position", "lane"})
        _num(s, "time", 0.0, T, allowed=f"a number of seconds in [0, duration = {T:g}]", where=where)
        _num(s, "position", 0.0, L, allowed=f"a position in [0, road_length={L}]", where=where)
        if isinstance(s["lane"], str) and s["lane"] == "ramp":
            if c["on_ramp"] is None:
                raise ValueError("spawn lane 'ramp' needs an on_ramp in the config")
        else:
            _num(s, "lane", 0, n_lanes - 1, integer=True, allowed=f"'ramp' or a lane index in [0, {n_lanes - 1}]",
                 where=where)
        if "speed" in s:
            _num(s, "speed", 0.0, sr[1], allowed=f"a number in [0, {sr[1]}] m/s", where=where)
        if "exit" in s:
            _num(s, "exit", -1, n_exits - 1, integer=True,
                 allowed=f"-1 (no exit) or an exit index in {list(range(n_exits))}", where=where)
    check_possible_agents(n_possible_agents(), agents_from)
    ego = c["ego_vehicle"]
    if min_vehicles and not (isinstance(ego, (int, np.integer)) and not isinstance(ego, bool)
                                  and 0 <= ego < c["vehicles_count"]):
        raise ValueError(f"config['ego_vehicle'] = {ego!r}; allowed: an index in [0, vehicles_count - 1 = {c['vehicles_count'] - 1}]")
    ip = c["initial_position"]
    if ip is not None:
        _num(c, "initial_position", 0.0, L, allowed=f"None (automatic) or a position in [0, road_length={L:g}]")
