"""The observations' inner loops, compiled: the neighbour search along
the road and the ``Kinematics`` rows (the rules every kernel here
follows: :mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.sim._kernels.physics import npy_mod

__all__ = ["nearest_along_road", "kinematics_rows"]


@nb.njit(cache=True)
def nearest_along_road(cx, rows, K, pd, periodic, length):
    """The observation's neighbour search
    (:meth:`icv_envs.envs.highway_formation.HighwayFormationEnv._neighbours`)
    compiled: for each query row, the ``K`` vehicles nearest by
    longitudinal distance among the ``K`` before and ``K`` after it in the
    x order (stable), within ``pd`` (round a ring of ``length`` each vehicle
    at most once), nearest first, ties by candidate order (rear first).
    Returns ``(sel, present)`` of shape ``(len(rows), K)``; absent slots
    hold a candidate row and ``present`` False."""
    n = cx.shape[0]
    m = rows.shape[0]
    order = np.argsort(cx, kind="mergesort")
    rank = np.empty(n, dtype=np.int64)
    for q in range(n):
        rank[order[q]] = q
    C = 2 * K
    offs = np.empty(C, dtype=np.int64)
    for q in range(K):
        offs[q] = q - K
        offs[K + q] = q + 1
    sel = np.empty((m, K), dtype=np.int64)
    present = np.empty((m, K), dtype=np.bool_)
    cand = np.empty(C, dtype=np.int64)
    dist = np.empty(C)
    half = 0.5 * length
    lim_lo = (n - 1) // 2
    lim_hi = (n - 1) // 2 + (n - 1) % 2
    for r in range(m):
        row = rows[r]
        x0 = cx[row]
        for c in range(C):
            o = offs[c]
            cr = rank[row] + o
            if periodic:
                valid = abs(o) <= (lim_hi if o > 0 else lim_lo)
                cr = cr % n
            else:
                valid = cr >= 0 and cr < n
            cand[c] = order[min(max(cr, 0), n - 1)]
            d = cx[cand[c]] - x0
            if periodic:
                d = npy_mod(d + half, length) - half
            d = abs(d)
            dist[c] = d if (valid and d < pd) else np.inf
        pick = np.argsort(dist, kind="mergesort")
        for q in range(K):
            sel[r, q] = cand[pick[q]]
            present[r, q] = np.isfinite(dist[pick[q]])
    return sel, present


@nb.njit(cache=True)
def kinematics_rows(F, rows, sel, present, idx, V, s_abs, s_rel, absolute, normalize, clip, period):
    """The ``Kinematics`` observation
    (:meth:`icv_envs.envs.observations.Kinematics.observe_rows`) compiled:
    row 0 the observer's own features (``F[rows]``), rows ``1..K`` its
    neighbours ``sel`` (zeros where not ``present``); unless ``absolute``,
    a neighbour's x, y, vx, vy (columns 1-4) relative to the observer's,
    its dx folded round a ring of length ``period`` (``period <= 0``: no
    ring); with ``normalize`` divided by ``s_abs`` (own row, absolute) or
    ``s_rel``, with ``clip`` clipped to [-1, 1]; the columns ``idx``, as
    float32 in a ``(len(rows), V, len(idx))`` array (slots past ``K``
    zeros). The same float64 operations as the array code, then one
    rounding to float32."""
    m = rows.shape[0]
    J = idx.shape[0]
    K = sel.shape[1]
    out = np.zeros((m, V, J), dtype=np.float32)
    half = 0.5 * period
    for r in range(m):
        o = rows[r]
        for j in range(J):
            val = F[o, idx[j]]
            if normalize:
                val = val / s_abs[idx[j]]
                if clip:
                    val = min(max(val, -1.0), 1.0)
            out[r, 0, j] = val
        for q in range(K):
            if not present[r, q]:
                continue
            c = sel[r, q]
            for j in range(J):
                f = idx[j]
                val = F[c, f]
                if not absolute:
                    if f >= 1 and f <= 4:
                        val = val - F[o, f]
                    if f == 1 and period > 0.0:
                        val = npy_mod(val + half, period) - half
                if normalize:
                    val = val / (s_abs[f] if absolute else s_rel[f])
                    if clip:
                        val = min(max(val, -1.0), 1.0)
                out[r, 1 + q, j] = val
    return out
