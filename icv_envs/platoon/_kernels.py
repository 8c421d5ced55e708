"""Compiled inner loops of the virtual platoon's algorithms (numba,
``@njit(cache=True)``; the rules of :mod:`icv_envs.sim._kernels`: plain arrays
in and out, the same operations as the code they replace)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["atan2_rows", "depths_of"]


@nb.njit(cache=True)
def atan2_rows(y, x):
    """NumPy's ``arctan2(y, x)`` of two float arrays of one length, libm's
    ``atan2`` (from stop 50, for the FCFS reservation's path headings:
    NumPy's at ``X86_V3``, the level the reference fingerprints are pinned
    at; NumPy's AVX-512 ``arctan2`` rounds some values differently, the rule
    of :mod:`icv_envs.sim._kernels`)."""
    out = np.empty(y.shape[0])
    for i in range(y.shape[0]):
        out[i] = math.atan2(y[i], x[i])
    return out


@nb.njit(cache=True)
def depths_of(conflict):
    """:func:`icv_envs.platoon.tree.tree_depths` of a checked ``(m, m)`` bool
    matrix: ``depths[0] = 0``, ``depths[k] = 1 + max{depths[i] : 1 <= i < k,
    conflict[i - 1, k - 1]}`` (1 if none)."""
    m = conflict.shape[0]
    depths = np.zeros(m + 1, dtype=np.int64)
    depths[1:] = 1
    for j in range(1, m):
        best = -1
        for i in range(j):
            if conflict[i, j] and depths[i + 1] > best:
                best = depths[i + 1]
        if best >= 0:
            depths[j + 1] = max(1, 1 + best)
    return depths
