"""The paper's four qualitative highway scenarios (Sec. 6.1, Fig. 7) as
config presets of :class:`~icv_envs.envs.highway_formation.HighwayFormationEnv`.

=============  ==============================================================
name           what happens
=============  ==============================================================
``lane-drop``  Fig. 7a: four lanes become three at 700 m (the rightmost lane
               ends); the formation re-forms on three lanes before the drop.
``lane-change`` Fig. 7b: an inner-formation lane change. A stopped obstacle
               blocks the second lane at 900 m; the formation re-forms on the
               three free lanes (the vehicles of the blocked lane change lanes
               inside the formation) and re-forms on four lanes once past it.
``off-ramp``   Fig. 7c: one member (the vehicle in the third lane of the
               first layer) has an exit at the off-ramp at 900 m; it leaves
               the formation, crosses to the ramp and exits; the others
               re-form.
``on-ramp``    Fig. 7d: a vehicle enters on the on-ramp (merge segment
               650-750 m), joins the formation on the ramp, merges and takes
               its target; the formation re-forms with one more member.
=============  ==============================================================
"""

from __future__ import annotations

import copy

__all__ = ["SCENARIOS", "scenario_config"]

SCENARIOS: dict[str, dict] = {
    "free": {},
    "lane-drop": {
        "lanes_count": 4,
        "initial_position": 150.0,
        "vehicles_count": 8,
        "lane_drop": {"position": 700.0, "lanes": 3},
    },
    "lane-change": {
        "lanes_count": 4,
        "initial_position": 150.0,
        "vehicles_count": 8,
        "obstacle": {"lane": 1, "position": 900.0, "length": 4.0},
    },
    "off-ramp": {
        "lanes_count": 4,
        "initial_position": 150.0,
        "vehicles_count": 7,
        "off_ramp": {"position": 900.0, "length": 50.0, "ramp_length": 150.0},
        "exits": {1: 0},
    },
    "on-ramp": {
        "lanes_count": 4,
        "initial_position": 150.0,
        "vehicles_count": 6,
        "on_ramp": {"position": 650.0, "length": 100.0, "approach": 350.0},
        "spawns": [{"time": 0.0, "position": 320.0, "lane": "ramp", "speed": 15.0}],
    },
}


def scenario_config(name: str) -> dict:
    """The config overrides of scenario ``name`` (a deep copy)."""
    if name not in SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; allowed: {sorted(SCENARIOS)}")
    return copy.deepcopy(SCENARIOS[name])
