"""
# Highway Ramps

| Import | `from icv_envs import highway_ramps_v0` |
|---|---|
| Creation | `highway_ramps_v0.parallel_env(method="formation", vgr=1/3, render_mode=None, **config)` |
| Actions | Continuous (`ContinuousAction`, default; `FormationResidual`) or Discrete (`DiscreteMetaAction`), see Action types |
| Parallel API | Yes (`parallel_env`); AEC through `env()` / `raw_env()` |
| Manual Control | No |
| Agents | `agents = ["icv_0", ...]`: every vehicle, from its arrival on an on-ramp until it exits, crashes or the episode ends |
| Number of agents | up to `max_vehicles` (default: mean arrivals + 6 sigma + 20, about 1,250 for 600 s at VGR 1/3) |
| Action Shape | `(2,)`; `DiscreteMetaAction`: `()` |
| Action Values | `Box(-1, 1, (2,), float32)` (`[acceleration, steering]`, or the residual); `DiscreteMetaAction`: `Discrete(5)` |
| Observation Shape | `Kinematics` (default): `(V, 13)`, `V = observation["vehicles_count"]` (8), columns = `features`; `OccupancyGrid`: `(F, nx, ny)`, default `(3, 11, 11)` |
| Observation Values | `Box(-1, 1, shape, float32)`; unbounded with `normalize=False` or `clip=False` |
| State Shape | `(len(possible_agents), 13)` |
| State Values | `Box(-1, 1, (len(possible_agents), 13), float32)` |
| Gymnasium id | `icv_envs/HighwayRamps-v0` (the first vehicle, arriving at t = 0 on the first on-ramp, is the learned ego) |
| PettingZoo id | `icv_envs/highway_ramps-v0` |

The paper's highway experiment (Xu et al. 2021, Sec. 6.1, Table 1): a 10 km
four-lane ring plus a ramp lane with five on-ramps (every 2000 m from 0 m,
100 m merge segments) and five off-ramps (every 2000 m from 1600 m, 50 m
diverge segments). Vehicles arrive on every on-ramp at the vehicle generating
rate `vgr` (vehicles/s per ramp; `arrivals="poisson"` or `"fixed"`), pick a
random exit among `exit_choices` (default all five) and leave at it; a
vehicle that misses its exit drives another lap. An arrival waits in a queue
while its ramp's spawn point is occupied. The `method` decides who
coordinates: `formation` (interlaced formations on the left three lanes,
the fourth lane a transition lane, the formation expert driving), `lane-lp`
(optimal lane assignment LP at the ramps, IDM) or `idm` (IDM/MOBIL);
`lane-lp-close` and `idm-close` are the two references at the formation
members' 0.5 s IDM time gap instead of 1.0 s (equal car-following margins). The
`expert_action` in the infos is the chosen method's controller.

## Observations, actions, rewards, state

As in `highway_formation_v0` (same action and observation types, features
and reward terms); row 0's `x` is the position on the ring divided by its
length, and neighbours and grids are found round the ring.

## Action types

`config["action"] = {"type": ..., <options>}` (highway-env's key and names; an
unknown type or an option the type does not have raises `ValueError`):

| type | space | the agent's action |
|---|---|---|
| `ContinuousAction` (default) | `Box(-1, 1, (2,), float32)` | `[acceleration, steering]` (below) |
| `DiscreteMetaAction` | `Discrete(5)` (`Discrete(3)` with `longitudinal` or `lateral` False) | `0 LANE_LEFT, 1 IDLE, 2 LANE_RIGHT, 3 FASTER, 4 SLOWER` (highway-env's order), carried out by the paper's low-level layer: Bezier lane change with preview steering, the feedback law around `target_speeds[index]` (default: `speed_range` in 5 m/s steps); impossible lane changes are ignored; the opposite request during a lane change aborts it (back to the lane it came from, as in highway-env); no safety layer |
| `FormationResidual` | `Box(-1, 1, (2,), float32)` | a correction `r`; the vehicle applies `clip(expert + bound * r, -1, 1)` (`bound` 0.25, or `[bound_accel, bound_steer]`); `r = 0` is the expert |

`infos[agent]["expert_action"]` is always the expert's `[u_a, u_s]` (the
`ContinuousAction` form), taken in the state the next action is taken in (after the
step's removals and spawns), so it equals `expert_actions()[agent]` at the
next step; agents that left get zeros. Details: `icv_envs.envs.actions`.

## Observation types

`config["observation"] = {"type": ..., <options>}`:

| type | shape (float32) | options |
|---|---|---|
| `Kinematics` (default) | `(vehicles_count, len(features))` | `features` (default: every column of the table below, in that order), `vehicles_count` (8), `perception_distance`, `absolute` (False: other rows relative to the observer), `normalize` (True: the scalings below; False: SI units), `clip` (True) |
| `OccupancyGrid` | `(len(features), nx, ny)`, default `(3, 11, 11)` | `features` (from `presence, vx, vy, cos_h, sin_h`; default the first three), `grid_size` (`[[-27.5, 27.5], [-27.5, 27.5]]` m), `grid_step` (`[5, 5]` m), `absolute` (False), `align_to_vehicle_axes` (False), `clip` (True) |

The space is `Box(-1, 1)` when normalised and clipped, else unbounded; it is
built once and shared by every agent. Details: `icv_envs.envs.observations`.
A fixed set of agent slots for MARL libraries (SuperSuit, RLlib, TorchRL):
`icv_envs.rl.slots`. `parallel_env(max_cycles=N)` truncates every agent after
N steps (PettingZoo's `max_cycles`).

## Episode end

An agent terminates when it reaches its exit or collides, and every agent is
truncated after `duration` (600 s) seconds. `agents` can be empty for a
while (between arrivals); `env.episode_over` tells when time is up, and the
AEC `env()` keeps stepping by itself until then. The arrivals do not depend
on `duration`: a shorter episode with the same seed is a prefix of a longer
one. Keys of `highway_formation_v0` that do not apply here (`vehicles_count`,
`initial_position`, `spawns`, `exits`, the layout sections, `ego_vehicle`:
the Gymnasium ego is the first arrival) must keep their defaults.

## Metrics

`env.metrics()` adds to the common metrics: `spawned`, `exited`,
`missed_exits`, `remaining` (on the road at the end), `queued`,
`not_spawned`, `lost` (spawned - exited - remaining - removed after a crash,
a bookkeeping check that must be 0); `env.metrics(series=True)` also returns
the 1 Hz time series and the density heat map (vehicles per 500 m per lane,
time-averaged and at the end), in the paper's coordinates.

## Arguments

| key | default | meaning |
|---|---|---|
| `method` | `"formation"` | `formation`, `lane-lp`, `idm`, `lane-lp-close`, `idm-close` |
| `vgr` | 1/3 | vehicles/s per on-ramp, in (0, 1] |
| `arrivals` | `"poisson"` | or `"fixed"` (constant interval, random phase per ramp) |
| `exit_choices` | None | list of off-ramp indices (0 = the one at 1600 m) a vehicle may pick |
| `duration` | 600 | seconds |
| `road_length`, `ramps`, `ramp_spacing`, `first_on_ramp`, `first_off_ramp` | 10000, 5, 2000, 0, 1600 | layout (metres) |
| `merge_length`, `diverge_length`, `on_ramp_approach`, `off_ramp_length` | 100, 50, 200, 100 | metres |
| `lane_speeds` | None = [25, 25, 25, 20] | desired speed per main lane (None: 25 m/s, the rightmost lane 20 m/s, for any `lanes_count`); `ramp_speed` 15 |
| `speed_range` | [15, 30] | main-road speeds (a control floor, not physics) |
| `formation_lanes` | None = [0, 1, 2] | lanes formations may use (None: every main lane but the rightmost) |
| `formation_size` | 12 | most members per formation |
| `seam` | 1000 | paper position of the ring's seam (keep it off the ramps) |
| `max_vehicles` | None | possible agents (arrivals beyond are counted in `not_spawned`) |

and the keys of `highway_formation_v0` (formation parameters, frequencies,
observation, reward, rendering). Invalid values raise `ValueError` naming
the key, the value and what is allowed.
"""

from __future__ import annotations

from icv_envs.envs.highway_ramps import HighwayRampsEnv
from icv_envs.envs.parallel import CoreParallelEnv, module_functions

__all__ = ["env", "parallel_env", "raw_env", "HighwayRampsParallelEnv"]


class HighwayRampsParallelEnv(CoreParallelEnv):
    core_cls = HighwayRampsEnv
    metadata = {
        "name": "highway_ramps_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 10,
    }


parallel_env, raw_env, env = module_functions(HighwayRampsParallelEnv)
