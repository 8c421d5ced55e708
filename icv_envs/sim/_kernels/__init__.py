"""Compiled inner loops of the simulation core (numba, ``@njit(cache=True)``).

What lives here: the loops that array operations cannot express without
Python-level iteration (the collision sweep, which stops at the first
sort-order offset with no pair in reach; the formation layer's
front-target pass and drivable-lane windows), and the per-step work whose cost was
the Python overhead of tens of small numpy calls rather than arithmetic
(issue 10): the fused physics substep (:func:`kinematic_substep`,
:func:`road_check`) and the run of substeps in which nothing happens that
the world must handle in Python (:func:`quiet_substeps`; the intersection's
frames with their events, PET transitions and jam watch, :func:`intersection_frames`), the run statistics (:func:`motion_record`,
:func:`headway_record`), collision detection as a whole
(:func:`collision_pairs`), the lane-sorted index and leader search
(:func:`build_lane_index`, :func:`leader_rows`,
:func:`own_lane_gap_rows`) and the observation's
neighbour search (:func:`nearest_along_road`), the highway env's feature
rows and reward terms (:func:`formation_feature_rows`,
:func:`formation_reward_terms`), and the formation layer's per-vehicle
rules (one lane window, :func:`drivable_lane_bits1`; the free vehicles that
may join, :func:`eligible_free_rows`; the members leaving for their exit,
:func:`leaving_rows`) and its step outside re-forming (membership, front
targets, room ahead: :func:`membership_pass`; the front-target hold, lane
windows and stall clocks: :func:`hold_pass`; the re-plan test and the
re-forming's frame, costs and slots; from stop 50 the step but the
re-forming in one call, :func:`update_pass`, and a re-plan in one,
:func:`plan_pass`; all in ``formation_step.py``). They take and return plain
arrays (no Python objects inside), and they perform the same IEEE-754
operations, in the same order, as the numpy code they replace (reductions
included: :func:`pairwise_sum` is NumPy's own summation order), so
trajectories stay bit-identical (``tests/test_trajectory_hash.py``; each
kernel is also tested against the numpy code it replaced in
``tests/test_kernels.py``). Floating-point reassociation (``fastmath``) is
off for the same reason.

Transcendental functions (``sin``, ``cos``, ``tan``, ``atan``; from stop
49 also ``exp`` in the highway reward, :func:`formation_reward_total`, and
``pow`` in the join profiles, :mod:`icv_envs.formation._kernels`; from
stop 50 ``cbrt`` at the join search's start, :func:`plan_pass`, and the
experts' IDM power, ``icv_envs.policies._kernels.free_speed_pow``; from
stop 51 the highway headings' ``cos`` and ``sin`` the observations and the
expert read, :func:`quiet_substeps` and :func:`cos_sin_rows`) come from
libm here, as in NumPy's float64 loops up to AVX2 (``X86_V3``), the level
the reference fingerprints are pinned at: there NumPy's ``exp``,
``power``, ``cbrt``, ``sin``, ``cos``, ``tan``, ``arctan``, ``arcsinh``,
``sinh``, ``hypot`` and ``arctan2`` are libm's, bit for bit (0 of 400,000
probes each differ, ``results/bench/stop49/libm_vs_numpy.py``). On an
AVX-512 machine NumPy takes ``exp``, ``power``, ``cbrt``, ``tan``,
``arctan``, ``arcsinh``, ``sinh`` and ``arctan2`` from its SIMD library,
which rounds 0.2-49% of those probes differently in the last bit (``sin``,
``cos`` and ``hypot`` agree); there the kernels' calls are libm's (as on
an AVX2 machine), not NumPy's SIMD ones, and trajectories can drift by
ulps from the array code's. So a kernel may take a transcendental step
inside rather than stop for NumPy's (stop 49: the seams a kernel stopped at
only for NumPy's call cost 13% of a batched highway world-step): the
pinned fingerprints stay the same, and on an AVX-512 machine the result is
the pinned level's number rather than that machine's NumPy's. On the
development machine (AVX-512), 22 of 24 fresh 600 s HighwayRamps runs
reproduced the committed results exactly and 2 differed in the 13th-16th
significant digit of the motion figures (README, "Speed"; stop 40, before
``exp`` and ``pow`` were added).

A rule for writing them: a helper that takes the road's arrays (lane
ends, obstacles, ramp intervals) and loops over them cost about 75 ns a
call when called once per vehicle inside a compiled loop (measured here;
a one-line helper over an array was inlined away, the ones with loops and
several exits were not, with or without ``inline="always"``): such rules
are written once over arrays and called once per kernel
(:func:`lanes_available`, :func:`interval_ends`; the leader rule,
:func:`leader_entries`, likewise, for one copy rather than for speed).
Helpers over scalars (``npy_mod``, ``lane_of1``, ``_rect_overlap_cs``) cost
nothing and stay, and so does ``policies/_kernels/lane_changes._in_intervals``, called
only for the few lane changes into or out of the ramp lane. A changed kernel module also invalidates the cached code
of the kernels that call into it (``icv_envs/_kernel_cache.py``; numba
itself checks only a kernel's own file).

Why numba: the loops are short, data-dependent and branchy (early exits,
variable-length outputs), which is what a JIT compiles well and what numpy
vectorisation cannot do without materialising every candidate; ``cache=True``
keeps the compiled code on disk, so only the first import on a machine pays
the compile time (measured: a HighwayRamps reset and 20 steps took 19.5 s
in a fresh checkout, 1.6 s once the cache was written). numba's cache does not hold recursive
functions, so :func:`pairwise_sum` runs its halving on an explicit stack.
"""

