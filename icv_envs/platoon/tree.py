"""Improved virtual platoon: tree-layers and reference positions (paper Sec. 4.2).

docs/intersection.md#tree-layers.  In the coordinating zone every sub-formation (vehicles with the
same movement) is a node.  Real nodes are numbered ``1..m`` in increasing
distance of their first vehicle to the intersection centre; node 0 is the
virtual leader, which conflicts with every node.  The "improved depth-first
spanning tree" of Xu et al. (2018) assigns::

    depth(0) = 0
    depth(j) = 1 + max{ depth(i) : i < j and node i conflicts with node j }

Nodes of equal depth form tree-layer ``T_m`` and may cross the box together;
conflicting nodes never share a layer and keep their distance order.  This is
the smallest (elementwise) depth assignment with those two properties.

Indexing convention (our decision): every node-indexed array has the virtual
leader at index 0 and real node ``k`` at index ``k`` (the paper's numbering),
so :func:`tree_depths` takes the ``(m, m)`` conflict matrix of the REAL nodes
only, prepends the leader itself and returns ``m + 1`` depths.  Per-node
inputs that the leader does not have (distances, formation lengths) are
``(m,)`` arrays for real nodes ``1..m``.

All positions ``X`` are distances to the centre (origin at the centre, smaller
is closer, paper Sec. 4 remark).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..formation._validate import finite
from ._kernels import depths_of

__all__ = [
    "DEFAULT_D_T",
    "tree_depths",
    "tree_layers",
    "reference_positions",
    "follower_references",
    "node_conflicts",
]

#: Gap ``D_t`` (metres) between successive tree-layers; the paper gives no
#: value.  Chosen as 20 m = a 2 s time gap at the 10 m/s virtual-leader speed
#: (Table 2).  It must cover one vehicle (5 m), a safety margin and the offset
#: between where two conflicting movements meet their conflict point: N
#: straight and E straight in lane 1 cross at (-6, 6), 6 m BEFORE the centre
#: for one and 6 m AFTER it for the other, so with equal speeds their spacing
#: at the crossing is ``D_t - 12 m``.  :func:`~icv_envs.platoon.conflicts.
#: required_layer_gap` gives 19 m (12 + 5 + 2 m margin) for both presets; a
#: smaller value such as the 9 m in-zone formation gap ``L_s`` would let a
#: later layer reach such a crossing point before the earlier one cleared it.
DEFAULT_D_T: float = 20.0


def _bool_square(name: str, value) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise ValueError(f"{name} must be a square (m, m) matrix, got shape {arr.shape}")
    if arr.dtype != np.bool_:
        if arr.size and not np.all(np.isin(arr, (0, 1))):
            bad = arr[~np.isin(arr, (0, 1))]
            raise ValueError(f"{name} must hold booleans (or 0/1), got value(s) {bad[:5].tolist()}")
        arr = arr.astype(bool)
    if not np.array_equal(arr, arr.T):
        i, j = np.argwhere(arr != arr.T)[0]
        raise ValueError(
            f"{name} must be symmetric (conflict is mutual), got entry [{i}, {j}] = "
            f"{bool(arr[i, j])} but [{j}, {i}] = {bool(arr[j, i])}"
        )
    return arr


def tree_depths(conflict) -> np.ndarray:
    """Tree-layer (depth) of the virtual leader and each real node.

    Args:
        conflict: ``(m, m)`` symmetric bool matrix of the REAL nodes ``1..m``
            ordered by increasing distance of their first vehicle to the
            centre (row ``k - 1`` is node ``k``).  The diagonal is ignored.

    Returns:
        int64 ``(m + 1,)``: ``depths[0] = 0`` (virtual leader, which conflicts
        with all) and ``depths[k] = 1 + max{depths[i] : i < k, i conflicts with
        k}`` for ``k = 1..m``.

    Raises:
        ValueError: not square, not boolean or not symmetric.
    """
    # the leader conflicts with every node (depth 1 at least); compiled loop over the nodes
    return depths_of(_bool_square("conflict", conflict))


def tree_layers(depths) -> list[np.ndarray]:
    """Node indices per tree-layer: ``layers[d]`` = sorted nodes with depth ``d``.

    With :func:`tree_depths` output ``layers[0]`` is ``[0]`` (the leader) and
    ``layers[1]`` the paper's ``T_1``.  Empty layers (impossible for
    :func:`tree_depths` output) are kept as empty arrays.
    """
    d = finite("depths", depths, ndim=1)
    if d.size and (np.any(d < 0) or np.any(d != np.round(d))):
        bad = d[(d < 0) | (d != np.round(d))]
        raise ValueError(f"depths must be integers >= 0, got {bad.tolist()}")
    d = d.astype(np.int64)
    if d.size == 0:
        return []
    order = np.argsort(d, kind="stable")
    counts = np.bincount(d)
    return [np.sort(a) for a in np.split(order, np.cumsum(counts)[:-1])]


def _check_d_t(D_t) -> float:
    if isinstance(D_t, (bool, np.bool_)) or not isinstance(D_t, numbers.Real) \
            or not math.isfinite(float(D_t)) or float(D_t) < 0:
        raise ValueError(f"D_t must be a finite real number >= 0 (metres), got {D_t!r}")
    return float(D_t)


def reference_positions(first_dist, lengths, depths, D_t: float = DEFAULT_D_T) -> np.ndarray:
    """Reference positions of the first vehicle of every node (paper Sec. 4.2).

    ``X_0 = X_1^1 - D_t`` (the virtual leader is ``D_t`` ahead of node 1) and
    for node ``k`` in tree-layer ``m``::

        X_ref,1^k = X_0 + m D_t + sum_{i=0}^{m-1} max_{n in T_i} len_n

    with ``len_n = max_j x_gj^n`` the extent of formation ``n`` behind its first
    vehicle and ``len = 0`` for the leader.  Node 1 (depth 1) gets
    ``X_ref = X_1^1``: it is on its reference.

    Args:
        first_dist: ``(m,)`` distances ``X_1^k`` of the first vehicles of real
            nodes ``1..m`` to the centre, nondecreasing (the node order).
        lengths: ``(m,)`` formation lengths ``len_k >= 0`` (metres).
        depths: ``(m + 1,)`` depths as returned by :func:`tree_depths`
            (``depths[0] == 0``, others ``>= 1``).
        D_t: gap between successive tree-layers (metres, >= 0).

    Returns:
        float64 ``(m + 1,)``: index 0 is ``X_0``, index ``k`` is ``X_ref,1^k``.

    Raises:
        ValueError: shape mismatch, unsorted ``first_dist``, negative lengths,
            bad depths or ``D_t``.
    """
    x = finite("first_dist", first_dist, ndim=1)
    ln = finite("lengths", lengths, ndim=1)
    d = finite("depths", depths, ndim=1)
    D = _check_d_t(D_t)
    m = x.shape[0]
    if ln.shape != (m,) or d.shape != (m + 1,):
        raise ValueError(
            f"need first_dist (m,), lengths (m,) and depths (m + 1,); got shapes "
            f"{x.shape}, {ln.shape}, {d.shape}"
        )
    if m == 0:
        raise ValueError("first_dist must hold at least one real node, got an empty array")
    if np.any(np.diff(x) < 0):
        i = int(np.argmax(np.diff(x) < 0))
        raise ValueError(
            f"first_dist must be nondecreasing (nodes sorted by distance to the centre), "
            f"got {x[i]} before {x[i + 1]}"
        )
    if np.any(ln < 0):
        raise ValueError(f"lengths must be >= 0 (metres), got {ln[ln < 0].tolist()}")
    if d[0] != 0 or np.any(d[1:] < 1) or np.any(d != np.round(d)):
        raise ValueError(
            f"depths must be integers with depths[0] == 0 (leader) and depths[1:] >= 1, "
            f"got {d.tolist()}"
        )
    return _reference_positions(x, ln, d.astype(np.int64), D)


def _reference_positions(x: np.ndarray, ln: np.ndarray, d: np.ndarray, D: float) -> np.ndarray:
    """:func:`reference_positions` without its checks, for a caller whose
    inputs are right by construction (the intersection expert's tree: float64
    distances, sorted, lengths >= 0, int64 depths of :func:`tree_depths`)."""
    layer_max = np.zeros(int(d.max()) + 1)
    np.maximum.at(layer_max, d[1:], ln)  # layer 0 (leader) keeps length 0
    before = np.concatenate([[0.0], np.cumsum(layer_max)])  # before[m] = sum_{i<m}
    x0 = x[0] - D
    out = x0 + d * D + before[d]
    out[0] = x0
    return out


def follower_references(first_position, offsets) -> np.ndarray:
    """Followers' references ``X_ref,i^k = X_1^k + x_gi`` (paper eq. (xi)).

    Args:
        first_position: the ACTUAL position ``X_1^k`` of the formation's first
            vehicle (scalar, or an array broadcasting with ``offsets``, e.g.
            ``first_positions[node_of_vehicle]``).
        offsets: ``x_gi >= 0``, metres behind the first vehicle.

    Returns:
        float64 array of the broadcast shape.
    """
    x1 = finite("first_position", first_position)
    off = finite("offsets", offsets)
    if np.any(off < 0):
        raise ValueError(f"offsets must be >= 0 (metres behind the first vehicle), got {off[off < 0].tolist()}")
    try:
        return np.asarray(x1 + off, dtype=np.float64)
    except ValueError:
        raise ValueError(
            f"first_position {x1.shape} and offsets {off.shape} must broadcast"
        ) from None


def node_conflicts(movements_of_nodes, movement_conflict_matrix) -> np.ndarray:
    """Conflict matrix of nodes from their movements (input of :func:`tree_depths`).

    Args:
        movements_of_nodes: ``(m,)`` movement ids of real nodes ``1..m`` in
            node order.
        movement_conflict_matrix: ``(M, M)`` symmetric bool movement matrix
            (e.g. ``conflict_model(...).matrix``), whose True diagonal makes
            two nodes with the same movement conflict.

    Returns:
        bool ``(m, m)`` = ``matrix[mv][:, mv]``.
    """
    mat = _bool_square("movement_conflict_matrix", movement_conflict_matrix)
    mv = np.asarray(movements_of_nodes)
    if mv.ndim != 1:
        raise ValueError(f"movements_of_nodes must be 1-D, got shape {mv.shape}")
    if mv.size and (not np.issubdtype(mv.dtype, np.integer) or mv.min() < 0 or mv.max() >= mat.shape[0]):
        raise ValueError(
            f"movements_of_nodes must be integer ids in 0..{mat.shape[0] - 1}, got {mv.tolist()}"
        )
    mv = mv.astype(np.int64)
    return mat[np.ix_(mv, mv)]
