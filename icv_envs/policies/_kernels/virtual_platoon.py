"""The improved virtual platoon's compiled loops, its nodes and their
order (paper Sec. 4.2, :class:`icv_envs.policies.virtual_platoon.VirtualPlatoon`):
each node's first and rear vehicle (:func:`node_heads`), the repair of the
passing order (:func:`repair_order`), the tree-layers with their
references and bounds (:func:`tree_layers`), all three in one call
(:func:`vp_tree`), and the test for members to detach
(:func:`detach_candidates`); the vehicles in the zone without a group
(:func:`zone_orphans`) and the nodes whose members all cleared the box
(:func:`nodes_cleared`). The references the tree gives its vehicles:
:mod:`icv_envs.policies._kernels.vp_references`. Rules:
:mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.platoon._kernels import depths_of
from icv_envs.policies._kernels.corridors import corridor_neighbours

__all__ = ["detach_candidates", "node_heads", "nodes_cleared", "repair_order", "tree_layers", "vp_tree", "zone_orphans"]


@nb.njit(cache=True)
def node_heads(rows, sizes, X, dist):
    """Per node (members in ``rows``, node ``k`` the next ``sizes[k] >= 1``
    of them; ``X``, ``dist`` the members' values, aligned with ``rows``) its
    first vehicle (least ``dist``) and its rear one (largest ``X``), ties to
    the earlier member, as the stable ``lexsort((dist, seg))`` /
    ``lexsort((-X, seg))`` of
    :meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon.tree`'s array
    code chose (finite values). Returns ``(I, V)``: rows ``first,
    rear_row`` of ``I`` and their ``X`` in ``V``."""
    K = sizes.shape[0]
    I = np.empty((2, K), dtype=np.int64)
    V = np.empty((2, K))
    q0 = 0
    for k in range(K):
        m = sizes[k]
        if m < 1:
            raise ValueError("node_heads: a node without members")
        b0 = q0
        b1 = q0
        for q in range(q0 + 1, q0 + m):
            if dist[q] < dist[b0]:
                b0 = q
            if X[q] > X[b1]:
                b1 = q
        I[0, k] = rows[b0]
        I[1, k] = rows[b1]
        V[0, k] = X[b0]
        V[1, k] = X[b1]
        q0 += m
    return I, V


@nb.njit(cache=True)
def repair_order(at, K, rows, seg, phase, lane, dist, leg):
    """The order repair of :meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon.tree`
    (``_repair_order`` until stop 40; :func:`vp_tree` calls it), its pair
    test and repair loop compiled: per node (``seg``, 0..K-1) and approach
    lane the nearest and farthest member distance over the members still
    approaching (``rows >= 0`` with ``phase == 0``); node ``k`` must come before
    node ``i`` of its leg when in a shared lane its nearest member is ahead of
    ``i``'s farthest (by more than 1e-6 m) and of ``i``'s nearest. The order
    ``at`` (node indices) is scanned later node ``b`` first, then earlier
    ``a``; the first such pair moves ``b`` to ``a``'s place and the scan
    restarts, at most ``4 len(at) + 4`` times. Returns the new order and the
    number of moves."""
    C = 1
    for q in range(rows.shape[0]):
        if rows[q] >= 0 and phase[rows[q]] == 0 and lane[rows[q]] + 1 > C:
            C = lane[rows[q]] + 1
    lo = np.full((K, C), np.inf)
    hi = np.full((K, C), -np.inf)
    any_app = False
    for q in range(rows.shape[0]):
        r = rows[q]
        if r < 0 or phase[r] != 0:
            continue
        any_app = True
        g = seg[q]
        c = lane[r]
        d = dist[r]
        if d < lo[g, c]:
            lo[g, c] = d
        if d > hi[g, c]:
            hi[g, c] = d
    at = at.copy()
    moves = 0
    if not any_app:
        return at, moves
    M = np.zeros((K, K), dtype=np.bool_)
    for k in range(K):
        for i in range(K):
            if leg[k] != leg[i]:
                continue
            for c in range(C):
                if lo[k, c] < hi[i, c] - 1e-6 and lo[k, c] < lo[i, c]:
                    M[k, i] = True
                    break
    n = at.shape[0]
    for _ in range(4 * n + 4):
        hit_b = -1
        hit_a = -1
        for b in range(n):
            for a in range(b):
                if M[at[b], at[a]]:
                    hit_b = b
                    hit_a = a
                    break
            if hit_b >= 0:
                break
        if hit_b < 0:
            break
        moved = at[hit_b]
        for q in range(hit_b, hit_a, -1):
            at[q] = at[q - 1]
        at[hit_a] = moved
        moves += 1
    return at, moves


@nb.njit(cache=True)
def _layers_before(depths, offset, lens, top):
    """``before[m]``: the summed length of the longest node of every layer
    below ``m`` (layers ``0..top``; node ``k`` of depth ``depths[k + offset]``
    and length ``lens[k]``), as ``numpy.maximum.at`` then ``cumsum`` take them
    (the maximum returns the new length on a tie; the sum runs in order).
    ``before`` has ``top + 2`` entries."""
    layer_max = np.zeros(top + 1)
    for k in range(lens.shape[0]):
        d = depths[k + offset]
        layer_max[d] = layer_max[d] if layer_max[d] > lens[k] else lens[k]
    before = np.empty(top + 2)
    before[0] = 0.0
    s = 0.0
    for i in range(top + 1):
        s += layer_max[i]
        before[i + 1] = s
    return before


@nb.njit(cache=True)
def tree_layers(mvs, conflict, xf, lens, rear, D_t):
    """The virtual platoon's tree and references for nodes in order
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon.tree`): the
    conflict block of the nodes' movements, the tree-layers
    (:func:`icv_envs.platoon._kernels.depths_of`), the layer references of
    :func:`icv_envs.platoon.tree._reference_positions` (the first vehicles'
    ``X`` made nondecreasing first), the upper triangle ``U`` (earlier
    conflicting nodes), and per node the bound ``D_t`` behind the rear of
    its earlier conflicting nodes (``-inf`` without one) with the first node
    attaining it. Returns ``(depths, refs, U, lb, pred)``; the array code's
    operations in its order (``maximum.accumulate``, ``maximum.at`` and
    ``cumsum`` as numpy takes them; ``argmax``'s first index)."""
    K = mvs.shape[0]
    C = np.empty((K, K), dtype=np.bool_)
    for i in range(K):
        for j in range(K):
            C[i, j] = conflict[mvs[i], mvs[j]]
    depths = depths_of(C)
    # _reference_positions(maximum.accumulate(xf), lens, depths, D_t)
    top = 0
    for k in range(K + 1):
        if depths[k] > top:
            top = depths[k]
    before = _layers_before(depths, 1, lens, top)
    refs = np.empty(K + 1)
    x0 = xf[0] - D_t
    for k in range(K + 1):
        refs[k] = x0 + depths[k] * D_t + before[depths[k]]
    refs[0] = x0
    U = np.zeros((K, K), dtype=np.bool_)
    lb = np.empty(K)
    pred = np.zeros(K, dtype=np.int64)
    for j in range(K):
        best = -np.inf
        arg = 0
        for i in range(K):
            if i < j and C[i, j]:
                U[i, j] = True
                v = rear[i] + D_t
            else:
                v = -np.inf
            if v > best:
                best = v
                arg = i
        lb[j] = best
        pred[j] = arg
    return depths, refs, U, lb, pred


@nb.njit(cache=True)
def vp_tree(rows, seg, sizes, ids, vp_order, mvs, lens, X, dist, phase, lane, cleared, leg_of, conflict, D_t):
    """:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon.tree` in one
    call, from every node's members (``rows``, ``seg``, ``sizes`` in the
    insertion order ``ids`` of the nodes, each node's in member order) and
    the nodes' movements ``mvs`` and lengths ``lens``: each node's first and
    rear vehicle (:func:`node_heads`); the nodes in the virtual platoon's
    order (the rank in ``vp_order``, the last place of an id listed twice,
    nodes not listed after the listed ones by id: the stable argsort of
    ``rank.get(id, len(rank) + id)`` with ``rank`` the dict of ``vp_order``'s
    places), repaired (:func:`repair_order`); the tree-layers and their
    references and bounds (:func:`tree_layers`) in that order; and the
    members not yet cleared, in that order, with the place of their node
    (what ``_member_rows`` answered for the ordered ids, filtered).

    Returns ``(moves, I, F, depths, refs, U, live_rows, live_node)``: ``I
    (5, K)`` by rows ``at`` (the order, indices into ``ids``), ``first``,
    ``rear_row``, ``pred``, ``mvs``; ``F (4, K)`` by rows ``xf``, ``rear``,
    ``lb``, ``lens`` (all but ``at`` in the new order)."""
    K = sizes.shape[0]
    nr = rows.shape[0]
    Xr = np.empty(nr)
    dr = np.empty(nr)
    for q in range(nr):
        Xr[q] = X[rows[q]]
        dr[q] = dist[rows[q]]
    I0, V0 = node_heads(rows, sizes, Xr, dr)
    # the rank of each id (its last place in vp_order); unlisted ids after the listed ones, by id
    no = vp_order.shape[0]
    distinct = 0
    for i in range(no):
        seen = False
        for j in range(i):
            if vp_order[j] == vp_order[i]:
                seen = True
                break
        if not seen:
            distinct += 1
    keys = np.empty(K, dtype=np.int64)
    for k in range(K):
        r = -1
        for i in range(no):
            if vp_order[i] == ids[k]:
                r = i
        keys[k] = r if r >= 0 else distinct + ids[k]
    o = np.argsort(keys, kind="mergesort")
    leg = np.empty(K, dtype=np.int64)
    for k in range(K):
        leg[k] = leg_of[mvs[k]]
    at, moves = repair_order(o, K, rows, seg, phase, lane, dist, leg)
    I = np.empty((5, K), dtype=np.int64)
    F = np.empty((4, K))
    for c in range(K):
        g = at[c]
        I[0, c] = g
        I[1, c] = I0[0, g]
        I[2, c] = I0[1, g]
        I[4, c] = mvs[g]
        F[0, c] = V0[0, g]
        F[1, c] = V0[1, g]
        F[3, c] = lens[g]
    depths, refs, U, lb, pred = tree_layers(I[4], conflict, F[0], F[3], F[1], D_t)
    for c in range(K):
        I[3, c] = pred[c]
        F[2, c] = lb[c]
    start = np.empty(K, dtype=np.int64)
    s = 0
    for k in range(K):
        start[k] = s
        s += sizes[k]
    live_rows = np.empty(nr, dtype=np.int64)
    live_node = np.empty(nr, dtype=np.int64)
    m = 0
    for c in range(K):
        g = at[c]
        for q in range(start[g], start[g] + sizes[g]):
            if not cleared[rows[q]]:
                live_rows[m] = rows[q]
                live_node[m] = c
                m += 1
    return moves, I, F, depths, refs, U, live_rows[:m], live_node[:m]


@nb.njit(cache=True)
def detach_candidates(node, phase, leg, lane, s, dist, keys, corr, crows, coord, big, mr, seg, ids):
    """The test of :meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._detach_inverted`,
    compiled: the approaching node members (``node >= 0``, ``phase == 0``,
    in row order) whose leader in their approach corridor ``3 leg + lane``
    (:func:`~icv_envs.policies._kernels.corridor_neighbours` on the index
    ``keys, corr, crows, coord`` at key ``corridor * big + s``) is an
    approaching vehicle of another node or of none, further from the centre
    than the first vehicle (least ``dist``) of the member's node by more than
    1e-9 m, as the member is (nodes ``ids`` with their members' rows ``mr``,
    ``seg`` the index into ``ids``; a node not among them counts as having
    its first vehicle at ``inf``). Returns ``(rows, bad)``: the approaching
    members and the test's answer per member."""
    n = node.shape[0]
    rows = np.empty(n, dtype=np.int64)
    q_corr = np.empty(n, dtype=np.int64)
    qk = np.empty(n)
    m = 0
    for i in range(n):
        if node[i] >= 0 and phase[i] == 0:
            rows[m] = i
            q_corr[m] = 3 * leg[i] + lane[i]
            qk[m] = q_corr[m] * big + s[i]
            m += 1
    rows, q_corr, qk = rows[:m], q_corr[:m], qk[:m]
    bad = np.zeros(m, dtype=np.bool_)
    if m == 0:
        return rows, bad
    lr, _, _, _ = corridor_neighbours(keys, corr, crows, coord, rows, q_corr, qk)
    K = ids.shape[0]
    dmin = np.full(K, np.inf)
    for j in range(mr.shape[0]):
        d = dist[mr[j]]
        if d < dmin[seg[j]]:
            dmin[seg[j]] = d
    for q in range(m):
        r = rows[q]
        a = lr[q]
        if a < 0 or node[a] == node[r] or phase[a] != 0:
            continue
        fd = np.inf
        for k in range(K):
            if ids[k] == node[r]:
                fd = dmin[k]
                break
        bad[q] = dist[a] > fd + 1e-9 and dist[r] > fd + 1e-9
    return rows, bad


@nb.njit(cache=True)
def zone_orphans(dist, R1, node, sub, phase, cleared, klane, tlane, lc_lane):
    """The vehicles inside ``R1`` in no node and no sub-formation, not yet
    cleared nor departed, ready to be a node of their own: in their target
    lane with no lane change under way, or already past the stop line
    (:meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._coordinate`),
    in row order."""
    n = dist.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if dist[i] <= R1 and node[i] < 0 and sub[i] < 0 and phase[i] < 2 and not cleared[i]:
            if (klane[i] == tlane[i] and lc_lane[i] < 0) or phase[i] > 0:
                out[m] = i
                m += 1
    return out[:m]


@nb.njit(cache=True)
def nodes_cleared(rows, sizes, cleared):
    """Per node (members in ``rows``, node ``k`` the next ``sizes[k]``):
    whether every member has cleared the box (the node then leaves the
    virtual platoon, :meth:`icv_envs.policies.virtual_platoon.VirtualPlatoon._coordinate`)."""
    K = sizes.shape[0]
    done = np.ones(K, dtype=np.bool_)
    q0 = 0
    for k in range(K):
        for q in range(q0, q0 + sizes[k]):
            if not cleared[rows[q]]:
                done[k] = False
                break
        q0 += sizes[k]
    return done
