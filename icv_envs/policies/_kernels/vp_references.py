"""The improved virtual platoon's compiled loops, the references its
vehicles track (paper Sec. 4.2,
:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`):
formation following (:func:`follow_references`), the tree's references
(:func:`tree_references`), the adjusting zone's anticipation
(:func:`anticipated_references`), the virtual lane's Gipps caps
(:func:`virtual_caps`) and the stop flags (:func:`stop_flags`), all in
one call with the advisory inside ``R1`` (:func:`vp_references`), and
the references as the observation reports them
(:func:`observation_references`). The
nodes and their order: :mod:`icv_envs.policies._kernels.virtual_platoon`.
Rules: :mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.policies._kernels.virtual_platoon import _layers_before
from icv_envs.sim._kernels.physics import npy_maximum

__all__ = ["anticipated_references", "follow_references", "observation_references", "stop_flags", "tree_references",
           "virtual_caps", "vp_references"]


@nb.njit(cache=True)
def virtual_caps(n, rows_all, kk, U, X, rear, rear_row, speed, D_safe, b, tau, bt2):
    """The virtual lane's safe-speed caps
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`, the virtual lane's cap):
    for member ``rows_all[j]`` of node ``kk[j]``, Gipps' safe speed behind
    the rear vehicle of every earlier node ``i`` it conflicts with
    (``U[i, kk[j]]``), the smallest, as an acceleration cap ``(v_safe - v) /
    tau``; ``inf`` for every other vehicle (and for members without such a
    node); ``bt2 = (b tau)^2`` as the caller's Python computes it. The array
    code's operations in its order (``sqrt`` is exactly rounded everywhere;
    its ``maximum(G, 0)`` returns 0 on a tie)."""
    cap = np.full(n, np.inf)
    K = rear.shape[0]
    for j in range(rows_all.shape[0]):
        r = rows_all[j]
        k = kk[j]
        best = np.inf
        for i in range(K):
            if U[i, k]:
                G = X[r] - rear[i] - D_safe
                vr = speed[rear_row[i]]
                vs = -b * tau + math.sqrt(bt2 + vr * vr + 2.0 * b * (G if G > 0.0 else 0.0))
                if vs < best:
                    best = vs
        cap[r] = (best - speed[r]) / tau
    return cap


@nb.njit(cache=True)
def anticipated_references(cand, mv, leg, dist, X, speed, conflict, leg_of, mvs, rear_row, rear, depths, lens, x0,
                           D_t, den):
    """The references the adjusting zone's free vehicles ``cand`` would get
    if their nodes were made now
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`, the anticipation):
    per candidate, the current nodes it conflicts with, up to the first
    node of its own leg with a vehicle behind it; its depth ``1 +`` their
    largest depth (0 without one); the layer reference ``x0 + depth D_t +``
    the longest node of every layer before it; the bound ``D_t`` behind the
    rear of those nodes (``-inf`` without one) and the first node attaining
    it; their maximum ``R``; the braking room ``v^2 / den``; the hold ``R -
    X``. Returns ``(ref, lb, pred, R, room, H)``. The array code's
    operations in its order (the layers' longest node and their running sum
    as ``maximum.at`` and ``cumsum`` take them; ``argmax``'s first index)."""
    nc = cand.shape[0]
    K = mvs.shape[0]
    C = np.zeros((nc, K), dtype=np.bool_)
    dnew = np.empty(nc, dtype=np.int64)
    top = 0
    for k in range(K):
        if depths[k] > top:
            top = depths[k]
    for j in range(nc):
        c = cand[j]
        first_behind = K
        for k in range(K):
            if leg_of[mvs[k]] == leg[c] and dist[rear_row[k]] >= dist[c]:
                first_behind = k
                break
        m = 0
        for k in range(K):
            ck = conflict[mv[c], mvs[k]] and k < first_behind
            C[j, k] = ck
            if ck and depths[k] > m:
                m = depths[k]
        dnew[j] = 1 + m
        if dnew[j] > top:
            top = dnew[j]
    before = _layers_before(depths, 0, lens, top)
    ref = np.empty(nc)
    lb = np.empty(nc)
    pred = np.zeros(nc, dtype=np.int64)
    R = np.empty(nc)
    room = np.empty(nc)
    H = np.empty(nc)
    for j in range(nc):
        c = cand[j]
        ref[j] = x0 + dnew[j] * D_t + before[dnew[j]]
        best = -np.inf
        arg = 0
        for k in range(K):
            v = rear[k] + D_t if C[j, k] else -np.inf
            if v > best:
                best = v
                arg = k
        lb[j] = best
        pred[j] = arg
        R[j] = ref[j] if ref[j] > lb[j] else lb[j]
        room[j] = speed[c] * speed[c] / den
        H[j] = R[j] - X[c]
    return ref, lb, pred, R, room, H


@nb.njit(cache=True)
def follow_references(k, rr, ref, vid, dist, klane, sig, phase, u, xg, speed, mode_follow, mode, xref, vref):
    """Formation following of
    :meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`,
    in place: followers ``k`` of the vehicles at rows ``rr`` (-1: gone).
    Two vehicles referring to each other (a safety net) lose the nearer
    one's reference (``ref = -1``; the test reads the references as they
    were before any is cleared); a follower ahead of its reference vehicle
    in that vehicle's lane or in the lane it signals into (``sig``), still
    approaching, drives free; the others follow (``mode_follow``) at ``u``
    of the reference vehicle minus their offset ``xg``, at its speed.
    Returns ``(cycles broken, followers ahead of their reference)``."""
    m = k.shape[0]
    cyc = np.zeros(m, dtype=np.bool_)
    for j in range(m):
        r = rr[j]
        q = r if r > 0 else 0
        cyc[j] = r >= 0 and ref[q] == vid[k[j]] and dist[k[j]] < dist[q]
    n_cyc = 0
    n_ahead = 0
    for j in range(m):
        if cyc[j]:
            n_cyc += 1
            ref[k[j]] = -1
    for j in range(m):
        if cyc[j] or rr[j] < 0:
            continue
        i = k[j]
        r = rr[j]
        in_its_lanes = klane[i] == klane[r] or klane[i] == sig[r]
        if in_its_lanes and dist[i] < dist[r] and phase[i] == 0:
            n_ahead += 1
            continue
        mode[i] = mode_follow
        xref[i] = u[r] - xg[i]
        vref[i] = speed[r]
    return n_cyc, n_ahead


@nb.njit(cache=True)
def tree_references(rows_all, kk, first_of, refs, lb_of, pred_of, rear_row, X, xg, speed, v0, hold_gap, mode_tree,
                    mode, xref, vref, tight, hold):
    """The virtual platoon's references of the live members ``rows_all`` of
    nodes ``kk``, in place (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`):
    a node's first vehicle its layer reference (never ahead of itself) at
    ``v0``, the others their offset behind the first vehicle at its speed;
    the bound behind an earlier conflicting node's rear (``lb_of``) binds
    where it lies ahead of that (``tight``: full braking), at the speed of
    that rear vehicle; ``hold`` where the vehicle is already more than
    ``hold_gap`` (+1e-9) inside that bound."""
    for j in range(rows_all.shape[0]):
        r = rows_all[j]
        c = kk[j]
        first = first_of[c]
        if r == first:
            a = refs[c + 1]
            paper = a if a > X[r] else X[r]
            vpaper = v0
        else:
            paper = X[first] + xg[r] - xg[first]
            vpaper = speed[first]
        lb = lb_of[c]
        bind = lb > paper
        mode[r] = mode_tree
        hold[r] = X[r] < lb - hold_gap - 1e-9
        xref[r] = lb if bind else paper
        vref[r] = speed[rear_row[pred_of[c]]] if bind else vpaper
        tight[r] = bind


@nb.njit(cache=True)
def stop_flags(phase, allowed, mv, klane, lc_lane, tlane, dist, R1, coordinated, hold, advised, u, length):
    """Who may not enter the box (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`):
    an approaching vehicle in a lane its movement may not leave from
    (``allowed[mv, clip(klane, 0, 2)]``), changing lanes or not yet in its
    target lane; inside ``R1`` without coordination; held; advised (rows
    ``advised``); none already at the line (``u > -length / 2``). Returns
    ``(stop, held approaching vehicles)``."""
    n = phase.shape[0]
    stop = np.empty(n, dtype=np.bool_)
    held = 0
    for i in range(n):
        lane = klane[i]
        if lane < 0:
            lane = 0
        if lane > 2:
            lane = 2
        appr = phase[i] == 0
        s = appr and (not allowed[mv[i], lane] or lc_lane[i] >= 0 or klane[i] != tlane[i])
        s = s or (appr and dist[i] <= R1 and not coordinated[i])
        s = s or (appr and hold[i])
        if appr and hold[i]:
            held += 1
        stop[i] = s
    for j in range(advised.shape[0]):
        stop[advised[j]] = True
    for i in range(n):
        stop[i] = stop[i] and not (u[i] > -0.5 * length[i])
    return stop, held


@nb.njit(cache=True, error_model="numpy")
def vp_references(fk, fk_rows, ref, vid, dist, klane, sig, phase, u, xg, speed, X, length, mv, leg, node, cleared,
                  has_tree, rows_all, kk, first_of, refs, lb_of, pred_of, rear_row, rear, U, t_ids, t_mvs, t_depths,
                  t_lens, conflict, leg_of, allowed, lc_lane, tlane, coordinated, v0, hold_gap, D_t, den, stop_margin,
                  queue_gap, zone_advisory, anticipate, R1, R2, floor, D_safe, b, tau, bt2, mode_free, mode_follow,
                  mode_tree):
    """:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._references`
    after the tree, in one call and in its order: the formation followers
    ``fk`` of the vehicles at rows ``fk_rows`` (:func:`follow_references`),
    the tree's references of its live members (:func:`tree_references`,
    with ``has_tree``), the speed advisory inside ``R1`` (with
    ``zone_advisory``), the adjusting zone's anticipation
    (:func:`anticipated_references` and its holds and advisories, with
    ``anticipate`` and ``has_tree``), the virtual lane's caps
    (:func:`virtual_caps`) and the stop flags (:func:`stop_flags`); the
    array code's operations in its order (numpy's ``maximum`` as
    :func:`npy_maximum`, ``x ** 2`` as ``x * x``).

    Returns ``(mode, Fr (3, n): xref, vref, cap, Bo (2, n): tight, stop,
    counts, zone, Z (3, m), adv, A (2, m), ant, AR, bound)``: ``counts``
    the broken cycles, followers ahead of their reference and vehicles held
    at the line; the zone advisory's rows, and by rows of ``Z`` their
    advised speed, hold and the tree's speed reference; the anticipation's
    advised rows, and by rows of ``A`` their speed and hold; its holding
    rows, their reference and the bounding node's id (-1: the layer
    reference binds)."""
    n = X.shape[0]
    mode = np.full(n, mode_free, dtype=np.int64)
    Fr = np.empty((3, n))
    xref = Fr[0]
    vref = Fr[1]
    for i in range(n):
        xref[i] = 0.0
        vref[i] = v0
    Bo = np.zeros((2, n), dtype=np.bool_)
    tight = Bo[0]
    hold = np.zeros(n, dtype=np.bool_)
    counts = np.zeros(3, dtype=np.int64)
    if fk.shape[0] > 0:
        n_cyc, n_ahead = follow_references(fk, fk_rows, ref, vid, dist, klane, sig, phase, u, xg, speed, mode_follow,
                                           mode, xref, vref)
        counts[0] = n_cyc
        counts[1] = n_ahead
    m_all = rows_all.shape[0]
    if has_tree:
        tree_references(rows_all, kk, first_of, refs, lb_of, pred_of, rear_row, X, xg, speed, v0, hold_gap, mode_tree,
                        mode, xref, vref, tight, hold)
    # the speed advisory inside R1 (VirtualPlatoon._references' docstring)
    w = np.zeros(m_all, dtype=np.bool_)
    Hz = np.empty(m_all)
    Lz = np.empty(m_all)
    nz = 0
    if zone_advisory:
        for j in range(m_all):
            r = rows_all[j]
            H = xref[r] - X[r]
            room = speed[r] * speed[r] / den
            L = npy_maximum(-u[r] - 0.5 * length[r] - stop_margin, 0.0)
            Hz[j] = H
            Lz[j] = L
            w[j] = phase[r] == 0 and H > room and L - room > queue_gap
            if w[j]:
                nz += 1
    zone = np.empty(nz, dtype=np.int64)
    Z = np.empty((3, nz))
    q = 0
    for j in range(m_all):
        if w[j]:
            r = rows_all[j]
            Z[2, q] = vref[r]
            vref[r] = v0 * Lz[j] / (Lz[j] + Hz[j])
            xref[r] = X[r]
            tight[r] = False
            zone[q] = r
            Z[0, q] = vref[r]
            Z[1, q] = Hz[j]
            q += 1
    # the adjusting zone's anticipation (VirtualPlatoon._references' docstring)
    adv = np.empty(0, dtype=np.int64)
    A = np.empty((2, 0))
    ant = np.empty(0, dtype=np.int64)
    AR = np.empty(0)
    bound = np.empty(0, dtype=np.int64)
    if anticipate and has_tree:
        cand = np.empty(n, dtype=np.int64)
        nc = 0
        for i in range(n):
            if (mode[i] == mode_free and phase[i] == 0 and node[i] < 0 and dist[i] > R1 and dist[i] <= R2
                    and not cleared[i]):
                cand[nc] = i
                nc += 1
        cand = cand[:nc]
        if nc > 0:
            aref, alb, apred, R, room, H = anticipated_references(cand, mv, leg, dist, X, speed, conflict, leg_of, t_mvs,
                                                                  rear_row, rear, t_depths, t_lens, refs[0], D_t, den)
            n_hold = 0
            n_slow = 0
            for j in range(nc):
                if H[j] > 0 and H[j] <= room[j]:
                    n_hold += 1
                if H[j] > room[j] and floor < v0:
                    n_slow += 1
            if n_hold or n_slow:
                adv = np.empty(n_slow, dtype=np.int64)
                A = np.empty((2, n_slow))
                q = 0
                for j in range(nc):
                    if H[j] > room[j] and floor < v0:
                        c = cand[j]
                        L = npy_maximum(dist[c] - R1, 0.0)
                        va = npy_maximum(v0 * L / (L + npy_maximum(H[j], 1e-9)), floor)
                        mode[c] = mode_tree
                        xref[c] = X[c]
                        vref[c] = va
                        adv[q] = c
                        A[0, q] = va
                        A[1, q] = H[j]
                        q += 1
                ant = np.empty(n_hold, dtype=np.int64)
                AR = np.empty(n_hold)
                bound = np.empty(n_hold, dtype=np.int64)
                q = 0
                for j in range(nc):
                    if H[j] > 0 and H[j] <= room[j]:
                        c = cand[j]
                        binds = alb[j] >= aref[j]
                        mode[c] = mode_tree
                        xref[c] = R[j]
                        vref[c] = speed[rear_row[apred[j]]] if binds else v0
                        ant[q] = c
                        AR[q] = R[j]
                        bound[q] = t_ids[apred[j]] if binds else -1
                        q += 1
    if has_tree and m_all > 0:
        cap = virtual_caps(n, rows_all, kk, U, X, rear, rear_row, speed, D_safe, b, tau, bt2)
        for i in range(n):
            Fr[2, i] = cap[i]
    else:
        for i in range(n):
            Fr[2, i] = np.inf
    stop, held = stop_flags(phase, allowed, mv, klane, lc_lane, tlane, dist, R1, coordinated, hold, zone, u, length)
    for i in range(n):
        Bo[1, i] = stop[i]
    counts[2] = held
    return mode, Fr, Bo, counts, zone, Z, adv, A, ant, AR, bound


@nb.njit(cache=True)
def observation_references(mode, xref, vref, u, X, speed, v0, adv, adv_H, adv_vtree, node, stop, mode_free,
                           mode_follow, mode_tree):
    """:meth:`icv_envs.policies.platoon_expert.PlatoonExpert.references`
    compiled: per vehicle whether it has a reference (``mode`` not free),
    the position error to it along the route (``xref - u`` following,
    ``X - xref`` in the tree, else 0), the speed error (``vref - speed``,
    else ``v0 - speed``); the rows ``adv`` under the advisory inside ``R1``
    report their hold ``-H`` and the tree's speed reference; whether it may
    enter the box (in a node, not stopped). Returns ``(has, d, dv, go)``."""
    n = mode.shape[0]
    has = np.empty(n, dtype=np.bool_)
    d = np.zeros(n)
    dv = np.empty(n)
    go = np.empty(n, dtype=np.bool_)
    for i in range(n):
        has[i] = mode[i] != mode_free
        if mode[i] == mode_follow:
            d[i] = xref[i] - u[i]
        elif mode[i] == mode_tree:
            d[i] = X[i] - xref[i]
        dv[i] = (vref[i] - speed[i]) if has[i] else (v0 - speed[i])
        go[i] = node[i] >= 0 and not stop[i]
    for j in range(adv.shape[0]):
        r = adv[j]
        d[r] = -adv_H[j]
        dv[r] = adv_vtree[j] - speed[r]
    return has, d, dv, go
