"""Geometry of the multi-lane unsignalized intersection (paper Sec. 4, docs/intersection.md#geometry).

Pure numpy, simulator-independent: legs, movements, lane-use tables and the
centreline polylines of every (movement, approach lane) inside the box.

Coordinates
-----------
Origin at the intersection centre, ``x`` east, ``y`` north, metres.  Right-hand
traffic.  Each of the four legs ``N, E, S, W`` (the leg a vehicle comes FROM)
has ``N_LANES = 3`` approach lanes and 3 departure lanes of width
``lane_width`` (4 m).  Lanes are numbered from the centre line outwards:
0 = leftmost (next to the centre line) .. 2 = rightmost (kerb side), for
approach and departure lanes alike.  The box ("conflict area") is the square
``|x|, |y| <= box_half`` (default ``3 * lane_width = 12`` m); the stop line of a
leg is its box edge.

Movement numbering (the paper's own figure is lost; this is our choice)
-----------------------------------------------------------------------
``m = 3 * leg_index + turn_index`` with legs ``N=0, E=1, S=2, W=3`` and turns
``left=0, straight=1, right=2``::

                           N  (ids 0 left, 1 straight, 2 right)
                        approach  |  departure
                        2   1   0 | 0   1   2
                        v   v   v | ^   ^   ^
                   +--------------------------------+
     departure 2 <-|                                |<- approach 2
     departure 1 <-|                                |<- approach 1
     departure 0 <-|                                |<- approach 0
     - - - - - - - |    box |x|, |y| <= box_half    | - - - - - - -   E
      approach 0 ->|    origin (0, 0) at the centre |-> departure 0   (ids 3 L,
      approach 1 ->|                                |-> departure 1    4 S, 5 R)
      approach 2 ->|                                |-> departure 2
   W               +--------------------------------+
   (ids 9 L,            v   v   v | ^   ^   ^
    10 S, 11 R)         2   1   0 | 0   1   2
                        departure |  approach
                           S  (ids 6 left, 7 straight, 8 right)

(Approach lanes of N lie west of the centre line at ``x = -(a + 1/2) w``,
its departure lanes east at ``x = +(j + 1/2) w``; the other legs are the
same picture rotated.)  Exit legs: left ``leg -> leg + 1`` (N->E, E->S,
S->W, W->N), straight ``leg -> leg + 2``, right ``leg -> leg + 3``.

Departure lane rule (documented choice)
---------------------------------------
:func:`departure_lane` with ``rule="same"`` (default): a vehicle leaves in the
departure lane with the SAME index as its approach lane (left turns from lane
0 -> departure lane 0, straight a -> a, right from lane 1 -> 1, from lane 2 ->
2).  This is the usual "turn into the corresponding lane" discipline and the
only rule for which every turn is an exact quarter circle tangent at both ends
centred on a box corner (right turns: radius ``box_half - (a + 1/2) w``,
tight; left turns: radius ``box_half + (a + 1/2) w``, wide) so that turns
from adjacent lanes are concentric and never cross.  ``rule="kerb"`` (left ->
0, straight -> same index, right -> 2) is available; its right turns from an
inner lane are a straight piece + quarter circle + straight piece.
"""

from __future__ import annotations

import math
import numbers
import operator
from collections.abc import Mapping

import numpy as np

from ..formation._validate import finite

__all__ = [
    "LEGS",
    "TURNS",
    "N_LANES",
    "MOVEMENTS",
    "DEFAULT_LANE_WIDTH",
    "DEFAULT_BOX_HALF",
    "DEFAULT_N_POINTS",
    "DEPARTURE_RULES",
    "LANE_USE_PRESETS",
    "leg_index",
    "turn_index",
    "movement_id",
    "movement_name",
    "exit_leg",
    "approach_heading",
    "exit_heading",
    "lane_use_table",
    "departure_lane",
    "approach_centerline",
    "departure_centerline",
    "lane_path",
    "path_length",
    "path_headings",
]

