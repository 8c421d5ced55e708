"""The intersection's vehicle regrouping, compiled loops (paper Sec. 5,
:class:`icv_envs.policies.regrouping.Regrouping`): which lane changes are
ready to start (:func:`lane_change_ready`), the approach zone's fronts
(:func:`approach_fronts`), the sub-formations' lane-change state
(:func:`lane_change_state`), the lane changes that end
(:func:`lane_change_progress`), the sub-formations' distance bounds
(:func:`segment_bounds`). Rules:
:mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.sim._kernels.physics import npy_maximum, npy_minimum

__all__ = ["approach_fronts", "lane_change_progress", "lane_change_ready", "lane_change_state", "segment_bounds"]


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
    rows = np.empty(n, dtype=np.int64)
    nxt = np.empty(n, dtype=np.int64)
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


@nb.njit(cache=True)
def approach_fronts(rows, sizes, u, dist, R2, vid, fslot, ref, xg):
    """The approach zone of
    :meth:`icv_envs.policies.regrouping.Regrouping._approach_and_division`
    for the formations not yet divided (members in ``rows``, formation
    ``k`` the next ``sizes[k] >= 1`` of them): its front (the member of
    largest ``u``, the first on a tie, as ``argmax``); a formation whose
    front is within ``R2`` of the centre is to be divided (returned mask);
    the others' members track the front with their spawn slots (``ref``,
    ``xg`` in place: the front's id and ``fslot - fslot[front]``; the front
    none and 0)."""
    K = sizes.shape[0]
    divide = np.zeros(K, dtype=np.bool_)
    q0 = 0
    for k in range(K):
        m = sizes[k]
        if m < 1:
            raise ValueError("approach_fronts: a formation without members")
        b = q0
        for q in range(q0 + 1, q0 + m):
            if u[rows[q]] > u[rows[b]]:
                b = q
        front = rows[b]
        if dist[front] <= R2:
            divide[k] = True
        else:
            for q in range(q0, q0 + m):
                ref[rows[q]] = vid[front]
            for q in range(q0, q0 + m):
                xg[rows[q]] = fslot[rows[q]] - fslot[front]
            ref[front] = -1
            xg[front] = 0.0
        q0 += m
    return divide


@nb.njit(cache=True)
def lane_change_state(rows, sizes, klane, tlane, lc_lane):
    """Per sub-formation in its lane-change state (members in ``rows``,
    sub-formation ``k`` the next ``sizes[k]``;
    :meth:`icv_envs.policies.regrouping.Regrouping._adjusting`): how many
    members still wait to start a lane change (not in their target lane,
    none under way), and whether every member is in its target lane with
    none under way. Returns ``(pending, settled)``."""
    K = sizes.shape[0]
    pending = np.zeros(K, dtype=np.int64)
    settled = np.ones(K, dtype=np.bool_)
    q0 = 0
    for k in range(K):
        for q in range(q0, q0 + sizes[k]):
            r = rows[q]
            if lc_lane[r] < 0 and klane[r] != tlane[r]:
                pending[k] += 1
            if not (klane[r] == tlane[r] and lc_lane[r] < 0):
                settled[k] = False
        q0 += sizes[k]
    return pending, settled


@nb.njit(cache=True)
def lane_change_progress(act, lat_plan, lat_leg, u, phase, lane, lc_u0, lc_len, lc_lat1, replan_tolerance, klane,
                         lc_lane):
    """The end of :meth:`icv_envs.policies.regrouping.Regrouping._lane_change_progress`,
    in place: of the vehicles ``act`` changing lanes (``lat_plan`` their
    planned lateral position), one past the curve's end and within 0.4 m of
    the target lane's centre, or already in the box, has finished (its kept
    lane is the target lane); one further than ``replan_tolerance`` from
    the plan (and not finished) gives up (its kept lane is the lane it is
    in); both end the change (``lc_lane = -1``)."""
    for j in range(act.shape[0]):
        i = act[j]
        entered = phase[i] > 0
        done = u[i] >= lc_u0[i] + lc_len[i] and abs(lat_leg[i] - lc_lat1[i]) < 0.4
        if done or entered:
            klane[i] = lc_lane[i]
            lc_lane[i] = -1
        elif abs(lat_plan[j] - lat_leg[i]) > replan_tolerance:
            klane[i] = lane[i]
            lc_lane[i] = -1


@nb.njit(cache=True)
def segment_bounds(rows, sizes, dist):
    """Per group (members in ``rows``, group ``k`` the next ``sizes[k] >=
    1``) the least and the largest ``dist`` of its members, as
    ``numpy.minimum.reduceat`` and ``maximum.reduceat`` give them (a NaN
    kept): :meth:`icv_envs.policies.regrouping.Regrouping._sub_distances`.
    Returns a ``(2, K)`` array: rows least, largest."""
    K = sizes.shape[0]
    out = np.empty((2, K))
    q0 = 0
    for k in range(K):
        lo = dist[rows[q0]]
        hi = lo
        for q in range(q0 + 1, q0 + sizes[k]):
            d = dist[rows[q]]
            lo = npy_minimum(lo, d)
            hi = npy_maximum(hi, d)
        out[0, k] = lo
        out[1, k] = hi
        q0 += sizes[k]
    return out
