"""The highway expert's two neighbour passes over several worlds in one call
(:func:`icv_envs.policies.formation_expert_many.compute_many`, issue
10 from stop 46).

The worlds' state arrays are concatenated, world ``b`` holding rows
``offs[b]:offs[b + 1]`` and lane-index entries ``ioffs[b]:ioffs[b + 1]``
(its index's own row numbers, local to the world). Each kernel calls the
one-world kernel on each world's slices, so every world gets exactly the
numbers of its own call (the same compiled code on the same values); the
other passes of ``FormationExpert.compute`` treat every vehicle on its own
and run on the concatenated arrays directly.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.policies._kernels.formation_expert import expert_control_rows
from icv_envs.policies._kernels.lane_changes import lane_change_starts

__all__ = ["expert_control_many", "lane_change_starts_many"]


@nb.njit(cache=True)
def lane_change_starts_many(offs, ioffs, i_offset, active, cx, cy, v, length, lane, desired, member, keys, i_rows,
                            i_lanes, i_x, *consts):
    """:func:`~icv_envs.policies._kernels.lane_change_starts` of every world
    (``consts``: its arguments after ``offset``, one road's, shared by the
    worlds; ``i_offset[b]`` world ``b``'s index ``offset``). Returns the
    starting rows (concatenated rows, ascending), their target lanes and
    curve lengths, and the ``blocked`` mask of all rows."""
    nw = offs.shape[0] - 1
    n = offs[nw]
    rows = np.empty(n, dtype=np.int64)
    lanes = np.empty(n, dtype=np.int64)
    lens = np.empty(n)
    blocked = np.zeros(n, dtype=np.bool_)
    m = 0
    for b in range(nw):
        o0, o1, j0, j1 = offs[b], offs[b + 1], ioffs[b], ioffs[b + 1]
        r, s_lane, s_len, bl = lane_change_starts(active[o0:o1], cx[o0:o1], cy[o0:o1], v[o0:o1], length[o0:o1],
                                                  lane[o0:o1], desired[o0:o1], member[o0:o1], keys[j0:j1],
                                                  i_rows[j0:j1], i_lanes[j0:j1], i_x[j0:j1], i_offset[b], *consts)
        for k in range(r.shape[0]):
            rows[m] = r[k] + o0
            lanes[m] = s_lane[k]
            lens[m] = s_len[k]
            m += 1
        blocked[o0:o1] = bl
    return rows[:m], lanes[:m], lens[:m], blocked


@nb.njit(cache=True)
def expert_control_many(offs, f_offs, m_offs, ioffs, i_offset, free_rows, free_pow, v, idm, m_rows, cx, x_ref, v_ref,
                        a_ref, feedback, keys, i_rows, i_lanes, i_x, length, lc_lane, lane, desired, member, exiting,
                        safety, phi, scales):
    """:func:`~icv_envs.policies._kernels.expert_control_rows` of every world:
    ``free_rows`` / ``m_rows`` (concatenated rows, ascending) and ``free_pow``
    cut at ``f_offs`` / ``m_offs`` per world; ``idm``, ``feedback``,
    ``safety``, ``scales``: the tuples of the expert's arguments of those
    names (one road's and one parameter set's, shared by the worlds).
    Returns the ``(n, 2)`` normalised actions of all rows."""
    nw = offs.shape[0] - 1
    out = np.empty((offs[nw], 2))
    for b in range(nw):
        o0, o1, j0, j1 = offs[b], offs[b + 1], ioffs[b], ioffs[b + 1]
        f0, f1, k0, k1 = f_offs[b], f_offs[b + 1], m_offs[b], m_offs[b + 1]
        out[o0:o1] = expert_control_rows(
            o1 - o0, free_rows[f0:f1] - o0, free_pow[f0:f1], v[o0:o1], *idm, m_rows[k0:k1] - o0, cx[o0:o1],
            x_ref[o0:o1], v_ref[o0:o1], a_ref[o0:o1], *feedback, keys[j0:j1], i_rows[j0:j1], i_lanes[j0:j1],
            i_x[j0:j1], i_offset[b], cx[o0:o1], v[o0:o1], length[o0:o1], lc_lane[o0:o1], lane[o0:o1],
            desired[o0:o1], member[o0:o1], exiting[o0:o1], *safety, phi[o0:o1], *scales)
    return out