#: Legs in index order (the leg a vehicle comes FROM).
LEGS: tuple[str, ...] = ("N", "E", "S", "W")
#: Turns in index order.
TURNS: tuple[str, ...] = ("left", "straight", "right")
#: Approach (and departure) lanes per leg (paper Sec. 4: three of each).
N_LANES: int = 3
#: The 12 movements ``(leg, turn)`` in id order ``m = 3 * leg + turn``.
MOVEMENTS: tuple[tuple[str, str], ...] = tuple((lg, t) for lg in LEGS for t in TURNS)
#: Lane width in metres (4 m).
DEFAULT_LANE_WIDTH: float = 4.0
#: Half side of the box: three lanes of 4 m on each side of the centre line.
DEFAULT_BOX_HALF: float = 12.0
#: Points of a path polyline (enough for ~0.4 m chords on the widest left turn).
DEFAULT_N_POINTS: int = 61
#: Departure lane rules understood by :func:`departure_lane`.
DEPARTURE_RULES: tuple[str, ...] = ("same", "kerb")

#: Lane-use presets, identical for all four legs (turn -> allowed approach lanes).
#: ``paper``: lane 0 left; lane 1 straight and right; lane 2 right (paper Sec. 4,
#: "left turn; straight (and right); right turn").  ``exclusive``: one movement
#: per lane.
LANE_USE_PRESETS: dict[str, dict[str, tuple[int, ...]]] = {
    "paper": {"left": (0,), "straight": (1,), "right": (1, 2)},
    "exclusive": {"left": (0,), "straight": (1,), "right": (2,)},
}

# outward unit vector of each leg (from the centre towards that leg)
_OUT = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, -1.0], [-1.0, 0.0]])


def _right_of(d: np.ndarray) -> np.ndarray:
    """Unit vector 90 degrees clockwise of direction ``d`` (its right-hand side)."""
    return np.array([d[1], -d[0]])


# ----------------------------------------------------------------------------
# validation helpers
# ----------------------------------------------------------------------------
def _positive(name: str, value) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a finite real number > 0 (metres), got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be a finite real number > 0 (metres), got {value!r}")
    return v


def _check_box(lane_width, box_half) -> tuple[float, float]:
    w = _positive("lane_width", lane_width)
    b = _positive("box_half", box_half)
    if b < N_LANES * w - 1e-9:
        raise ValueError(
            f"box_half must be >= {N_LANES} * lane_width = {N_LANES * w} so the lanes fit "
            f"in the box, got {box_half!r}"
        )
    return w, b


def _index(name: str, value, names: tuple[str, ...]) -> int:
    """Index of ``value`` given as a name in ``names`` or an integer index."""
    if isinstance(value, str):
        if value in names:
            return names.index(value)
        raise ValueError(f"unknown {name} {value!r}; allowed: {', '.join(names)} or 0..{len(names) - 1}")
    if not isinstance(value, (bool, np.bool_)):
        try:
            i = operator.index(value)
        except TypeError:
            i = None
        if i is not None and 0 <= i < len(names):
            return int(i)
    raise ValueError(f"unknown {name} {value!r}; allowed: {', '.join(names)} or 0..{len(names) - 1}")


def leg_index(leg) -> int:
    """Index 0..3 of ``leg`` (``"N"``, ``"E"``, ``"S"``, ``"W"`` or an index)."""
    return _index("leg", leg, LEGS)


def turn_index(turn) -> int:
    """Index 0..2 of ``turn`` (``"left"``, ``"straight"``, ``"right"`` or an index)."""
    return _index("turn", turn, TURNS)


def _movement(movement) -> int:
    """Movement id 0..11 from an id or a ``(leg, turn)`` pair."""
    if isinstance(movement, tuple) and len(movement) == 2:
        return movement_id(*movement)
    if not isinstance(movement, (bool, np.bool_, str)):
        try:
            m = operator.index(movement)
        except TypeError:
            m = None
        if m is not None and 0 <= m < len(MOVEMENTS):
            return int(m)
    raise ValueError(
        f"unknown movement {movement!r}; allowed: an id 0..{len(MOVEMENTS) - 1} "
        f"or a (leg, turn) pair with leg in {LEGS} and turn in {TURNS}"
    )


