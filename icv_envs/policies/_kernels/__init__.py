"""Compiled inner loops of the experts (numba, ``@njit(cache=True)``), one
module per room of the paper's method, as the policies that call them:

* :mod:`.laws` -- the control laws both experts share (normalised actions,
  the IDM without a leader, the clipped feedback law, paper Sec. 2.2 eq. (law));
* :mod:`.formation_expert` -- the highway formation expert (paper Sec. 2.2, 3.4):
  safety envelope, exit and lane-end lanes, and the arithmetic of
  ``FormationExpert.compute`` around the numpy calls that stay (its runs of
  kernels in one call each);
* :mod:`.lane_changes` -- that expert's lane-change decisions (Sec. 3.4):
  which lane changes start, which end or re-plan;
* :mod:`.regrouping` -- the intersection's vehicle regrouping (Sec. 5): which lane changes are ready and
  their gap test, the approach zone's fronts, the lane-change state, the merging;
* :mod:`.corridors` -- the intersection's corridor index (read by Sec. 5's regrouping and Sec. 4.2);
* :mod:`.virtual_platoon` -- the improved virtual platoon (Sec. 4.2), its
  nodes and their order: node heads, passing-order repair, tree-layers,
  members to detach;
* :mod:`.vp_references` -- the references the virtual platoon gives its
  vehicles (Sec. 4.2): formation following, the tree's references, the
  advisories, anticipation, the virtual lane's caps, stop flags;
* :mod:`.platoon_control` -- the intersection experts' control (Sec. 4.3, Sec. 5's controller):
  steering through the box, the safety envelope, the longitudinal law.

Same rule as :mod:`icv_envs.sim._kernels`: the same IEEE-754 operations on
the same values, in the same order, as the numpy code each kernel replaced
(comparisons, one subtraction and product per lane test, ``corr * BIG +
coord`` for the corridor keys; numpy's ``maximum(a, b)`` and ``minimum(a,
b)`` return ``b`` on a tie, its ``clip`` keeps the value on a tie), no
``fastmath``, so trajectories are the same bit for bit
(``tests/test_trajectory_hash.py``; the replaced code is frozen in
``tests/test_kernels.py``, ``tests/test_expert_kernels.py``,
``tests/test_corridor_index.py`` and ``tests/test_box_steering.py``).
Transcendental calls: the IDM's power stays NumPy's in the highway
expert, the kernels computing what lies around it; the lane-change curve's
``arcsinh`` and ``sinh`` and the pure pursuit's ``hypot`` and ``arctan``
are libm's inside one kernel each from stop 49
(:mod:`icv_envs.formation._kernels`), as the intersection's steering's
already were: NumPy's float64 loops are libm's up to AVX2 (the rule and
its AVX-512 caveat: :mod:`icv_envs.sim._kernels`).
Kernels added from stop 36 that divide use ``error_model="numpy"`` (IEEE
``inf``/``nan`` as NumPy's, no ``ZeroDivisionError``).
"""

from icv_envs.policies._kernels.corridors import corridor_add_signals, corridor_index, corridor_neighbours
from icv_envs.policies._kernels.formation_expert import (
    desired_lane_rows,
    exit_lanes,
    expert_accelerations,
    expert_control_rows,
    expert_lane_speeds,
    free_speed_pow,
    free_speed_pow_rows,
    free_speed_ratio,
    lane_end_escape,
    lane_speed_rows,
    preview_points,
    safety_cap,
)
from icv_envs.policies._kernels.lane_changes import lane_change_starts, lane_changes_ended
from icv_envs.policies._kernels.laws import idm_free_pow, normalised_actions
from icv_envs.policies._kernels.regrouping import (
    approach_fronts,
    lane_change_gaps,
    lane_change_progress,
    lane_change_ready,
    lane_change_state,
    merge_pairs,
    regroup_pass,
    segment_bounds,
    stuck_in_zone,
)
from icv_envs.policies._kernels.platoon_control import (
    box_obstacle_rows,
    box_steering,
    envelope_pairs,
    platoon_accelerations,
    platoon_actions_rows,
    stop_line_caps,
)
from icv_envs.policies._kernels.virtual_platoon import (
    detach_candidates,
    node_heads,
    nodes_cleared,
    repair_order,
    tree_layers,
    vp_tree,
    zone_orphans,
)
from icv_envs.policies._kernels.vp_references import (
    anticipated_references,
    follow_references,
    observation_references,
    stop_flags,
    tree_references,
    virtual_caps,
    vp_references,
)

__all__ = ["anticipated_references", "detach_candidates", "box_obstacle_rows", "box_steering", "node_heads", "corridor_add_signals", "corridor_index", "corridor_neighbours", "desired_lane_rows",
           "envelope_pairs", "exit_lanes", "expert_accelerations", "expert_control_rows", "expert_lane_speeds",
           "follow_references", "free_speed_pow", "idm_free_pow", "free_speed_pow_rows", "free_speed_ratio",
           "approach_fronts", "lane_change_gaps", "lane_change_progress", "lane_change_ready", "lane_change_starts", "lane_change_state", "lane_changes_ended", "lane_end_escape", "merge_pairs", "lane_speed_rows", "nodes_cleared", "normalised_actions", "observation_references",
           "platoon_accelerations", "platoon_actions_rows", "preview_points", "regroup_pass", "repair_order", "safety_cap", "segment_bounds", "stop_flags", "stop_line_caps", "stuck_in_zone", "tree_layers",
           "tree_references", "virtual_caps", "vp_references", "vp_tree", "zone_orphans"]
