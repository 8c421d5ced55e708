"""Optimal lane assignment (Dao et al. 2007), the paper's highway reference.

Dao, Clark, Plante, Cheng & Wang, "Optimized lane assignment using
inter-vehicle communication" (2007): at a ramp, vehicles are grouped by
destination and the share of each group put on each lane is the solution of
a linear program that minimises total travel time, subject to lane
capacity and to every vehicle being able to reach its exit from its lane.
The paper we reproduce (Xu et al. 2021, Sec. 6.1) describes it in one
paragraph ("taking the percentage of vehicles to be assigned to each lane as
independent variable, while maintaining the number of vehicles in a certain
lane less than the biggest lane capacity"); the exact formulation is not
public. Ours, as a pure function over numpy arrays::

    variables  p[e, l] >= 0   share of exit group e put on main lane l
               o[l]    >= 0   vehicles over lane l's capacity (elastic slack)
    minimise   sum_{e,l} n_e p[e, l] D_e / v_l                 (1) travel time
             + M sum_l o[l]                                    (2) capacity excess
             + eps sum_{e,l} n_e p[e, l]^2                     (3) tie-break
    subject to sum_l p[e, l] = 1                                (every vehicle gets a lane)
               sum_e n_e p[e, l] - o[l] <= C_l                  (lane capacity)
               p[e, l] = 0  if D_e < changes(l) * d_lc          (reachability)

* ``v_l``: the lanes' desired speeds, the paper's Table 1 (left three lanes
  25 m/s, fourth lane 20 m/s), so the fourth lane costs a vehicle going
  ``D`` metres ``D / 20 - D / 25`` seconds more.
* ``C_l``: the vehicles lane ``l`` holds over the planning window at its
  desired speed (``window / (s0 + v_l T + length)``, IDM's equilibrium
  spacing, computed by the caller); the constraint is a hard one up to the
  elastic slack ``o``, whose price ``M`` (default 1e4 s per vehicle, more
  than any trip's travel-time saving on a 10 km ring) makes the LP exceed a
  capacity only when the demand cannot be placed otherwise. It binds once
  the lanes fill; before, the travel-time term decides.
* reachability: a vehicle on lane ``l`` (0 = leftmost of ``L`` main lanes)
  merged from the ramp lane into lane ``L - 1`` and must get back to the
  ramp lane at its exit: ``changes(l) = (L - 1 - l) + (L - l)`` lane
  changes, each needing ``d_lc`` metres (default 100 m: a 3 s lane change at
  25 m/s plus one more second to find a gap). Lanes too far for the
  vehicle's trip are closed; the rightmost lane is always open. (On the
  paper's ring every exit is at least 1500 m past a merge, so this binds
  only for short trips; it is kept because the formulation needs it.)
* (3) is a tie-break: lanes 0-2 have equal speed, so the LP alone is
  degenerate and a simplex solver returns a vertex (every group on one
  lane). The strictly convex term ``eps n_e p^2`` selects, among the optimal
  travel-time solutions, the one that spreads each group evenly over lanes
  of equal cost. ``eps`` (default 1e-3 s per vehicle) is small enough that
  it never trades travel time: moving a share ``dp`` to a lane 5 m/s slower
  costs at least ``n_e dp * D (1/20 - 1/25)`` = 15 s x ``n_e dp`` for the
  shortest trip (1500 m), the tie-break gains at most ``2 eps n_e dp``.
  The quadratic is written exactly as a piecewise-linear convex function of
  ``K`` (default 50) equal pieces per variable, so the problem stays an LP
  (``scipy.optimize.linprog``, HiGHS) and its optimum is exact up to shares
  of ``1/K``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from icv_envs.formation._validate import finite

__all__ = ["optimal_lane_shares", "lane_changes_needed"]


def lane_changes_needed(n_lanes: int) -> np.ndarray:
    """Lane changes a ramp vehicle put on main lane ``l`` makes between its
    merge (into lane ``n_lanes - 1``) and its exit (onto the ramp lane)."""
    lanes = np.arange(n_lanes)
    return (n_lanes - 1 - lanes) + (n_lanes - lanes)


def optimal_lane_shares(
    counts,
    distances,
    lane_speeds,
    capacities,
    lane_change_distance: float = 100.0,
    *,
    tie_break: float = 1e-3,
    pieces: int = 50,
    excess_cost: float = 1e4,
    return_info: bool = False,
):
    """Shares ``p[e, l]`` of each exit group on each lane (rows sum to 1).

    ``counts[e]`` vehicles (>= 0) going ``distances[e]`` metres (>= 0) to
    their exit; ``lane_speeds[l]`` (> 0) and ``capacities[l]`` (> 0,
    vehicles) per main lane, lane 0 leftmost. ``lane_change_distance``
    (metres per lane change, >= 0) sets reachability; ``tie_break`` (eps,
    seconds per vehicle, >= 0), ``pieces`` (K >= 1) and ``excess_cost`` (M,
    seconds per vehicle over capacity, > 0) are documented in the module
    docstring. With ``return_info`` also returns a dict with the lane loads,
    the capacity excess and the travel time of the solution."""
    n = finite("counts", counts, ndim=1)
    D = finite("distances", distances, ndim=1)
    v = finite("lane_speeds", lane_speeds, ndim=1)
    C = finite("capacities", capacities, ndim=1)
    if n.shape != D.shape:
        raise ValueError(f"counts and distances must have the same shape, got {n.shape} and {D.shape}")
    if v.shape != C.shape or len(v) < 1:
        raise ValueError(f"lane_speeds and capacities must be non-empty and of one shape, got {v.shape}, {C.shape}")
    if (n < 0).any():
        raise ValueError(f"counts must be >= 0, got {n.tolist()}")
    if (D < 0).any():
        raise ValueError(f"distances must be >= 0, got {D.tolist()}")
    if (v <= 0).any():
        raise ValueError(f"lane_speeds must be > 0, got {v.tolist()}")
    if (C <= 0).any():
        raise ValueError(f"capacities must be > 0, got {C.tolist()}")
    for name, val, lo_ok in (("lane_change_distance", lane_change_distance, True), ("tie_break", tie_break, True),
                             ("excess_cost", excess_cost, False)):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not np.isfinite(val) or val < 0 or (
                val == 0 and not lo_ok):
            raise ValueError(f"{name} must be a finite number {'>= 0' if lo_ok else '> 0'}, got {val!r}")
    if isinstance(pieces, bool) or not isinstance(pieces, (int, np.integer)) or pieces < 1:
        raise ValueError(f"pieces must be an integer >= 1, got {pieces!r}")
    E, L, K = len(n), len(v), int(pieces)
    if E == 0:
        out = np.zeros((0, L))
        return (out, {"load": np.zeros(L), "excess": np.zeros(L), "travel_time": 0.0}) if return_info else out
    allowed = D[:, None] >= lane_changes_needed(L)[None, :] * float(lane_change_distance)
    allowed[:, L - 1] = True
    w = np.maximum(n, 1e-6)  # empty groups still get a (nearly costless) distribution
    # variables: q[e, l, k] (piece k of p[e, l], 0 <= q <= 1/K), then o[l]
    nq = E * L * K
    tt = (w[:, None] * D[:, None] / v[None, :])  # travel time of p[e, l] = 1
    # piece k of eps n p^2 on [k/K, (k+1)/K] has slope eps n (2k + 1) / K
    slope = float(tie_break) * w[:, None, None] * (2.0 * np.arange(K)[None, None, :] + 1.0) / K
    cost = np.concatenate([(tt[:, :, None] + slope).ravel(), np.full(L, float(excess_cost))])
    A_eq = np.zeros((E, nq + L))
    for e in range(E):
        A_eq[e, e * L * K:(e + 1) * L * K] = 1.0
    b_eq = np.ones(E)
    A_ub = np.zeros((L, nq + L))
    for lane in range(L):
        for e in range(E):
            A_ub[lane, (e * L + lane) * K:(e * L + lane + 1) * K] = w[e]
        A_ub[lane, nq + lane] = -1.0
    b_ub = C.copy()
    ub = np.repeat(np.where(allowed, 1.0 / K, 0.0).ravel(), K)
    bounds = np.column_stack([np.zeros(nq + L), np.concatenate([ub, np.full(L, np.inf)])])
    res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method="highs")
    if res.status != 0:  # pragma: no cover - the elastic LP is always feasible
        raise RuntimeError(f"lane assignment LP failed: {res.message}")
    p = np.clip(res.x[:nq].reshape(E, L, K).sum(axis=2), 0.0, None)
    p = p / p.sum(axis=1, keepdims=True)
    if not return_info:
        return p
    load = w @ p
    return p, {"load": load, "excess": res.x[nq:], "travel_time": float((tt * p).sum())}
