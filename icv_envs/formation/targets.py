"""Target positions of the one-dimensional multi-lane formation.

Paper Sec. 3.1-3.2 (Xu et al., IET ITS 2021): the formation is a list of
targets ``(x_g, y_g)`` in the *formation frame*: ``x_g`` is the distance in
metres BEHIND the most forward target (so ``x_g >= 0``) and ``y_g`` is the lane
id, 1 = leftmost lane .. ``N_l`` = rightmost lane.

Targets are grouped into layers (at most one target per lane); every layer is
split into two sublayers whose lanes are never adjacent; adjacent sublayers
are ``L_s`` apart.  The printed equation (xy) of the paper is wrong (it yields
lanes 0 and -1 for ``N_l = 5``); :func:`interlaced_targets` implements the
corrected form from docs/formation.md#target-equation.

All functions are pure numpy, vectorised over the vehicle index.
"""

from __future__ import annotations

import math
import numbers
import operator

import numpy as np

__all__ = [
    "GEOMETRIES",
    "interlaced_targets",
    "parallel_targets",
    "formation_targets",
    "formation_length",
]

#: Formation geometries understood by :func:`formation_targets` (paper Fig. 1).
GEOMETRIES: tuple[str, ...] = ("interlaced", "parallel")


# ----------------------------------------------------------------------------
# validation helpers
# ----------------------------------------------------------------------------
def _check_int(name: str, value, minimum: int) -> int:
    """Return ``value`` as a Python int >= ``minimum`` or raise ValueError."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r} (a bool)")
    try:
        ivalue = operator.index(value)
    except TypeError:
        raise ValueError(
            f"{name} must be an integer >= {minimum}, got {value!r} "
            f"(type {type(value).__name__})"
        ) from None
    if ivalue < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(ivalue)


def _check_spacing(spacing) -> float:
    """Return ``spacing`` as a finite float > 0 or raise ValueError."""
    if isinstance(spacing, (bool, np.bool_)) or not isinstance(spacing, numbers.Real):
        raise ValueError(
            f"spacing must be a finite real number > 0 (metres), got {spacing!r}"
        )
    s = float(spacing)
    if not math.isfinite(s) or s <= 0.0:
        raise ValueError(
            f"spacing must be a finite real number > 0 (metres), got {spacing!r}"
        )
    return s


def _check_common(n_vehicles, n_lanes, spacing) -> tuple[int, int, float]:
    return (
        _check_int("n_vehicles", n_vehicles, 0),
        _check_int("n_lanes", n_lanes, 1),
        _check_spacing(spacing),
    )


def _check_geometry(geometry) -> str:
    if not isinstance(geometry, str) or geometry not in GEOMETRIES:
        raise ValueError(
            f"unknown formation geometry {geometry!r}; allowed: {', '.join(GEOMETRIES)}"
        )
    return geometry


# ----------------------------------------------------------------------------
# geometries
# ----------------------------------------------------------------------------
def interlaced_targets(
    n_vehicles: int, n_lanes: int, spacing: float = 20.0
) -> tuple[np.ndarray, np.ndarray]:
    """Targets of the interlaced formation (paper Fig. 1a, Fig. 2).

    Paper Sec. 3.2, eq. (xy), corrected per docs/formation.md#target-equation.  For target
    ``i = 1..N`` on ``N_l`` lanes with sublayer gap ``L_s``::

        k = mod(i - 1, N_l) + 1          # position inside its layer
        m = ceil(i / N_l)                # layer number
        c = ceil(N_l / 2)                # size of the first sublayer
        x_gi = (P2(m) + com(k, c)) * L_s # metres behind the front target
        y_gi = P1(k) - com(k, c) * P1(c) # lane id, 1 = leftmost
        P1(p) = 2p - 1,  P2(p) = 2p - 2,  com(p, q) = 1 if p > q else 0

    The first sublayer of a layer takes the odd lanes 1, 3, 5, ..., the second
    the even lanes 2, 4, ...  For ``N_l = 5`` and ``i = 1..10`` this gives
    ``(x/L_s, lane)`` = (0,1) (0,3) (0,5) (1,2) (1,4) (2,1) (2,3) (2,5) (3,2)
    (3,4), which reproduces the captions of the paper's Fig. 2 (4, 7 and 9
    vehicles on 5 lanes).

    Decision for ``N_l = 1`` (the paper is silent): the formula only fills the
    first sublayer of each layer, leaving every other sublayer empty, i.e. a
    single-lane platoon with gap ``2 L_s``.  We compress it to an ordinary
    single-lane platoon with gap ``L_s``: ``x_gi = (i - 1) L_s``, lane 1.  This
    keeps the invariant "adjacent occupied sublayers are ``L_s`` apart".

    Targets are ordered front to back (``x`` nondecreasing in ``i``) and the
    targets for ``N`` vehicles are the first ``N`` targets for any larger
    number (prefix property), so a joining vehicle never moves the others.

    Args:
        n_vehicles: number of targets ``N >= 0`` (0 gives empty arrays).
        n_lanes: number of lanes ``N_l >= 1``.
        spacing: sublayer gap ``L_s`` in metres, finite and > 0
            (20 m on the highway, Table 1).

    Returns:
        ``(x_behind, lane)``: float64 array (N,) of metres behind the front
        target (>= 0) and int64 array (N,) of lane ids in ``1..N_l``.

    Raises:
        ValueError: ``n_vehicles`` not an integer >= 0, ``n_lanes`` not an
            integer >= 1, or ``spacing`` not finite and > 0.
    """
    n, n_l, l_s = _check_common(n_vehicles, n_lanes, spacing)
    i = np.arange(1, n + 1, dtype=np.int64)
    if n_l == 1:
        return (i - 1).astype(np.float64) * l_s, np.ones(n, dtype=np.int64)
    k = (i - 1) % n_l + 1
    m = (i - 1) // n_l + 1  # == ceil(i / N_l) in exact integer arithmetic
    c = (n_l + 1) // 2  # == ceil(N_l / 2)
    com = (k > c).astype(np.int64)
    x = (2 * m - 2 + com).astype(np.float64) * l_s
    lane = (2 * k - 1) - com * (2 * c - 1)
    return x, lane.astype(np.int64)


def parallel_targets(
    n_vehicles: int, n_lanes: int, spacing: float = 20.0
) -> tuple[np.ndarray, np.ndarray]:
    """Targets of the parallel formation (paper Sec. 3.1, Fig. 1b).

    Vehicles in one layer drive side by side: layer ``m = ceil(i / N_l)`` sits
    at ``x_gi = (m - 1) L_s`` behind the front and target ``i`` takes lane
    ``k = mod(i - 1, N_l) + 1`` (layers fill from the left).  The paper gives
    no equation for this geometry; this is the direct reading of Fig. 1b with
    layers ``L_s`` apart.  Same ordering and prefix property as
    :func:`interlaced_targets`.

    Args:
        n_vehicles: number of targets ``N >= 0``.
        n_lanes: number of lanes ``N_l >= 1``.
        spacing: layer gap ``L_s`` in metres, finite and > 0.

    Returns:
        ``(x_behind, lane)``: float64 (N,) metres behind the front target and
        int64 (N,) lane ids ``1..N_l``.

    Raises:
        ValueError: on bad ``n_vehicles``, ``n_lanes`` or ``spacing``.
    """
    n, n_l, l_s = _check_common(n_vehicles, n_lanes, spacing)
    i = np.arange(1, n + 1, dtype=np.int64)
    x = ((i - 1) // n_l).astype(np.float64) * l_s
    lane = (i - 1) % n_l + 1
    return x, lane.astype(np.int64)


def formation_targets(
    n_vehicles: int,
    n_lanes: int,
    spacing: float = 20.0,
    geometry: str = "interlaced",
) -> tuple[np.ndarray, np.ndarray]:
    """Targets of a formation of the given geometry (paper Sec. 3.1-3.2).

    Dispatches to :func:`interlaced_targets` (``geometry="interlaced"``, the
    paper's choice) or :func:`parallel_targets` (``geometry="parallel"``).

    Raises:
        ValueError: unknown ``geometry`` (allowed: ``GEOMETRIES``) or bad
            ``n_vehicles`` / ``n_lanes`` / ``spacing``.
    """
    geometry = _check_geometry(geometry)
    if geometry == "interlaced":
        return interlaced_targets(n_vehicles, n_lanes, spacing)
    return parallel_targets(n_vehicles, n_lanes, spacing)


def formation_length(
    n_vehicles: int,
    n_lanes: int,
    spacing: float = 20.0,
    geometry: str = "interlaced",
) -> float:
    """Longitudinal length of a formation: the largest ``x_behind``.

    Front target to rearmost target in metres (paper Sec. 3.2; used as the
    "length of formation" in the virtual-platoon references of Sec. 4).
    ``0.0`` for ``n_vehicles <= 1``.  O(1): since ``x`` is nondecreasing in the
    target index, the length is ``x`` of the last target.

    Raises:
        ValueError: as :func:`formation_targets`.
    """
    geometry = _check_geometry(geometry)
    n, n_l, l_s = _check_common(n_vehicles, n_lanes, spacing)
    if n <= 1:
        return 0.0
    if geometry == "parallel" or n_l == 1:
        # parallel: layer of the last target; interlaced N_l = 1: (N-1) L_s.
        steps = (n - 1) // n_l if geometry == "parallel" else n - 1
        return float(steps * l_s)
    k = (n - 1) % n_l + 1
    m = (n - 1) // n_l + 1
    c = (n_l + 1) // 2
    return float((2 * m - 2 + (1 if k > c else 0)) * l_s)
