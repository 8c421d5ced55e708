"""
# Highway Formation

| Import | `from icv_envs import highway_formation_v0` |
|---|---|
| Creation | `highway_formation_v0.parallel_env(scenario="lane-drop", render_mode=None, **config)` |
| Actions | Continuous (`ContinuousAction`, default; `FormationResidual`) or Discrete (`DiscreteMetaAction`), see Action types |
| Parallel API | Yes (`parallel_env`); AEC through `env()` / `raw_env()` |
| Manual Control | No |
| Agents | `agents = ["icv_0", "icv_1", ...]`: every ICV, from its appearance until it crashes, exits or the episode ends |
| Number of agents | `vehicles_count` + scheduled `spawns` (8 by default) |
| Action Shape | `(2,)`; `DiscreteMetaAction`: `()` |
| Action Values | `Box(-1, 1, (2,), float32)` (`[acceleration, steering]`, or the residual); `DiscreteMetaAction`: `Discrete(5)` |
| Observation Shape | `Kinematics` (default): `(V, 13)`, `V = observation["vehicles_count"]` (8), columns = `features`; `OccupancyGrid`: `(F, nx, ny)`, default `(3, 11, 11)` |
| Observation Values | `Box(-1, 1, shape, float32)`; unbounded with `normalize=False` or `clip=False` |
| State Shape | `(len(possible_agents), 13)` |
| State Values | `Box(-1, 1, (len(possible_agents), 13), float32)` |
| Gymnasium id | `icv_envs/HighwayFormation-v0` (one learned ego among expert ICVs) |
| PettingZoo id | `icv_envs/highway_formation-v0` (`pettingzoo.make("parallel", ...)`) |

Intelligent and connected vehicles (ICVs) drive on a straight multi-lane
highway (1 to 6 lanes) in the interlaced multi-lane formation of Xu et al.
(2021), Sec. 3: a formation layer (run by the environment, as V2X
infrastructure would) generates the formation's targets (Sec. 3.2, the
corrected target equation of docs/formation.md#target-equation) on the lanes that are drivable
ahead and assigns them to the members by minimum total cost with the
Hungarian method (Sec. 3.3); it re-forms whenever lanes close or open (a lane
drop, an obstacle blocking a lane) or a vehicle joins (on-ramp) or leaves
(off-ramp). Each agent's job is to reach and hold its target safely. The
formation expert (:class:`icv_envs.policies.FormationExpert`; Bezier lane
changes, preview steering, the paper's feedback law, an IDM safety envelope)
does it through the same action space, and its action is in every agent's
info as `"expert_action"`.

The vehicle model is the paper's rear-axle kinematic bicycle (Sec. 2.2,
L = 2.8 m, steering within +-30 deg, acceleration within [-6, 3] m/s^2),
integrated at 25 Hz (0.04 s); agents act at `policy_frequency` (5 Hz), each
action held for the substeps in between.

The simulation core stores vehicles as arrays; neighbour search uses
lane-sorted positions and collisions a sweep over x-sorted bodies, so a step
costs O(N log N) (highway-env's own loops are O(N^2)); highway-env supplies
road drawing, rendering and the observation conventions.

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

## Observations (Kinematics)

A `(V, 13)` float32 array in highway-env's `Kinematics` layout. Row 0 is the
observing vehicle in absolute terms; rows 1..V-1 are the V-1 vehicles nearest
by longitudinal distance within `perception_distance` (150 m), relative to the
observer (x, y, vx, vy differences), zero-padded (presence 0). Columns:

| # | feature | scaling |
|---|---|---|
| 0 | presence | 1 for a vehicle, 0 for padding |
| 1 | x | row 0: x / road_length; others: dx / perception_distance |
| 2 | y | / (lanes x lane_width) (row 0: absolute, lane 0 centred at 0) |
| 3, 4 | vx, vy | / v_max |
| 5, 6 | cos_h, sin_h | heading |
| 7 | target_dx | (X_ref - x) / 100 m, 0 for a vehicle outside a formation |
| 8 | target_dy | (y_ref - y) / (lanes x lane_width) |
| 9 | target_dv | (v_ref - v) / v_max |
| 10 | member | 1 if the vehicle holds a formation target |
| 11 | exit_dx | metres to the start of the vehicle's exit (diverge segment) / 1000; 1 for a vehicle with no exit |
| 12 | lane_end_dx | metres to the end of the vehicle's lane (lane drop, obstacle, ramp end) / 200, clipped to [0, 1] |

With the default options all values are clipped to [-1, 1].

## Actions (ContinuousAction)

`[u_a, u_s]` in [-1, 1]: acceleration `u_a * 3` m/s^2 for `u_a >= 0` and
`u_a * 6` m/s^2 for `u_a < 0` (so 0 coasts), steering `u_s * 30` deg.
Out-of-range values are clipped; a wrong shape or a NaN (or, for
`DiscreteMetaAction`, anything but an integer index) raises `ValueError`
naming the agent. Every live agent needs an action unless
`missing_action="expert"`, in which case the expert drives the ones left out.

## Rewards

Per agent and per step, the weighted sum (weights in `config["reward"]`) of

* `progress` (0.4): speed / v_max;
* `safety` (1.0): -1 on the step of a collision, else
  `-max(0, 1 - gap / (2 m + v * 1 s))` for the gap to the leader in its lane;
* `comfort` (0.1): `-(u_a^2 + u_s^2) / 2` of the action taken;
* `formation` (0.5): `exp(-(dx / L_s)^2 - (dy / lane_width)^2)` of the target
  error for members, 0 for free vehicles.

The components are in `infos[agent]["rewards"]` (unless `info_keys` leaves them out).

## Episode end

An agent *terminates* when it collides (its vehicle is then removed) or
reaches its exit at the end of an off-ramp; it is *truncated* when it reaches
the end of the road, and every agent is truncated after `duration` seconds.

## State

`state()` returns one row per possible agent (in `possible_agents` order),
with the observation's columns in absolute terms; zeros for vehicles not on
the road. Use it for centralised critics.

## Arguments

`parallel_env(render_mode=None, **config)`; `config` keys are highway-env style
(see `HighwayFormationEnv.default_config()`), the main ones:

| key | default | meaning |
|---|---|---|
| `scenario` | `"free"` | preset: `free`, `lane-drop`, `lane-change`, `off-ramp`, `on-ramp` (the paper's Fig. 7) |
| `lanes_count` | 4 | main lanes, 1 to 6 (1: a single-lane platoon with gap L_s) |
| `road_length` | 2000 | metres |
| `lane_drop` | None | `{"position": x, "lanes": n}`: only the n leftmost lanes continue after x |
| `obstacle` | None | `{"lane": l, "position": x, "length": 4}` blocks lane l |
| `on_ramp` / `off_ramp` | None | `{"position": x, "length": merge/diverge length[, "approach"/"ramp_length"]}` |
| `vehicles_count` | 8 | ICVs at the start, split into formations of at most `formation_size` (12) |
| `spawns` | [] | `[{"time", "position", "lane" (int or "ramp")[, "speed", "exit"]}]` vehicles appearing later |
| `exits` | {} | `{vehicle_index: exit_index}`: which initial vehicles leave at which off-ramp |
| `formation` | see below | `geometry` (`interlaced`/`parallel`), `spacing` L_s (20 m), `w1` (1), `w2` (10), `speed` (25 m/s), `lookahead` (200 m), `join_distance`, `exit_lookahead`, `exit_lookahead_per_lane` (0; HighwayRamps 300 m: added per further lane to cross), `max_anchor_lead` |
| `speed_range` | [10, 30] | m/s; the lower bound is a control floor, vehicles may brake below it to avoid a collision |
| `simulation_frequency` / `policy_frequency` | 25 / 5 | Hz |
| `duration` | 60 | seconds |
| `observation` | `{"type": "Kinematics", "vehicles_count": 8, "perception_distance": 150}` | see Observation types |
| `action` | `{"type": "ContinuousAction"}` | see Action types |
| `reward` | see Rewards | |
| `expert_in_info` | True | put the expert's action in infos (costs one vectorised expert call per step) |
| `info_keys` | None | the per-step keys of each agent's info: None for all (`speed`, `lane`, `formation`, `target_lane`, `crashed`, `rewards`), or a list of them, `[]` for none (as a TraCI subscription: a user pays for the per-agent values it reads; at 800 agents the full infos cost about 15% of a step). The order stays the one above; `expert_action` is switched by `expert_in_info`; an agent's last info when it leaves the road (`exited`, `left_road`, `crashed`) is always whole |
| `expert_driven_check` | True | compare every action with the expert's (float32): a vehicle whose action equals it is *expert-driven* (it carries out the expert's lane-change plan; its collisions are counted under `expert` in `collisions_by_fault`). False: every vehicle is policy-driven and no step computes the expert for this check (training on learned actions: about a quarter of a 20-agent step; `icv_envs.vector.BatchedWorlds(expert=False)` sets it). Feeding the expert's actions back then does not reproduce the expert's trajectory |
| `missing_action` | `"error"` | or `"expert"` |
| `show_formation` | True | draw targets and the assignment when rendering |
| `show_overlay` | True | draw the title (env, scenario), the time and a legend on every frame (docs/rendering.md) |

Invalid values raise `ValueError` naming the key, the value and what is allowed.
Bounds that keep a run within memory: `duration` <= 86400 s, at most 200,000
possible agents, `acceleration_range` within +-20 m/s^2 (see `icv_envs/envs/_config.py`).
highway-env keys the env does not use (`other_vehicles_type`, `manual_control`,
`show_trajectories`) must keep their defaults. A config passed to
`reset(options={"config": ...})` is validated before it is applied: a rejected one
leaves the env as it was. `"config"` is the only reset option the env reads; any other key is
ignored with a warning naming it (PettingZoo's API test resets with other keys).
"""

from __future__ import annotations

from icv_envs.envs.highway_formation import HighwayFormationEnv
from icv_envs.envs.parallel import CoreParallelEnv, module_functions

__all__ = ["env", "parallel_env", "raw_env", "HighwayFormationParallelEnv"]


class HighwayFormationParallelEnv(CoreParallelEnv):
    """PettingZoo parallel env over :class:`HighwayFormationEnv` (every ICV an agent)."""

    core_cls = HighwayFormationEnv
    metadata = {
        "name": "highway_formation_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 10,
    }


parallel_env, raw_env, env = module_functions(HighwayFormationParallelEnv)