def _lane(name: str, value) -> int:
    if not isinstance(value, (bool, np.bool_)):
        try:
            i = operator.index(value)
        except TypeError:
            i = None
        if i is not None and 0 <= i < N_LANES:
            return int(i)
    raise ValueError(f"{name} must be a lane index in 0..{N_LANES - 1}, got {value!r}")


# ----------------------------------------------------------------------------
# movements
# ----------------------------------------------------------------------------
def movement_id(leg, turn) -> int:
    """Movement id ``3 * leg_index + turn_index`` (0..11), see the module diagram."""
    return 3 * leg_index(leg) + turn_index(turn)


def movement_name(movement) -> str:
    """``"N-left"`` style name of a movement id or ``(leg, turn)`` pair."""
    leg, turn = MOVEMENTS[_movement(movement)]
    return f"{leg}-{turn}"


def exit_leg(leg, turn) -> str:
    """Leg the movement leaves by: left ``+1``, straight ``+2``, right ``+3`` (mod 4)."""
    return LEGS[(leg_index(leg) + 1 + turn_index(turn)) % 4]


def approach_heading(leg) -> float:
    """Heading (radians, ``atan2`` convention, 0 = east) of traffic approaching from ``leg``."""
    d = -_OUT[leg_index(leg)]
    return float(math.atan2(d[1], d[0]))


def exit_heading(leg) -> float:
    """Heading (radians) of traffic departing the box along ``leg``."""
    d = _OUT[leg_index(leg)]
    return float(math.atan2(d[1], d[0]))


# ----------------------------------------------------------------------------
# lane use
# ----------------------------------------------------------------------------
def _lanes_tuple(key, lanes) -> tuple[int, ...]:
    if isinstance(lanes, (str, bytes)) or not hasattr(lanes, "__iter__"):
        lanes = (lanes,)
    out = sorted({_lane(f"lane of movement {key!r}", a) for a in lanes})
    return tuple(out)


def lane_use_table(name_or_dict="paper") -> dict[int, tuple[int, ...]]:
    """Validated lane-use table: movement id -> sorted tuple of approach lanes.

    Args:
        name_or_dict: a preset name in ``LANE_USE_PRESETS`` (``"paper"`` or
            ``"exclusive"``) or a mapping whose keys are turn names (applied
            to all four legs), movement ids 0..11 or ``(leg, turn)`` pairs,
            and whose values are lane indices or iterables of them (0 =
            leftmost .. 2 = kerb).  Later, more specific keys (ids, pairs)
            override turn-name keys.

    Returns:
        ``{m: lanes}`` for all 12 movements, lanes sorted and unique.

    Raises:
        ValueError: unknown preset name (lists the presets); unknown key; a
            lane index outside ``0..2``; a movement left without a lane
            (names the movement).
    """
    if isinstance(name_or_dict, str):
        if name_or_dict not in LANE_USE_PRESETS:
            raise ValueError(
                f"unknown lane-use preset {name_or_dict!r}; allowed: "
                f"{', '.join(LANE_USE_PRESETS)} or a dict movement -> lanes"
            )
        name_or_dict = LANE_USE_PRESETS[name_or_dict]
    if not isinstance(name_or_dict, Mapping):
        raise ValueError(
            f"lane use must be a preset name ({', '.join(LANE_USE_PRESETS)}) or a dict "
            f"movement -> lanes, got {name_or_dict!r}"
        )
    table: dict[int, tuple[int, ...]] = {}
    # turn-name keys first, then specific ones
    for key, lanes in name_or_dict.items():
        if isinstance(key, str) and key in TURNS:
            for lg in range(4):
                table[3 * lg + TURNS.index(key)] = _lanes_tuple(key, lanes)
    for key, lanes in name_or_dict.items():
        if isinstance(key, str) and key in TURNS:
            continue
        try:
            m = _movement(key)
        except ValueError:
            raise ValueError(
                f"unknown lane-use key {key!r}; allowed: a turn name {TURNS}, a movement "
                f"id 0..{len(MOVEMENTS) - 1} or a (leg, turn) pair"
            ) from None
        table[m] = _lanes_tuple(key, lanes)
    for m in range(len(MOVEMENTS)):
        if not table.get(m):
            raise ValueError(
                f"movement {m} ({movement_name(m)}) has no approach lane in the lane-use "
                f"table; every movement needs at least one lane in 0..{N_LANES - 1}"
            )
    return {m: table[m] for m in range(len(MOVEMENTS))}


