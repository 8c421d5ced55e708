"""The Intersection env's configuration (:class:`icv_envs.envs.intersection.IntersectionEnv`):
its own keys over highway-env's defaults (:func:`config_entries`, documented
in :mod:`icv_envs.envs.intersection_v0`) and their checks
(:func:`check_config`), each error naming the key, the bad value and what is
allowed. The geometry the config describes (the layout, the tree-layer gap
``D_t``) is built and checked by the env."""

from __future__ import annotations

import math

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
    is_speed_pair,
    num as _num,
    section,
    speed_range,
)
from icv_envs.platoon.geometry import LANE_USE_PRESETS

__all__ = ["INFO_KEYS", "METHODS", "FCFS_TIGHT", "MAX_THROUGHPUT", "UNUSED_KEYS", "config_entries", "check_config"]

METHODS = ("multi-vp", "single-vp", "fcfs", "fcfs-tight")
#: FCFS reservation buffers of the method ``fcfs-tight`` (the buffers of the
#: first implementation: 5 steps = 0.2 s, 0.5 m; "tight" is its historical
#: name: by PET it is the MORE cautious variant, see ``_FCFS_DEFAULTS``), kept
#: so the effect of the margin is visible; ``fcfs`` uses ``_FCFS_DEFAULTS``
FCFS_TIGHT = {"time_buffer": 5, "space_buffer": 0.5}
MAX_THROUGHPUT = 20000.0  # veh/h: beyond any lane's capacity; a sanity bound for the config

#: The per-step keys of an agent's info dict, in their order (``info_keys``
#: selects among them; ``expert_action`` is switched by ``expert_in_info``)
INFO_KEYS = ("speed", "movement", "distance", "node", "tree_layer", "crashed", "rewards")

_REWARD_DEFAULTS = {"progress": 0.4, "safety": 1.0, "comfort": 0.1, "tracking": 0.5}
#: Reservation parameters of ``fcfs``.  Buffers chosen so that FCFS's measured
#: minimum PET is as close as the tile reservation allows to the virtual
#: platoon's (issue 8, "equal safety"): at 2500 veh/h, seed 0, 300 s,
#: multi-vp's minimum PET is 0.20 s (single-vp 0.08 s), FCFS's 0.24 s with no
#: buffer, 0.44 s with 0 s / 0.5 m and 0.60 s (seed 2) with 0.2 s / 0.5 m
#: (``fcfs-tight``): the virtual platoon's D_t = 21 m is the tighter margin,
#: so the fair FCFS has no extra buffer (the 1 m tiles, the footprint grown
#: by the 0.1 m lookup step, remain).
_FCFS_DEFAULTS = {"tile": 1.0, "time_buffer": 0, "space_buffer": 0.0, "request_distance": 80.0, "a_plan": 1.5}
_OBS_DEFAULTS = {"type": "Kinematics", "vehicles_count": 8, "perception_distance": 100.0}
#: highway-env keys this env does not use: setting them is an error
UNUSED_KEYS = {
    "other_vehicles_type": "every vehicle is driven by the env's method or an agent",
    **UNUSED_COMMON,
}


def config_entries() -> dict:
    """The env's own config keys and their defaults (over highway-env's)."""
    return {
        "method": "multi-vp",
        "lane_use": "paper",
        "throughput": 1500.0,
        "turn_shares": [1 / 3, 1 / 3, 1 / 3],
        "arrivals": "poisson",
        "formation_size": 6,
        "R1": 300.0,
        "R2": 500.0,
        "R3": 800.0,
        "lane_width": 4.0,
        "box_half": 16.0,
        "departure_length": 40.0,
        "opposing_left_conflict": False,
        "D_t": "auto",
        "desired_speed": 10.0,
        "speed_range": [0.0, 20.0],
        "acceleration_range": [-6.0, 3.0],
        "max_steering_deg": 30.0,
        "wheelbase": 2.8,
        "gap_outside": 15.0,
        "gap_inside": 9.0,
        "merge_range": 60.0,
        "max_node_size": 12,
        "fcfs": dict(_FCFS_DEFAULTS),
        "envelope_in_box": True,
        "vp_anticipation": True,
        "vp_zone_advisory": True,
        "simulation_frequency": 25,
        "policy_frequency": 5,
        "duration": 120.0,
        "warmup": 0.0,
        "max_vehicles": None,
        "observation": dict(_OBS_DEFAULTS),
        "action": {"type": "ContinuousAction"},
        "reward": dict(_REWARD_DEFAULTS),
        "reward_speed_range": None,
        "expert_in_info": True,
        "info_keys": None,
        "expert_driven_check": True,
        "missing_action": "error",
        "show_zones": True,
        "show_groups": True,
        "show_overlay": True,
        "screen_width": 900,
        "screen_height": 900,
        "scaling": 0.54,  # px/m: 900 px show +-833 m, the scene out to R3 = 800 m
        "centering_position": [0.5, 0.5],
    }