from __future__ import annotations

from icv_envs.sim._kernels.formation import (drivable_lane_bits, drivable_lane_bits1, eligible_free_rows,
                                             hold_targets, leaving_rows, reference_rows)
from icv_envs.sim._kernels.formation_step import (hold_pass, membership_pass, off_reference_rows, plan_pass,
                                                  reform_costs, reform_members, reform_slots, update_pass)
from icv_envs.sim._kernels.frames import intersection_frames, quiet_substeps
from icv_envs.sim._kernels.neighbours import (sweep_candidates, collision_pairs, build_lane_index,
                                              build_lane_index_pair, leader_entries,
                                              leader_rows, own_lane_gap_rows, lane_gap_pass)
from icv_envs.sim._kernels.observation import (formation_feature_rows, formation_post_rows, formation_reward_terms,
                                               formation_reward_total,
                                               intersection_feature_rows, intersection_post_rows,
                                               intersection_reward_rows, kinematics_rows, nearest_along_road,
                                               nearest_euclidean, corridor_leaders)
from icv_envs.sim._kernels.physics import (controls_rows, cos_sin_rows, npy_mod, kinematic_substep, road_check, interval_ends,
                                           lanes_available)
from icv_envs.sim._kernels.stats import (pairwise_sum, motion_record, motion_sums_add, headway_record, pet_transitions,
                                         id_range)

__all__ = [
    "npy_mod",
    "controls_rows",
    "cos_sin_rows",
    "kinematic_substep",
    "road_check",
    "interval_ends",
    "lanes_available",
    "sweep_candidates",
    "collision_pairs",
    "build_lane_index",
    "build_lane_index_pair",
    "leader_entries",
    "leader_rows",
    "own_lane_gap_rows",
    "lane_gap_pass",
    "nearest_along_road",
    "nearest_euclidean",
    "corridor_leaders",
    "intersection_feature_rows",
    "intersection_post_rows",
    "intersection_reward_rows",
    "kinematics_rows",
    "formation_feature_rows",
    "formation_post_rows",
    "formation_reward_terms",
    "formation_reward_total",
    "pairwise_sum",
    "motion_record",
    "motion_sums_add",
    "headway_record",
    "pet_transitions",
    "id_range",
    "drivable_lane_bits",
    "drivable_lane_bits1",
    "eligible_free_rows",
    "leaving_rows",
    "hold_targets",
    "hold_pass",
    "membership_pass",
    "off_reference_rows",
    "plan_pass",
    "reform_costs",
    "reform_members",
    "reform_slots",
    "update_pass",
    "reference_rows",
    "quiet_substeps",
    "intersection_frames",
]
