"""Assignment of vehicles to formation targets.

Paper Sec. 3.3 (Xu et al., IET ITS 2021): every vehicle is assigned to one
target so that the total cost ``sum_i F_w(i, a(i))`` is minimal over all
one-to-one assignments (a 0-1 integer programme, eq. (lp), i.e. the linear
assignment problem).  The paper solves it with the Hungarian algorithm; we use
``scipy.optimize.linear_sum_assignment`` (exact, O(N^3), deterministic).

Coordinates are in the formation frame (docs/formation.md#layers): ``x`` in metres BEHIND
the front target, ``y`` in lane ids (1 = leftmost).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from icv_envs.formation._validate import finite
from scipy.optimize import linear_sum_assignment

__all__ = ["DEFAULT_W1", "DEFAULT_W2", "assignment_cost", "assign_targets", "total_cost"]

#: Weight of the squared longitudinal distance (paper Sec. 3.3 / docs/formation.md#assignment).
DEFAULT_W1: float = 1.0
#: Weight of the squared number of lane changes (paper Sec. 3.3 / docs/formation.md#assignment).
DEFAULT_W2: float = 10.0


def _as_1d(name: str, values) -> np.ndarray:
    """``values`` as a finite float64 1-D array, else ValueError naming it."""
    return finite(name, values, ndim=1)


def _check_weight(name: str, w) -> float:
    if isinstance(w, (bool, np.bool_)) or not isinstance(w, numbers.Real):
        raise ValueError(f"{name} must be a finite real number >= 0, got {w!r}")
    wf = float(w)
    if not math.isfinite(wf) or wf < 0.0:
        raise ValueError(f"{name} must be a finite real number >= 0, got {w!r}")
    return wf


def _check_pair(xname: str, x, yname: str, y) -> tuple[np.ndarray, np.ndarray]:
    xa, ya = _as_1d(xname, x), _as_1d(yname, y)
    if xa.shape != ya.shape:
        raise ValueError(
            f"{xname} and {yname} must have the same shape, got {xa.shape} and {ya.shape}"
        )
    return xa, ya


def assignment_cost(
    veh_x,
    veh_lane,
    tgt_x,
    tgt_lane,
    w1: float = DEFAULT_W1,
    w2: float = DEFAULT_W2,
) -> np.ndarray:
    """Cost matrix ``C[i, j] = F_w(i, j)`` of assigning vehicle i to target j.

    Paper Sec. 3.3, cost function ``F_w``::

        F_w(i, j) = w1 (x_gj - x_vi)^2 + w2 (y_gj - y_vi)^2

    with ``x`` in metres behind the formation front and ``y`` in lane ids,
    both in the formation frame.  ``w1 = 1, w2 = 10`` by default (docs/formation.md#assignment).
    Lane ids may be fractional (a vehicle in the middle of a lane change).

    Args:
        veh_x, veh_lane: 1-D arrays (N,) of vehicle positions / lane ids.
        tgt_x, tgt_lane: 1-D arrays (M,) of target positions / lane ids.
        w1, w2: finite non-negative weights.

    Returns:
        float64 array (N, M).

    Raises:
        ValueError: non-1-D or non-finite inputs, ``veh_x``/``veh_lane`` or
            ``tgt_x``/``tgt_lane`` of different shapes, or a weight that is
            negative or not finite.
    """
    vx, vy = _check_pair("veh_x", veh_x, "veh_lane", veh_lane)
    gx, gy = _check_pair("tgt_x", tgt_x, "tgt_lane", tgt_lane)
    w1f, w2f = _check_weight("w1", w1), _check_weight("w2", w2)
    dx = gx[None, :] - vx[:, None]
    dy = gy[None, :] - vy[:, None]
    return w1f * dx * dx + w2f * dy * dy


def assign_targets(
    veh_x,
    veh_lane,
    tgt_x,
    tgt_lane,
    w1: float = DEFAULT_W1,
    w2: float = DEFAULT_W2,
) -> np.ndarray:
    """Minimum-total-cost one-to-one assignment of vehicles to targets.

    Paper Sec. 3.3, eq. (lp) with cost ``F_w`` (see :func:`assignment_cost`),
    solved exactly by ``scipy.optimize.linear_sum_assignment`` in place of the
    paper's Hungarian algorithm.  The result is deterministic for identical
    inputs (ties are broken by the solver's fixed order).

    Args:
        veh_x, veh_lane: 1-D arrays (N,) of vehicle positions / lane ids.
        tgt_x, tgt_lane: 1-D arrays (N,) of target positions / lane ids;
            there must be exactly as many targets as vehicles.
        w1, w2: finite non-negative weights.

    Returns:
        int64 array (N,): ``result[i]`` is the index of the target assigned to
        vehicle ``i``; a permutation of ``0..N-1``.

    Raises:
        ValueError: as :func:`assignment_cost`, or ``N != M``.
    """
    cost = assignment_cost(veh_x, veh_lane, tgt_x, tgt_lane, w1, w2)
    n, m = cost.shape
    if n != m:
        raise ValueError(
            f"need as many targets as vehicles, got {n} vehicles and {m} targets"
        )
    return _solve(cost)


def _solve(cost: np.ndarray) -> np.ndarray:
    n = cost.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(n, dtype=np.int64)
    out[rows] = cols
    return out


def total_cost(cost, assignment) -> float:
    """Total cost ``sum_i cost[i, assignment[i]]`` of an assignment (eq. (lp)).

    Args:
        cost: 2-D finite array (N, M).
        assignment: integer array (N,) of target indices in ``0..M-1``.

    Raises:
        ValueError: ``cost`` not 2-D / not finite, ``assignment`` not of shape
            (N,), not integer, or with an index out of range.
    """
    c = np.asarray(cost, dtype=np.float64)
    if c.ndim != 2:
        raise ValueError(f"cost must be a 2-D array, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError("cost must be finite, got non-finite entries")
    a = np.asarray(assignment)
    if a.shape != (c.shape[0],):
        raise ValueError(
            f"assignment must have shape ({c.shape[0]},) to match cost {c.shape}, got {a.shape}"
        )
    if a.size == 0:
        return 0.0
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"assignment must hold integer indices, got dtype {a.dtype}")
    if a.min() < 0 or a.max() >= c.shape[1]:
        raise ValueError(
            f"assignment indices must be in 0..{c.shape[1] - 1}, got {a.tolist()}"
        )
    return float(c[np.arange(c.shape[0]), a].sum())
