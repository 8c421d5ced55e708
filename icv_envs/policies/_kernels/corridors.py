"""The intersection's corridor index (the conflict geometry the
regrouping, paper Sec. 5, and the virtual platoon, Sec. 4.2, read):
:func:`corridor_index` builds the sorted entries of
:class:`icv_envs.policies.platoon_common.Corridors`, which the experts
rebuild two or three times per step from about eighty small array
operations (about 140 us at 65 vehicles, most of it numpy's per-call
overhead); :func:`corridor_neighbours` answers its queries. The
trigonometry of the footprint's reach stays in numpy (numba's ``sin`` and
numpy's SIMD ``sin`` may round differently). Rules:
:mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["corridor_add_signals", "corridor_index", "corridor_neighbours"]


@nb.njit(cache=True)
def corridor_index(phase, lane, lat_leg, sin_dh, cos_dh, length, width, w, leg, s, signal_lane, pid, plane, L,
                   diverge, exit_leg, exit_of, mv, dlane, big):
    """Entries ``(rows, corr, coord, keys, signal_only, lead)`` of the corridor index, sorted by key then
    row. Per vehicle first, as the numpy code computed them: on the approach (``phase`` 0) the
    footprint's lateral reach ``w/2 + (length |sin dh| + width |cos dh|) / 2`` (``dh`` the heading
    relative to the approach direction; its sine and cosine from numpy), in the box (``phase`` 1)
    over its first ``diverge`` metres (``early``), departed (``phase`` 2) or within ``diverge`` of
    the box's exit edge (``dep``, corridor ``12 + 3 exit + dlane[pid]``, the exit its own leg or
    its movement's). Candidate entries in the order of the numpy code: the approach lanes
    ``lane - 1, lane, lane + 1`` the footprint reaches into (``|lat_leg - (ln + 0.5) w| < reach``),
    the signal lane, the path of an in-box vehicle, its approach lane over its first metres
    (``early``, lane ``max(plane, 0)``), the departure lane (``dep``); of two entries of one
    vehicle in one corridor the first is kept (a vehicle whose body covers its signal lane is
    listed there physically)."""
    n = phase.shape[0]
    appr = np.empty(n, dtype=np.bool_)
    box = np.empty(n, dtype=np.bool_)
    early = np.empty(n, dtype=np.bool_)
    dep = np.empty(n, dtype=np.bool_)
    reach = np.empty(n)
    dep_corr = np.zeros(n, dtype=np.int64)
    for i in range(n):
        appr[i] = phase[i] == 0
        box[i] = phase[i] == 1
        reach[i] = 0.5 * w + 0.5 * (length[i] * abs(sin_dh[i]) + width[i] * abs(cos_dh[i]))
        early[i] = box[i] and s[i] < diverge
        dep[i] = phase[i] == 2 or (box[i] and s[i] > L[i] - diverge)
        if dep[i]:
            ex = exit_leg[i] if exit_leg[i] >= 0 else exit_of[mv[i]]
            dep_corr[i] = 12 + 3 * ex + dlane[pid[i]]
    cap = 7 * n + 1
    rows = np.empty(cap, dtype=np.int64)
    corr = np.empty(cap, dtype=np.int64)
    coord = np.empty(cap, dtype=np.float64)
    sig = np.zeros(cap, dtype=np.bool_)
    m = 0
    for dl in (-1, 0, 1):
        for i in range(n):
            ln = lane[i] + dl
            if appr[i] and ln >= 0 and ln < 3 and abs(lat_leg[i] - (ln + 0.5) * w) < reach[i]:
                rows[m] = i
                corr[m] = 3 * leg[i] + ln
                coord[m] = s[i]
                m += 1
    for i in range(n):
        if appr[i] and signal_lane[i] >= 0:
            rows[m] = i
            corr[m] = 3 * leg[i] + signal_lane[i]
            coord[m] = s[i]
            sig[m] = True
            m += 1
    for i in range(n):
        if box[i]:
            rows[m] = i
            corr[m] = 24 + pid[i]
            coord[m] = s[i]
            m += 1
    for i in range(n):
        if early[i]:
            rows[m] = i
            corr[m] = 3 * leg[i] + max(plane[i], 0)
            coord[m] = s[i]
            m += 1
    for i in range(n):
        if dep[i]:
            rows[m] = i
            corr[m] = dep_corr[i]
            coord[m] = s[i] - L[i]
            m += 1
    # first occurrence of each (row, corridor)
    keep = np.ones(m, dtype=np.bool_)
    for a in range(m):
        if sig[a]:
            for b in range(a):
                if keep[b] and rows[b] == rows[a] and corr[b] == corr[a]:
                    keep[a] = False
                    break
    idx = np.flatnonzero(keep)
    rows, corr, coord, sig = rows[idx], corr[idx], coord[idx], sig[idx]
    keys = corr * big + coord
    # sort by key, ties by row (np.lexsort((rows, keys)))
    o = np.argsort(rows, kind="mergesort")
    o = o[np.argsort(keys[o], kind="mergesort")]
    rows, corr, coord, keys, sig = rows[o], corr[o], coord[o], keys[o], sig[o]
    k = rows.shape[0]
    lead = np.full(k, -1, dtype=np.int64)
    for a in range(k - 1):
        if corr[a + 1] == corr[a]:
            lead[a] = a + 1
    return rows, corr, coord, keys, sig, lead


@nb.njit(cache=True)
def corridor_neighbours(keys, corr, rows, coord, q_rows, q_corr, qk):
    """Per query: the nearest entry of another vehicle ahead (key > ``qk``) and behind (<=) in
    corridor ``q_corr``, looking at most 4 entries each way (a vehicle is listed at most once per
    corridor, so its own entry is the only one skipped). ``(lead_row, lead_coord, foll_row,
    foll_coord)``, -1 / +-inf when none."""
    k = q_rows.shape[0]
    m = keys.shape[0]
    lr = np.full(k, -1, dtype=np.int64)
    lc = np.full(k, np.inf)
    fr = np.full(k, -1, dtype=np.int64)
    fc = np.full(k, -np.inf)
    if m == 0:
        return lr, lc, fr, fc
    pos = np.searchsorted(keys, qk, side="right")
    for i in range(k):
        for j in range(4):
            p = pos[i] + j
            if p >= m or corr[p] != q_corr[i]:
                break
            if rows[p] != q_rows[i]:
                lr[i] = rows[p]
                lc[i] = coord[p]
                break
        for j in range(1, 5):
            p = pos[i] - j
            if p < 0 or corr[p] != q_corr[i]:
                break
            if rows[p] != q_rows[i]:
                fr[i] = rows[p]
                fc[i] = coord[p]
                break
    return lr, lc, fr, fc


@nb.njit(cache=True)
def corridor_add_signals(rows, corr, coord, keys, phase, leg, s, signal_lane, big):
    """The entries of :func:`corridor_index` with turn signals, from those of
    the index without (``signal_lane`` all -1, the same state): every
    approaching vehicle (``phase`` 0) with ``signal_lane >= 0`` is listed in
    approach corridor ``3 leg + signal_lane`` at ``s`` (``signal_only``)
    unless it is listed there physically already; the entries stay sorted by
    key then row and each entry's leader is the next one in its corridor.
    The same entries, order and leaders as :func:`corridor_index` with the
    signals: a signal can only repeat one of the vehicle's physical approach
    entries (an approaching vehicle has no other), and the order by (key,
    row) is total. Returns ``(rows, corr, coord, keys, signal_only, lead)``."""
    n = phase.shape[0]
    m = rows.shape[0]
    add = np.zeros(n, dtype=np.bool_)
    k = 0
    for i in range(n):
        if phase[i] == 0 and signal_lane[i] >= 0:
            c = 3 * leg[i] + signal_lane[i]
            listed = False
            for a in range(m):
                if rows[a] == i and corr[a] == c:
                    listed = True
                    break
            if not listed:
                add[i] = True
                k += 1
    o_rows = np.empty(m + k, dtype=np.int64)
    o_corr = np.empty(m + k, dtype=np.int64)
    o_coord = np.empty(m + k)
    o_keys = np.empty(m + k)
    o_sig = np.zeros(m + k, dtype=np.bool_)
    # the new entries sorted by (key, row), then merged into the sorted old ones
    nr = np.empty(k, dtype=np.int64)
    nc = np.empty(k, dtype=np.int64)
    nk = np.empty(k)
    q = 0
    for i in range(n):
        if add[i]:
            nr[q] = i
            nc[q] = 3 * leg[i] + signal_lane[i]
            nk[q] = nc[q] * big + s[i]
            q += 1
    o = np.argsort(nk, kind="mergesort")  # (rows ascending already: ties by row)
    a = 0
    b = 0
    for p in range(m + k):
        take_new = False
        if b < k:
            j = o[b]
            if a >= m or nk[j] < keys[a] or (nk[j] == keys[a] and nr[j] < rows[a]):
                take_new = True
        if take_new:
            j = o[b]
            o_rows[p] = nr[j]
            o_corr[p] = nc[j]
            o_coord[p] = s[nr[j]]
            o_keys[p] = nk[j]
            o_sig[p] = True
            b += 1
        else:
            o_rows[p] = rows[a]
            o_corr[p] = corr[a]
            o_coord[p] = coord[a]
            o_keys[p] = keys[a]
            a += 1
    lead = np.full(m + k, -1, dtype=np.int64)
    for p in range(m + k - 1):
        if o_corr[p + 1] == o_corr[p]:
            lead[p] = p + 1
    return o_rows, o_corr, o_coord, o_keys, o_sig, lead