def departure_lane(movement, approach_lane, rule: str = "same") -> int:
    """Departure lane index used by ``movement`` entered from ``approach_lane``.

    ``rule="same"`` (default, see the module docstring): the same index as the
    approach lane, for every turn.  ``rule="kerb"``: left -> 0, straight ->
    same index, right -> ``N_LANES - 1`` (kerb lane).

    Raises:
        ValueError: unknown movement, lane outside ``0..2`` or unknown rule.
    """
    m = _movement(movement)
    a = _lane("approach_lane", approach_lane)
    if rule not in DEPARTURE_RULES:
        raise ValueError(f"unknown departure rule {rule!r}; allowed: {', '.join(DEPARTURE_RULES)}")
    if rule == "same":
        return a
    turn = m % 3
    return {0: 0, 1: a, 2: N_LANES - 1}[turn]


# ----------------------------------------------------------------------------
# centrelines
# ----------------------------------------------------------------------------
def _approach_point(leg: int, lane: int, w: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Stop-line point and unit direction of travel of an approach lane."""
    out = _OUT[leg]
    d = -out
    return b * out + (lane + 0.5) * w * _right_of(d), d


def _departure_point(leg: int, lane: int, w: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Box-edge point and unit direction of travel of a departure lane."""
    out = _OUT[leg]
    return b * out + (lane + 0.5) * w * _right_of(out), out


def approach_centerline(leg, lane, distance, lane_width: float = DEFAULT_LANE_WIDTH,
                        box_half: float = DEFAULT_BOX_HALF) -> np.ndarray:
    """Point(s) of approach ``lane`` of ``leg`` at ``distance`` metres before the stop line.

    Args:
        leg: ``"N"``..``"W"`` or 0..3.
        lane: approach lane 0 (leftmost) .. 2 (kerb).
        distance: scalar or array of metres before the stop line (negative
            values lie inside the box, on the lane's straight extension).

    Returns:
        ``(2,)`` for a scalar distance, else ``distance.shape + (2,)``.
    """
    w, b = _check_box(lane_width, box_half)
    p, d = _approach_point(leg_index(leg), _lane("lane", lane), w, b)
    dist = finite("distance", distance)
    return p - dist[..., None] * d


def departure_centerline(leg, lane, distance, lane_width: float = DEFAULT_LANE_WIDTH,
                         box_half: float = DEFAULT_BOX_HALF) -> np.ndarray:
    """Point(s) of departure ``lane`` of ``leg`` at ``distance`` metres past the box edge."""
    w, b = _check_box(lane_width, box_half)
    p, d = _departure_point(leg_index(leg), _lane("lane", lane), w, b)
    dist = finite("distance", distance)
    return p + dist[..., None] * d


def _line(p0: np.ndarray, p1: np.ndarray, n: int) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)[:, None]
    return p0 + t * (p1 - p0)


