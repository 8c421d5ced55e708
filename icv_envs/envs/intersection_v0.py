"""
# Intersection

| Import | `from icv_envs import intersection_v0` |
|---|---|
| Creation | `intersection_v0.parallel_env(method="multi-vp", throughput=1500, render_mode=None, **config)` |
| Actions | Continuous (`ContinuousAction`, default; `FormationResidual`) or Discrete (`DiscreteMetaAction`), see Action types |
| Parallel API | Yes (`parallel_env`); AEC through `env()` / `raw_env()` |
| Manual Control | No |
| Agents | `agents = ["icv_0", ...]`: every vehicle, from its appearance at `R3` (800 m from the centre) until it has crossed the box and driven `departure_length` (40 m) on, crashes, or the episode ends |
| Number of agents | every arrival generated for the episode (`len(possible_agents)`, about `throughput * duration / 3600`), or `max_vehicles` |
| Action Shape | `(2,)`; `DiscreteMetaAction`: `()` |
| Action Values | `Box(-1, 1, (2,), float32)` (`[acceleration, steering]`, or the residual); `DiscreteMetaAction`: `Discrete(5)` |
| Observation Shape | `Kinematics` (default): `(V, 14)`, `V = observation["vehicles_count"]` (8), columns = `features`; `OccupancyGrid`: `(F, nx, ny)`, default `(3, 11, 11)` |
| Observation Values | `Box(-1, 1, shape, float32)`; unbounded with `normalize=False` or `clip=False` |
| State Shape | `(len(possible_agents), 14)` |
| State Values | `Box(-1, 1, (len(possible_agents), 14), float32)` |
| Gymnasium id | `icv_envs/Intersection-v0` (the first vehicle, arriving on leg N at t = 0, is the learned ego; all others follow the method's expert) |
| PettingZoo id | `icv_envs/intersection-v0` (`pettingzoo.make("parallel", ...)`) |

The multi-lane unsignalized intersection of Xu et al. (2021), Sec. 4-5 and
Table 2 (docs/intersection.md): four legs (N, E, S, W), each with three approach and
three departure lanes of 4 m; a lane-use table (`lane_use`: `"paper"`, left
lane left turn / middle lane straight and right / right lane right turn, or
`"exclusive"`, one movement per lane, or a custom dict) decides which
(movement, lane) paths exist, and the conflict model between the 12
movements (crossing, diverging, converging) is derived from those paths
(:mod:`icv_envs.platoon.conflicts`).  Movements are numbered
`3 * leg + turn`, legs N=0, E=1, S=2, W=3, turns left=0, straight=1,
right=2 (:mod:`icv_envs.platoon.geometry`).

Vehicles arrive at `R3` on every leg in interlaced formations (`L_s = 15 m`)
at the rate that gives the requested `throughput` (vehicles/h entering the
intersection, split evenly over the legs).  The zones are decided by the
distance to the centre: approaching (`> R2` = 500 m: the formation is kept),
adjusting (`R2 >= d > R1` = 300 m: regrouping, i.e. division into
sub-formations of one movement, lane changes to the expected lanes,
tightening to `L_s = 9 m`, merging of same-movement sub-formations) and
coordinating (`<= R1`), where the `method` decides who enters the box when:

* `multi-vp` (the paper's improved virtual platoon): every sub-formation is
  a node; tree-layers by `depth(j) = 1 + max{depth(i) : i < j, i conflicts
  with j}`, references `X_ref,1^k = X_0 + m D_t + sum max len` (Sec. 4.2),
  followers `X_1^k + x_gi`;
* `single-vp`: the same tree with one vehicle per node;
* `fcfs`: tile reservation, first come first served (Dresner & Stone), with
  buffers chosen for equal safety (minimum PET) with the virtual platoon;
* `fcfs-tight`: the same with a 0.2 s / 0.5 m buffer.

The expert (:class:`icv_envs.policies.platoon_expert.PlatoonExpert` or
:class:`icv_envs.policies.fcfs.FcfsExpert`) drives through the same action
space (pure pursuit on the lane centre / Bezier lane change / path through
the box, the paper's feedback law on its references, an IDM safety envelope)
and its action is in every agent's info as `"expert_action"`.  All design
choices the paper leaves open are documented in those modules.

The vehicle model is the paper's rear-axle kinematic bicycle (L = 2.8 m,
steering within +-30 deg, acceleration within [-6, 3] m/s^2, speed within
[0, 20] m/s), integrated at 25 Hz (0.04 s, Table 2); agents act at
`policy_frequency` (5 Hz).

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

A `(V, 14)` float32 array in highway-env's `Kinematics` layout.  Row 0 is the
observing vehicle in absolute terms; rows 1..V-1 the V-1 nearest vehicles
(Euclidean distance of body centres) within `perception_distance` (100 m),
nearest first, exactly equal distances by vehicle row (ascending id), with
x, y, vx, vy relative to the observer, zero-padded (presence 0).
Columns:

| # | feature | scaling |
|---|---|---|
| 0 | presence | 1 for a vehicle, 0 for padding |
| 1, 2 | x, y (east, north; origin at the centre) | row 0: / R3; others: difference / perception_distance |
| 3, 4 | vx, vy | / v_max |
| 5, 6 | cos_h, sin_h | heading |
| 7 | dist | distance to the centre along the vehicle's route / R3 (negative once past the stop line by more than the box half-width) |
| 8 | ref_dx | reference position error (m, positive: the reference is ahead) / 100; formation slot, virtual-platoon reference or reservation plan; 0 without one |
| 9 | ref_dv | reference speed - speed, / v_max |
| 10 | lane_err | lateral offset from the lane centre it keeps (approach) or its path (box, departure) / 12 m |
| 11 | turn | -1 left, 0 straight, +1 right |
| 12 | zone | 0 approaching, 1/3 adjusting, 2/3 coordinating, 1 in or past the box |
| 13 | go | 1 if it may enter the box now (in a virtual-platoon node / holding a reservation, in an allowed lane) |

Opt-in columns (not in the default; name them in `observation["features"]`,
e.g. the default list plus these two, giving `(V, 16)`): the leader the safety
reward and the experts' safety envelope see, the nearest vehicle ahead over
the vehicle's corridors (its lane, the lane it signals into, its path in the
box):

| feature | scaling |
|---|---|
| lead_gap | bumper gap to that leader (m) / perception_distance; 1 (the perception distance) without one |
| lead_dv | own speed - the leader's, / v_max; 0 without one |

With the default options all values are clipped to [-1, 1].

## Actions (ContinuousAction)

`[u_a, u_s]` in [-1, 1]: acceleration `u_a * 3` m/s^2 for `u_a >= 0` and
`u_a * 6` m/s^2 for `u_a < 0` (0 coasts), steering `u_s * 30` deg.
Out-of-range values are clipped; a wrong shape or a NaN (or, for
`DiscreteMetaAction`, anything but an integer index) raises `ValueError`
naming the agent.  Every live agent needs an action unless
`missing_action="expert"`.

## Rewards

Per agent and per step, the weighted sum (weights in `config["reward"]`) of
`progress` (0.4): speed / v_max (with `reward_speed_range` = [lo, hi], as
in highway-env, `clip((v - lo) / (hi - lo), 0, 1)`: `[0, 10]` pays nothing
for driving faster than the methods' desired speed); `safety` (1.0): -1 on the step of a
collision, else `-max(0, 1 - gap / (2 m + v * 1 s))` towards the leader in
its lane / path; `comfort` (0.1): `-(u_a^2 + u_s^2) / 2`; `tracking` (0.5):
`exp(-(ref_dx / 10 m)^2)` for a vehicle with a reference, else 0.  The
components are in `infos[agent]["rewards"]`.

## Episode end

An agent *terminates* when it reaches the end of the departure stretch
(success; `infos[agent]["exited"]`) or collides or leaves the road (its
vehicle is removed); it is *truncated* if it drives back out of its approach
road, and every agent is truncated after `duration` seconds.  Vehicles keep
arriving: `agents` can be empty for a while; `env.episode_over` tells when
time is up (the AEC `env()` then keeps stepping by itself: `agent_iter()`
ends only when time is up).

## State

`state()` returns one row per possible agent (in `possible_agents` order)
with the observation's columns in absolute terms; zeros for vehicles not on
the road.

## Metrics

`env.metrics()` (definitions in :mod:`icv_envs.sim.intersection_metrics`):
`collisions`, `lost` (spawned - removed - left_road - remaining -
crashed_removed: must be 0), `spawned`, `cleared`, `remaining`, `queued`
(arrivals waiting for a free spawn point), `achieved_throughput` (vehicles/h
that cleared the box), `mean_speed`, `speed_fluctuation` (mean |dv/dt| of the
REALISED speed: a vehicle held at 0 m/s while braking is commanded adds 0),
`speed_std` (per-vehicle speed standard deviation, mean over vehicles),
`stopped_share` (share of vehicle-time below 0.1 m/s), `commanded_abs_accel`
(mean commanded |a|, a diagnostic), `pet_min`, `pet_p05`, `pet_samples`
(post-encroachment time at the conflict areas of crossing and merging
paths), `jammed` (vehicles stopped > 10 s outside a queue at the box) and
`jammed_vehicle_seconds`, `mean_delay` (travel time from R3 until clearing
the box minus the same distance at `desired_speed`), `envelope_box_binding`
(vehicle-steps in which the safety envelope had to cut a command in the box:
0 when the coordination is right), `virtual_cap_binding`, `nodes`, `merges`,
`lane_changes`, and for `fcfs` / `fcfs-tight` `requests`, `granted`,
`rejected`, `max_plan_error`.

## Arguments

| key | default | meaning |
|---|---|---|
| `method` | `"multi-vp"` | `multi-vp`, `single-vp`, `fcfs` (reservation, buffers matched to the virtual platoon's minimum PET: none), `fcfs-tight` (reservation with 0.2 s / 0.5 m buffers) |
| `lane_use` | `"paper"` | `paper`, `exclusive` or a dict (turn name / movement id / (leg, turn) -> lanes); a movement without a lane is an error |
| `throughput` | 1500 | vehicles/h entering the intersection (all legs), > 0 |
| `turn_shares` | [1/3, 1/3, 1/3] | left, straight, right |
| `arrivals` | `"poisson"` | formation heads: `poisson` (shifted exponential) or `fixed` |
| `formation_size` | 6 | vehicles per arriving formation |
| `R1`, `R2`, `R3` | 300, 500, 800 | zone radii (m), `box_half < R1 < R2 < R3` |
| `box_half` | 16 | half side of the box (m); a 12 m box makes the kerb-lane right turn (2 m radius) undrivable |
| `D_t` | `"auto"` | gap between tree-layers (m); `"auto"`: `required_layer_gap` of the geometry and lane use (19 m for both presets) + `desired_speed` x policy period (2 m, the reaction margin of the safe-speed cap) = 21 m; a number smaller than `required_layer_gap` is an error |
| `desired_speed` | 10 | m/s, the virtual leader's (Table 2) |
| `speed_range` | [0, 20] | m/s (Table 2) |
| `gap_outside`, `gap_inside` | 15, 9 | formation gap L_s outside / inside the coordinating zone (m) |
| `merge_range`, `max_node_size` | 60, 12 | merging |
| `fcfs` | `{"tile": 1, "time_buffer": 0, "space_buffer": 0, "request_distance": 80, "a_plan": 1.5}` | reservation parameters (`fcfs-tight` fixes time_buffer 5 steps, space_buffer 0.5 m) |
| `envelope_in_box` | True | False switches the safety envelope off inside the box (to show the coordination alone is collision-free) |
| `vp_anticipation` | True | virtual-platoon methods: vehicles of the adjusting zone already track (comfortable braking only) the reference they would get as a node, instead of meeting it at R1 (docs/methods.md#virtual-platoon); False = the paper's zones as printed |
| `vp_zone_advisory` | True | virtual-platoon methods: a node vehicle inside R1 whose reference lies further behind it than comfortable braking absorbs drives at the speed that meets it at the stop line, instead of standing for it right after R1 (docs/methods.md#virtual-platoon); False = it stands |
| `duration` | 120 | seconds |
| `max_vehicles` | None | cap on arrivals (possible agents) |
| `simulation_frequency` / `policy_frequency` | 25 / 5 | Hz |
| `observation` | `{"type": "Kinematics", "vehicles_count": 8, "perception_distance": 100}` | see Observation types |
| `action` | `{"type": "ContinuousAction"}` | see Action types |
| `reward` | see Rewards | |
| `reward_speed_range` | None | highway-env's key: `[lo, hi]` m/s, `0 <= lo < hi <= v_max`, maps the speed of the progress term linearly to [0, 1], clipped; None = speed / v_max |
| `expert_in_info`, `expert_driven_check`, `missing_action` | True, True, `"error"` | as in `highway_formation_v0` |
| `info_keys` | None | as in `highway_formation_v0`; the keys: `speed`, `movement`, `distance`, `node`, `tree_layer`, `crashed`, `rewards` (an agent's last info adds `wrong_exit`) |
| `show_zones`, `show_groups` | True | rendering: zone circles; group lines and tree-layer labels |
| `show_overlay` | True | rendering: title (method, demand, lane use), time, legend and a true-size inset of the box (docs/rendering.md) |
| `scaling` | 0.54 | rendering: pixels per metre; 0.54 on 900 px shows the scene out to R3 = 800 m |

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

from icv_envs.envs.intersection import IntersectionEnv
from icv_envs.envs.parallel import CoreParallelEnv, module_functions

__all__ = ["env", "parallel_env", "raw_env", "IntersectionParallelEnv"]


class IntersectionParallelEnv(CoreParallelEnv):
    """PettingZoo parallel env over :class:`IntersectionEnv` (every vehicle an agent)."""

    core_cls = IntersectionEnv
    metadata = {
        "name": "intersection_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 10,
    }


parallel_env, raw_env, env = module_functions(IntersectionParallelEnv)
