"""The intersection's vehicle regrouping, compiled loops (paper Sec. 5,
:class:`icv_envs.policies.regrouping.Regrouping`): which lane changes are
ready to start (:func:`lane_change_ready`). Rules:
:mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["lane_change_ready"]


@nb.njit(cache=True)
def lane_change_ready(klane, tlane, lc_lane, phase, stage, st_lc, vid, yielding_vids, ref_rows, u, xg, dist, speed,
                      R1, slot_tolerance, want):
    """The first part of
    :meth:`icv_envs.policies.regrouping.Regrouping._start_lane_changes`:
    ``want`` cleared (-1) in place; the vehicles that need a lane change
    (not in their target lane, none under way, approaching, at least at
    stage ``st_lc``), in row order; of those in division (stage ``st_lc``),
    ready only within ``slot_tolerance`` of their slot (``u`` minus their
    reference's ``u - xg``, 0 without a reference: ``ref_rows`` -1), or any
    distance behind it while yielding (their id in ``yielding_vids``); the
    ready ones inside ``R1`` or slower than 2 m/s and not yielding signal
    the next lane towards their target (``want``, in place). Returns the
    ready rows and their next lanes."""
    n = klane.shape[0]
    for i in range(n):
        want[i] = -1
    m = 0
    for i in range(n):
        if klane[i] != tlane[i] and lc_lane[i] < 0 and phase[i] == 0 and stage[i] >= st_lc:
            m += 1
    rows = np.empty(m, dtype=np.int64)
    nxt = np.empty(m, dtype=np.int64)
    q = 0
    for i in range(n):
        if not (klane[i] != tlane[i] and lc_lane[i] < 0 and phase[i] == 0 and stage[i] >= st_lc):
            continue
        yielding = False
        for v in yielding_vids:
            if v == vid[i]:
                yielding = True
                break
        ready = True
        if stage[i] == st_lc:
            r = ref_rows[i]
            err = u[i] - (u[r] - xg[i]) if r >= 0 else 0.0
            ready = abs(err) < slot_tolerance or (yielding and err < slot_tolerance)
        d = tlane[i] - klane[i]
        nx = klane[i] + (1 if d > 0 else (-1 if d < 0 else 0))
        if ready and (dist[i] <= R1 or speed[i] < 2.0) and not yielding:
            want[i] = nx
        if ready:
            rows[q] = i
            nxt[q] = nx
            q += 1
    return rows[:q], nxt[:q]