def lane_path(movement, approach_lane, lane_width: float = DEFAULT_LANE_WIDTH,
              box_half: float = DEFAULT_BOX_HALF, n_points: int = DEFAULT_N_POINTS,
              rule: str = "same") -> np.ndarray:
    """Centreline polyline of a movement inside the box (paper Sec. 4.2).

    From the approach lane's stop-line point to the departure lane's point on
    the exit box edge (lane chosen by :func:`departure_lane` with ``rule``).
    Straight movements are a straight segment.  A turn is the fillet of the
    two lane lines: with ``P`` their intersection, ``d1 = |P - start|`` and
    ``d2 = |end - P|``, the path is a straight piece ``d1 - r``, a circular arc
    of radius ``r = min(d1, d2)`` tangent to both lines, and a straight piece
    ``d2 - r``.  Under ``rule="same"`` ``d1 == d2`` and the turn is one exact
    quarter circle (right turns tight, radius ``box_half - (a + 1/2) w``; left
    turns wide, radius ``box_half + (a + 1/2) w``).

    Args:
        movement: id 0..11 or ``(leg, turn)``.
        approach_lane: 0..2 (whether the lane-use table allows it is not
            checked here).
        lane_width, box_half: geometry (metres).
        n_points: polyline points for a pure arc or line (>= 2); a composite
            turn gets up to two extra points.
        rule: departure lane rule (``DEPARTURE_RULES``).

    Returns:
        float64 ``(K, 2)`` polyline, first point on the stop line, last on the
        exit edge.
    """
    w, b = _check_box(lane_width, box_half)
    m = _movement(movement)
    a = _lane("approach_lane", approach_lane)
    if isinstance(n_points, (bool, np.bool_)):
        raise ValueError(f"n_points must be an integer >= 2, got {n_points!r}")
    try:
        n = operator.index(n_points)
    except TypeError:
        raise ValueError(f"n_points must be an integer >= 2, got {n_points!r}") from None
    if n < 2:
        raise ValueError(f"n_points must be an integer >= 2, got {n_points!r}")
    leg, turn = divmod(m, 3)
    j = departure_lane(m, a, rule)
    p0, d0 = _approach_point(leg, a, w, b)
    p1, d1v = _departure_point((leg + 1 + turn) % 4, j, w, b)
    if turn == 1:
        return _line(p0, p1, n)
    # corner P = p0 + t d0 with (P - p1) parallel to d1v: t = (p1 - p0) . d0 since d0 ⟂ d1v
    dist1 = float(np.dot(p1 - p0, d0))
    corner = p0 + dist1 * d0
    dist2 = float(np.dot(p1 - corner, d1v))
    r = min(dist1, dist2)
    a0 = p0 + (dist1 - r) * d0  # arc start
    a1 = corner + r * d1v  # arc end
    # centre lies r to the turning side of the incoming direction
    side = _right_of(d0) if turn == 2 else -_right_of(d0)
    c = a0 + r * side
    th0 = math.atan2(a0[1] - c[1], a0[0] - c[0])
    th1 = math.atan2(a1[1] - c[1], a1[0] - c[0])
    dth = (th1 - th0 + math.pi) % (2 * math.pi) - math.pi  # quarter turn, signed
    th = th0 + dth * np.linspace(0.0, 1.0, n)
    arc = c + r * np.stack([np.cos(th), np.sin(th)], axis=1)
    arc[0], arc[-1] = a0, a1
    pieces = []
    if dist1 - r > 1e-9:
        pieces.append(p0[None])
    pieces.append(arc)
    if dist2 - r > 1e-9:
        pieces.append(p1[None])
    return np.concatenate(pieces, axis=0)


def path_length(path) -> float:
    """Arc length of a polyline ``(K, 2)`` (sum of its segment lengths)."""
    p = finite("path", path, ndim=2)
    if p.shape[1] != 2 or p.shape[0] < 2:
        raise ValueError(f"path must have shape (K >= 2, 2), got {p.shape}")
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def path_headings(path) -> np.ndarray:
    """Heading (radians) of each segment of a polyline ``(K, 2)`` -> ``(K - 1,)``."""
    p = finite("path", path, ndim=2)
    if p.shape[1] != 2 or p.shape[0] < 2:
        raise ValueError(f"path must have shape (K >= 2, 2), got {p.shape}")
    d = np.diff(p, axis=0)
    return np.arctan2(d[:, 1], d[:, 0])
