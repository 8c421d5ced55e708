"""Optimal lane assignment (Dao et al. 2007), the paper's highway reference.

The exact formulation is not public; this is the reconstruction of
docs/methods.md#lane-lp as a pure function over numpy arrays:

    variables  p[e, l] >= 0   share of exit group e put on lane l
    minimise   sum_{e,l} n_e p[e, l] D_e / v_l           (total travel time)
    subject to sum_l p[e, l] = 1                          (every vehicle gets a lane)
               sum_e n_e p[e, l] <= C_l                   (lane capacity)
               p[e, l] = 0  where exit e is too close to reach from lane l

solved with ``scipy.optimize.linprog`` (HiGHS). "Too close" means fewer than
``(n_lanes - l) * min_distance_per_lane`` metres to the diverge segment:
from lane l a vehicle needs ``n_lanes - l`` lane changes to reach the ramp
lane. The rightmost lane is always allowed (a vehicle must be somewhere).
When demand exceeds total capacity the capacities are scaled up just enough
to make the problem feasible (documented choice: the reference then still
spreads vehicles by cost instead of failing).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from icv_envs.formation._validate import finite

__all__ = ["optimal_lane_shares"]


def optimal_lane_shares(
    counts,
    distances,
    lane_speeds,
    capacities,
    min_distance_per_lane: float = 250.0,
) -> np.ndarray:
    """Shares ``p[e, l]`` of each exit group on each lane (rows sum to 1).

    ``counts[e]`` vehicles (>= 0), ``distances[e]`` metres to their exit (> 0
    for groups that can still exit), ``lane_speeds[l]`` (> 0) and
    ``capacities[l]`` (> 0) per main lane, lane 0 leftmost."""
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
    if (v <= 0).any():
        raise ValueError(f"lane_speeds must be > 0, got {v.tolist()}")
    if (C <= 0).any():
        raise ValueError(f"capacities must be > 0, got {C.tolist()}")
    if not np.isfinite(min_distance_per_lane) or min_distance_per_lane < 0:
        raise ValueError(f"min_distance_per_lane must be >= 0, got {min_distance_per_lane!r}")
    E, L = len(n), len(v)
    if E == 0:
        return np.zeros((0, L))
    need = (L - np.arange(L)) * float(min_distance_per_lane)  # metres needed from lane l
    allowed = D[:, None] >= need[None, :]
    allowed[:, L - 1] = True
    w = np.maximum(n, 1e-9)  # empty groups still get a (costless) distribution
    cost = (w[:, None] * np.maximum(D, 0.0)[:, None] / v[None, :]).ravel()
    # equality: each group's shares sum to one
    A_eq = np.zeros((E, E * L))
    for e in range(E):
        A_eq[e, e * L:(e + 1) * L] = 1.0
    b_eq = np.ones(E)
    # capacity per lane
    A_ub = np.zeros((L, E * L))
    for lane in range(L):
        A_ub[lane, lane::L] = w
    scale = max(1.0, float(w.sum()) / float(C.sum()) * 1.0001)
    b_ub = C * scale
    bounds = [(0.0, None if ok else 0.0) for ok in allowed.ravel()]
    for _ in range(8):
        res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, bounds=bounds, method="highs")
        if res.status == 0:
            p = res.x.reshape(E, L)
            p = np.clip(p, 0.0, None)
            return p / p.sum(axis=1, keepdims=True)
        b_ub = b_ub * 2.0  # reachability can make a lane's capacity binding: relax and retry
    raise RuntimeError(f"lane assignment LP failed: {res.message}")  # pragma: no cover