def check_config(c: dict, known: dict, validate_spaces, n_possible_agents) -> None:
    """Every key of ``c`` checked, in the order a user meets the errors:
    unknown and unused keys, the sections, then key by key;
    ``validate_spaces()`` checks the observation and action configs and
    ``n_possible_agents()`` counts the agents the config asks for."""
    unknown = set(c) - set(known)
    if unknown:
        raise ValueError(f"unknown config keys {sorted(map(str, unknown))}; allowed: {sorted(known)}")
    check_unused(c, AbstractEnv.default_config(), UNUSED_KEYS, "IntersectionEnv", UNUSED_KEYS)
    for key in ("fcfs", "reward", "observation", "action"):
        section(c, key)
    if not isinstance(c["method"], str) or c["method"] not in METHODS:
        raise ValueError(f"unknown method {c['method']!r}; allowed: {list(METHODS)}")
    lu = c["lane_use"]
    if not isinstance(lu, (str, dict)):
        raise ValueError(f"config['lane_use'] = {lu!r} is invalid; allowed: one of {list(LANE_USE_PRESETS)} "
                         f"or a dict movement -> lanes")
    if isinstance(lu, str) and lu not in LANE_USE_PRESETS:
        raise ValueError(f"unknown lane_use {lu!r}; allowed: {list(LANE_USE_PRESETS)} or a dict movement -> lanes")
    tp = c["throughput"]
    if isinstance(tp, bool) or not isinstance(tp, (int, float, np.integer, np.floating)) or not math.isfinite(tp) \
            or not 0 < tp <= MAX_THROUGHPUT:
        raise ValueError(f"throughput = {tp!r} vehicles/h is invalid; allowed: a number in (0, {MAX_THROUGHPUT:g}] "
                         f"(vehicles per hour entering the intersection, all legs)")
    sh = c["turn_shares"]
    if not (isinstance(sh, (list, tuple)) and len(sh) == 3
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0 for v in sh)
            and sum(sh) > 0):
        raise ValueError(f"turn_shares = {sh!r}; allowed: three numbers >= 0 (left, straight, right) with a positive sum")
    if not isinstance(c["arrivals"], str) or c["arrivals"] not in ("poisson", "fixed"):
        raise ValueError(f"arrivals = {c['arrivals']!r}; allowed: 'poisson', 'fixed'")
    _num(c, "formation_size", 1, 30, integer=True, allowed="an integer in [1, 30]")
    for k in ("R1", "R2", "R3"):
        _num(c, k, 0.0, 1e5, lo_open=True, allowed="a number of metres in (0, 100000]")
    _num(c, "lane_width", 2.5, 6.0, allowed="a number in [2.5, 6] metres")
    _num(c, "box_half", 3 * c["lane_width"], 100.0, allowed=f"a number in [3 * lane_width = {3 * c['lane_width']:g}, 100] metres")
    _num(c, "departure_length", 5.0, 1000.0, allowed="a number in [5, 1000] metres")
    if not isinstance(c["opposing_left_conflict"], (bool, np.bool_)):
        raise ValueError(f"config['opposing_left_conflict'] = {c['opposing_left_conflict']!r}; allowed: True or False")
    if not (isinstance(c["D_t"], str) and c["D_t"] == "auto"):
        _num(c, "D_t", 0.0, 500.0, lo_open=True, allowed="'auto' or a number of metres in (0, 500]")
    sr = speed_range(c)
    _num(c, "desired_speed", 0.0, sr[1], lo_open=True, allowed=f"a number in (0, v_max = {sr[1]}] m/s")
    ar = accel_range(c)
    _num(c, "max_steering_deg", 0.0, 60.0, lo_open=True, allowed="a number in (0, 60] degrees")
    _num(c, "wheelbase", 0.5, 10.0, allowed="a number in [0.5, 10] metres")
    _num(c, "gap_outside", 0.0, 100.0, lo_open=True, allowed="a number in (0, 100] metres")
    _num(c, "gap_inside", 0.0, 100.0, lo_open=True, allowed="a number in (0, 100] metres")
    _num(c, "merge_range", 0.0, 1000.0, allowed="a number in [0, 1000] metres")
    _num(c, "max_node_size", 1, 100, integer=True, allowed="an integer in [1, 100]")
    fc = c["fcfs"]
    check_keys(fc, "fcfs", _FCFS_DEFAULTS)
    _num(fc, "tile", 0.1, 5.0, allowed="a number in [0.1, 5] metres", where="['fcfs']")
    _num(fc, "time_buffer", 0, 100, integer=True, allowed="an integer number of steps in [0, 100]", where="['fcfs']")
    _num(fc, "space_buffer", 0.0, 5.0, allowed="a number in [0, 5] metres", where="['fcfs']")
    _num(fc, "request_distance", 1.0, 1000.0, allowed="a number in [1, 1000] metres", where="['fcfs']")
    _num(fc, "a_plan", 0.0, ar[1], lo_open=True, allowed=f"a number in (0, a_max = {ar[1]}] m/s^2", where="['fcfs']")
    if c["method"] == "fcfs-tight":
        own = {k: fc[k] for k in FCFS_TIGHT if fc[k] != _FCFS_DEFAULTS[k]}
        if own:
            raise ValueError(f"method 'fcfs-tight' fixes the reservation buffers {FCFS_TIGHT}; got fcfs = {own}: "
                             f"use method 'fcfs' to set fcfs.time_buffer / fcfs.space_buffer")
    _num(c, "simulation_frequency", 0, 1000, lo_open=True, integer=True, allowed="an integer > 0 [Hz]")
    _num(c, "policy_frequency", 0, 1000, lo_open=True, integer=True, allowed="an integer > 0 [Hz]")
    if c["simulation_frequency"] % c["policy_frequency"]:
        raise ValueError(
            f"policy_frequency={c['policy_frequency']} must divide simulation_frequency={c['simulation_frequency']}"
        )
    _num(c, "duration", 0.0, MAX_DURATION, lo_open=True,
         allowed=f"a number of seconds in (0, {MAX_DURATION:g}] (MAX_DURATION, one simulated day)")
    _num(c, "warmup", 0.0, 3600.0, allowed="a number of seconds in [0, 3600]")
    mv = c["max_vehicles"]
    if mv is not None and not (isinstance(mv, (int, np.integer)) and not isinstance(mv, bool)
                               and 1 <= mv <= MAX_AGENTS):
        raise ValueError(f"max_vehicles = {mv!r}; allowed: None (all arrivals) or an integer in [1, {MAX_AGENTS}] "
                         f"(MAX_AGENTS)")
    rsr = c["reward_speed_range"]
    if rsr is not None and not is_speed_pair(rsr, sr[1]):
        raise ValueError(f"config['reward_speed_range'] = {rsr!r} is invalid; allowed: None (speed / v_max) "
                         f"or [lo, hi] with 0 <= lo < hi <= v_max = {sr[1]} m/s")
    r = c["reward"]
    check_keys(r, "reward", _REWARD_DEFAULTS)
    for k in _REWARD_DEFAULTS:
        _num(r, k, -1e6, 1e6, allowed="a finite number in [-1e6, 1e6]", where="['reward']")
    validate_spaces()
    if c["missing_action"] not in ("error", "expert"):
        raise ValueError(f"config['missing_action'] = {c['missing_action']!r}; allowed: 'error', 'expert'")
    for key in ("envelope_in_box", "vp_anticipation", "vp_zone_advisory", "expert_in_info", "expert_driven_check"):
        flag(c, key)
    info_keys(c, INFO_KEYS)
    check_render(c, flags=("show_zones", "show_groups", "show_overlay"))
    check_possible_agents(n_possible_agents(), "throughput x (duration + warmup)")
