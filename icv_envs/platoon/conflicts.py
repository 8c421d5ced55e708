"""Conflict model of the 12 movements, derived from geometry and lane use.

Paper Sec. 4.2 (Fig. "conflict relationships", lost in print), docs/intersection.md#conflicts.
Three kinds of conflict between two movements ``i != j``:

- ``"crossing"``: some lane path of ``i`` and some lane path of ``j`` (over the
  approach lanes the lane-use table allows, see
  :func:`~icv_envs.platoon.geometry.lane_path`) intersect at a point strictly
  inside the box ``|x|, |y| < box_half``.  Touching at the box edge (a shared
  stop-line start point or a shared exit point) is not a crossing: those are
  the diverging / converging cases.
- ``"diverging"``: ``i`` and ``j`` come from the same leg and can use the same
  approach lane.
- ``"converging"``: ``i`` and ``j`` leave by the same leg and can end in the
  same departure lane (index from
  :func:`~icv_envs.platoon.geometry.departure_lane`).

A movement conflicts with itself (kind ``"self"``, diagonal True).  Nothing is
typed in: another lane-use table or departure rule gives its own matrix.

Opposing left turns (N-left vs S-left, E-left vs W-left) are defined NOT to
conflict (paper Sec. 4.2: "achieved by special designing of intersection
structure"): with ``opposing_left_conflict=False`` (default) every kind
derived for such a pair is moved to ``waived`` and the matrix entry is False.
With ``opposing_left_conflict=True`` the pair keeps whatever the geometry and
lanes give.  With the presets (left turns from lane 0 only) the two wide
quarter circles (radius ``box_half + w/2``, centred on opposite box corners)
do not meet, so the switch changes nothing; a table allowing left turns from
lane 1 makes them cross, and then the switch is what removes that conflict.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from .geometry import (
    DEFAULT_BOX_HALF,
    DEFAULT_LANE_WIDTH,
    DEFAULT_N_POINTS,
    DEPARTURE_RULES,
    LEGS,
    MOVEMENTS,
    TURNS,
    departure_lane,
    lane_path,
    lane_use_table,
    movement_name,
    path_length,
)

__all__ = [
    "CONFLICT_KINDS",
    "OPPOSING_LEFT_PAIRS",
    "ConflictModel",
    "conflict_model",
    "conflicts_report",
    "format_matrix",
    "polyline_intersections",
    "required_layer_gap",
]

#: Kinds of conflict, in report order.
CONFLICT_KINDS: tuple[str, ...] = ("crossing", "diverging", "converging", "self")
#: Movement-id pairs of opposing left turns (N-left/S-left, E-left/W-left).
OPPOSING_LEFT_PAIRS: tuple[tuple[int, int], ...] = ((0, 6), (3, 9))

_EMPTY: frozenset = frozenset()


# ----------------------------------------------------------------------------
# polyline intersection
# ----------------------------------------------------------------------------
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def polyline_intersections(p, q, eps: float = 1e-9) -> np.ndarray:
    """All intersection points of polylines ``p (K1, 2)`` and ``q (K2, 2)``.

    Vectorised over all segment pairs.  Proper and touching intersections are
    returned; a collinear overlap contributes the midpoint of the overlap.

    Returns:
        float64 ``(n, 4)`` rows ``(x, y, s_p, s_q)`` with the arc length of the
        point along ``p`` and along ``q`` (duplicates at shared vertices are
        not removed).
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    a0, da = p[:-1], np.diff(p, axis=0)
    b0, db = q[:-1], np.diff(q, axis=0)
    la = np.linalg.norm(da, axis=1)
    lb = np.linalg.norm(db, axis=1)
    sa = np.concatenate([[0.0], np.cumsum(la)])[:-1]
    sb = np.concatenate([[0.0], np.cumsum(lb)])[:-1]
    A0, DA = a0[:, None, :], da[:, None, :]
    B0, DB = b0[None, :, :], db[None, :, :]
    w = B0 - A0
    den = _cross(DA, DB)  # (n1, n2)
    scale = la[:, None] * lb[None, :]
    par = np.abs(den) <= eps * np.maximum(scale, 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = _cross(w, DB) / den
        u = _cross(w, DA) / den
    hit = ~par & (t >= -eps) & (t <= 1 + eps) & (u >= -eps) & (u <= 1 + eps)
    ii, jj = np.nonzero(hit)
    tt = np.clip(t[ii, jj], 0.0, 1.0)
    uu = np.clip(u[ii, jj], 0.0, 1.0)
    pts = a0[ii] + tt[:, None] * da[ii]
    rows = [np.column_stack([pts, sa[ii] + tt * la[ii], sb[jj] + uu * lb[jj]])]
    # collinear overlaps
    col = par & (np.abs(_cross(w, DA)) <= eps * np.maximum(la[:, None] ** 2, 1e-300))
    for i, j in zip(*np.nonzero(col)):
        r2 = la[i] ** 2
        t0 = float(np.dot(b0[j] - a0[i], da[i]) / r2)
        t1 = float(np.dot(b0[j] + db[j] - a0[i], da[i]) / r2)
        lo, hi = max(0.0, min(t0, t1)), min(1.0, max(t0, t1))
        if lo <= hi + eps:
            tm = 0.5 * (lo + hi)
            pt = a0[i] + tm * da[i]
            um = float(np.dot(pt - b0[j], db[j]) / lb[j] ** 2)
            rows.append(np.array([[pt[0], pt[1], sa[i] + tm * la[i], sb[j] + um * lb[j]]]))
    return np.concatenate(rows, axis=0)


# ----------------------------------------------------------------------------
# the model
# ----------------------------------------------------------------------------
@dataclass(frozen=True)
class ConflictModel:
    """Conflicts between the 12 movements (see the module docstring).

    Attributes:
        matrix: ``(12, 12)`` bool, symmetric, True diagonal; ``matrix[i, j]``
            iff ``kinds[i, j]`` is non-empty.
        kinds: ``(12, 12)`` object array of frozensets of ``CONFLICT_KINDS``.
        waived: ``{(i, j): kinds}`` (``i < j``) removed because opposing left
            turns are defined not to conflict.
        crossings: ``{(i, j): (n, 6) array}`` (``i < j``) of interior crossing
            points ``(x, y, s_i, s_j, lane_i, lane_j)``: arc lengths along the
            lane paths of ``i`` and ``j`` from their stop lines.
        lane_use: validated lane-use table ``{m: lanes}``.
        lane_use_name: preset name or ``"custom"``.
        paths: ``{(m, lane): (K, 2) polyline}`` for every allowed lane.
        opposing_left_conflict, lane_width, box_half, rule: the parameters.
    """

    matrix: np.ndarray
    kinds: np.ndarray
    waived: dict
    crossings: dict
    lane_use: dict
    lane_use_name: str
    paths: dict = field(repr=False)
    opposing_left_conflict: bool = False
    lane_width: float = DEFAULT_LANE_WIDTH
    box_half: float = DEFAULT_BOX_HALF
    rule: str = "same"

    def kind_matrix(self, kind: str) -> np.ndarray:
        """``(12, 12)`` bool matrix of the pairs whose kinds contain ``kind``."""
        if kind not in CONFLICT_KINDS:
            raise ValueError(f"unknown conflict kind {kind!r}; allowed: {', '.join(CONFLICT_KINDS)}")
        return np.vectorize(lambda s: kind in s, otypes=[bool])(self.kinds)


def conflict_model(lane_use="paper", opposing_left_conflict: bool = False,
                   lane_width: float = DEFAULT_LANE_WIDTH, box_half: float = DEFAULT_BOX_HALF,
                   rule: str = "same", n_points: int = DEFAULT_N_POINTS) -> ConflictModel:
    """Derive the movement conflict model (paper Sec. 4.2) from geometry and lanes.

    Args:
        lane_use: preset name (``LANE_USE_PRESETS``) or a table accepted by
            :func:`~icv_envs.platoon.geometry.lane_use_table`.
        opposing_left_conflict: keep the derived conflict between opposing
            left turns (default False: the paper defines them conflict-free).
        lane_width, box_half: geometry in metres.
        rule: departure lane rule (``DEPARTURE_RULES``).
        n_points: polyline resolution of the lane paths.

    Returns:
        A :class:`ConflictModel`.

    Raises:
        ValueError: bad lane-use table, geometry or rule.
    """
    if not isinstance(opposing_left_conflict, (bool, np.bool_)):
        raise ValueError(
            f"opposing_left_conflict must be a bool, got {opposing_left_conflict!r}"
        )
    if rule not in DEPARTURE_RULES:
        raise ValueError(f"unknown departure rule {rule!r}; allowed: {', '.join(DEPARTURE_RULES)}")
    name = lane_use if isinstance(lane_use, str) else "custom"
    table = lane_use_table(lane_use)
    n = len(MOVEMENTS)
    paths = {
        (m, a): lane_path(m, a, lane_width, box_half, n_points, rule)
        for m in range(n) for a in table[m]
    }
    bh = float(box_half)
    tol = 1e-6 * max(bh, 1.0)
    kinds = np.empty((n, n), dtype=object)
    crossings: dict = {}
    for i in range(n):
        kinds[i, i] = frozenset({"self"})
    for i in range(n):
        li, ti = divmod(i, 3)
        ei = (li + 1 + ti) % 4
        for j in range(i + 1, n):
            lj, tj = divmod(j, 3)
            ej = (lj + 1 + tj) % 4
            k = set()
            if li == lj and set(table[i]) & set(table[j]):
                k.add("diverging")
            if ei == ej and ({departure_lane(i, a, rule) for a in table[i]}
                             & {departure_lane(j, b, rule) for b in table[j]}):
                k.add("converging")
            pts = []
            for a in table[i]:
                for b in table[j]:
                    x = polyline_intersections(paths[(i, a)], paths[(j, b)])
                    inside = np.max(np.abs(x[:, :2]), axis=1) < bh - tol
                    if np.any(inside):
                        y = x[inside]
                        pts.append(np.column_stack([y, np.full(len(y), a), np.full(len(y), b)]))
            if pts:
                k.add("crossing")
                c = np.concatenate(pts, axis=0)
                c.setflags(write=False)
                crossings[(i, j)] = c
            kinds[i, j] = kinds[j, i] = frozenset(k)
    waived: dict = {}
    if not opposing_left_conflict:
        for i, j in OPPOSING_LEFT_PAIRS:
            if kinds[i, j]:
                waived[(i, j)] = kinds[i, j]
            kinds[i, j] = kinds[j, i] = _EMPTY
    matrix = np.vectorize(bool, otypes=[bool])(kinds)
    matrix.setflags(write=False)
    kinds.setflags(write=False)
    return ConflictModel(
        matrix=matrix, kinds=kinds, waived=waived, crossings=crossings, lane_use=table,
        lane_use_name=name, paths=paths, opposing_left_conflict=bool(opposing_left_conflict),
        lane_width=float(lane_width), box_half=bh, rule=rule,
    )


def conflicts_report(lane_use="paper", opposing_left_conflict: bool = False, **kwargs) -> dict:
    """JSON-ready description of :func:`conflict_model` (``kwargs`` are passed on).

    Returns:
        ``{"lane_use": name or "custom", "opposing_left_conflict": bool,
        "departure_rule": str, "lane_width": float, "box_half": float,
        "movements": [{"id", "leg", "turn", "name", "exit_leg", "lanes",
        "departure_lanes"}], "matrix": 12x12 list of 0/1, "kinds": 12x12 list
        of sorted kind-name lists, "waived": {"i-j": [kinds]}}``.
    """
    model = conflict_model(lane_use, opposing_left_conflict, **kwargs)
    movements = []
    for m, (leg, turn) in enumerate(MOVEMENTS):
        lanes = list(model.lane_use[m])
        movements.append({
            "id": m,
            "leg": leg,
            "turn": turn,
            "name": movement_name(m),
            "exit_leg": LEGS[(LEGS.index(leg) + 1 + TURNS.index(turn)) % 4],
            "lanes": lanes,
            "departure_lanes": [departure_lane(m, a, model.rule) for a in lanes],
        })
    order = {k: i for i, k in enumerate(CONFLICT_KINDS)}
    report = {
        "lane_use": model.lane_use_name,
        "opposing_left_conflict": model.opposing_left_conflict,
        "departure_rule": model.rule,
        "lane_width": model.lane_width,
        "box_half": model.box_half,
        "movements": movements,
        "matrix": model.matrix.astype(int).tolist(),
        "kinds": [[sorted(s, key=order.__getitem__) for s in row] for row in model.kinds],
        "waived": {f"{i}-{j}": sorted(s, key=order.__getitem__) for (i, j), s in model.waived.items()},
    }
    json.dumps(report)  # guarantee JSON-readiness
    return report


def format_matrix(model_or_matrix) -> str:
    """ASCII rendering of a 12x12 conflict matrix (``X`` conflict, ``.`` none)."""
    mat = model_or_matrix.matrix if isinstance(model_or_matrix, ConflictModel) else np.asarray(model_or_matrix)
    labels = [f"{lg}{t[0].upper()}" for lg, t in MOVEMENTS]
    head = "        " + " ".join(f"{m:>2d}" for m in range(len(labels)))
    lines = [head]
    for i, lab in enumerate(labels):
        row = " ".join(" X" if mat[i, j] else " ." for j in range(mat.shape[1]))
        lines.append(f"{i:>2d} {lab:<4s} {row}")
    return "\n".join(lines)


def required_layer_gap(model: ConflictModel, vehicle_length: float = 5.0,
                       margin: float = 2.0) -> float:
    """Smallest tree-layer gap ``D_t`` that keeps conflict points clear (helper).

    Convention (ours, the paper only says "distance to the centre"): a vehicle
    on a lane path of length ``L`` at arc length ``s`` from the stop line has
    centre coordinate ``X = L / 2 - s`` (exact distance to the centre for
    straight movements; the path midpoint counts as "at the centre" for
    turns; ``X = L / 2 + d`` at ``d`` metres before the stop line).  Two
    conflicting vehicles driving at equal speed with ``X_j = X_i + D`` meet
    their conflict point (crossing point, shared stop-line point for
    diverging, shared exit point for converging) with a spacing of
    ``D - (X_j^c - X_i^c)`` in either order, so every conflicting pair needs
    ``D >= vehicle_length + margin + |X_i^c - X_j^c|``.  Returns the maximum
    over all conflicting pairs of the matrix (0 if there are none).
    """
    for nm, v in (("vehicle_length", vehicle_length), ("margin", margin)):
        if not isinstance(v, (int, float, np.floating, np.integer)) or isinstance(v, bool) \
                or not math.isfinite(float(v)) or v < 0:
            raise ValueError(f"{nm} must be a finite real number >= 0 (metres), got {v!r}")
    L = {k: path_length(p) for k, p in model.paths.items()}
    worst = 0.0
    n = model.matrix.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            ks = model.kinds[i, j]
            if not ks:
                continue
            if "crossing" in ks:
                for x, y, si, sj, a, b in model.crossings[(i, j)]:
                    d = abs((L[(i, int(a))] / 2 - si) - (L[(j, int(b))] / 2 - sj))
                    worst = max(worst, d)
            if "diverging" in ks:
                for a in set(model.lane_use[i]) & set(model.lane_use[j]):
                    worst = max(worst, abs(L[(i, a)] - L[(j, a)]) / 2)
            if "converging" in ks:
                for a in model.lane_use[i]:
                    for b in model.lane_use[j]:
                        if departure_lane(i, a, model.rule) == departure_lane(j, b, model.rule):
                            worst = max(worst, abs(L[(i, a)] - L[(j, b)]) / 2)
    off_diagonal = model.matrix & ~np.eye(n, dtype=bool)
    return float(worst + vehicle_length + margin) if off_diagonal.any() else 0.0

