"""The intersection's vehicle regrouping, compiled loops (paper Sec. 5,
:class:`icv_envs.policies.regrouping.Regrouping`): which lane changes are
ready to start (:func:`lane_change_ready`), the approach zone's fronts
(:func:`approach_fronts`), the sub-formations' lane-change state
(:func:`lane_change_state`), the gap test of the lane changes that are
ready (:func:`lane_change_gaps`), the merging (:func:`merge_pairs`), the
vehicles stuck out of their lane inside ``R1`` (:func:`stuck_in_zone`), the
lane changes that end
(:func:`lane_change_progress`), the sub-formations' distance bounds
(:func:`segment_bounds`); the approach, the adjusting's test and the
merging's in one call (:func:`regroup_pass`). Rules:
:mod:`icv_envs.policies._kernels`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.policies._kernels.corridors import corridor_neighbours
from icv_envs.policies._kernels.lane_changes import _idm_interaction
from icv_envs.sim._kernels.physics import npy_maximum, npy_minimum

__all__ = ["approach_fronts", "lane_change_gaps", "lane_change_progress", "lane_change_ready", "lane_change_state",
           "merge_pairs", "regroup_pass", "segment_bounds", "stuck_in_zone"]


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


@nb.njit(cache=True)
def lane_change_gaps(rows, nxt, leg, speed, u, dist, vlen, keys, corr, crow, coord, big, lc_duration, lc_min_length,
                     lc_max_length, lc_stop_room, min_length_ok, lc_min_gap, b_safe, a_max, sqrt_ab2, member_T, member_s0,
                     R1):
    """The gap test of
    :meth:`icv_envs.policies.regrouping.Regrouping._start_lane_changes` for
    the ready vehicles ``rows`` changing into lanes ``nxt`` (from stop 42;
    the array code it replaced is frozen in ``tests/test_expert_kernels.py``):

    * the manoeuvre's length ``clip(v lc_duration, lc_min_length,
      lc_max_length)``, at most the room before the stop line ``-u -
      lc_stop_room``; it fits when at least ``min_length_ok``;
    * the leader and follower in the target lane's corridor
      (:func:`~icv_envs.policies._kernels.corridor_neighbours` on the index
      ``keys, corr, crow, coord``, key ``corr * big + u``), the bumper gaps
      to them (``inf`` without) and IDM's interaction term of this vehicle
      behind the leader and of the follower behind this vehicle (member
      time gap and standstill distance); the change is accepted when both
      gaps exceed ``lc_min_gap`` and neither deceleration exceeds
      ``b_safe``;
    * the refused ones that fit and are beside a vehicle of the target lane
      (the follower's gap first, then the leader's, at most ``lc_min_gap``),
      outside ``R1`` and at 2 m/s or more: ``(k, other row)`` pairs in row
      order, for the yields (:meth:`Regrouping._note_yields`);
    * of accepted changes into one corridor within 12 m of each other
      (ordered by corridor, then ``u`` descending, ties in row order, as
      ``lexsort``), every second of a run is dropped.

    Returns ``(length, ok, yield_k, yield_other)``."""
    k = rows.shape[0]
    length = np.empty(k)
    ok = np.empty(k, dtype=np.bool_)
    q_corr = np.empty(k, dtype=np.int64)
    qk = np.empty(k)
    for q in range(k):
        r = rows[q]
        x = speed[r] * lc_duration
        if x < lc_min_length:
            x = lc_min_length
        elif x > lc_max_length:
            x = lc_max_length
        length[q] = npy_minimum(x, -u[r] - lc_stop_room)
        ok[q] = length[q] >= min_length_ok
        q_corr[q] = 3 * leg[r] + nxt[q]
        qk[q] = q_corr[q] * big + u[r]
    lr, lc, fr, fc = corridor_neighbours(keys, corr, crow, coord, rows, q_corr, qk)
    yk = np.empty(k, dtype=np.int64)
    yo = np.empty(k, dtype=np.int64)
    ny = 0
    for q in range(k):
        r = rows[q]
        v = speed[r]
        ln = vlen[r]
        gap_f = lc[q] - u[r] - 0.5 * (vlen[lr[q]] + ln) if lr[q] >= 0 else np.inf
        gap_r = u[r] - fc[q] - 0.5 * (vlen[fr[q]] + ln) if fr[q] >= 0 else np.inf
        vl = speed[lr[q]] if lr[q] >= 0 else v
        vf = speed[fr[q]] if fr[q] >= 0 else 0.0
        own = _idm_interaction(v, gap_f, v - vl, member_T, a_max, member_s0, sqrt_ab2)
        fol = _idm_interaction(vf, gap_r, vf - v, member_T, a_max, member_s0, sqrt_ab2)
        possible = ok[q]
        ok[q] = possible and gap_f > lc_min_gap and gap_r > lc_min_gap and own > -b_safe and fol > -b_safe
        if possible and not ok[q] and dist[r] > R1 and speed[r] >= 2.0:
            side_r = fr[q] >= 0 and gap_r <= lc_min_gap
            side_f = lr[q] >= 0 and gap_f <= lc_min_gap
            if side_r or side_f:
                yk[ny] = q
                yo[ny] = fr[q] if side_r else lr[q]
                ny += 1
    # runs of accepted changes into one corridor within 12 m: every second one waits
    o = np.empty(k, dtype=np.int64)
    m = 0
    for q in range(k):
        if ok[q]:
            # (insertion by corridor, then u descending; equal keys keep row order)
            p = m
            while p > 0 and (q_corr[o[p - 1]] > q_corr[q]
                             or (q_corr[o[p - 1]] == q_corr[q] and -u[rows[o[p - 1]]] > -u[rows[q]])):
                o[p] = o[p - 1]
                p -= 1
            o[p] = q
            m += 1
    if m > 1:
        drop = np.zeros(m, dtype=np.bool_)
        for p in range(m - 1):
            a = o[p]
            b = o[p + 1]
            if q_corr[a] == q_corr[b] and abs(u[rows[b]] - u[rows[a]]) < 12.0 and not drop[p]:
                drop[p + 1] = True
        for p in range(m):
            if drop[p]:
                ok[o[p]] = False
    return length, ok, yk[:ny], yo[:ny]


@nb.njit(cache=True)
def merge_pairs(leg, mv, dmin, dmax, adjusted, size, conflict, R1, merge_range, max_node_size):
    """The merging of :meth:`icv_envs.policies.regrouping.Regrouping._merging`
    (paper Sec. 5; compiled from stop 42, the Python loop it replaced is
    frozen in ``tests/test_expert_kernels.py``) over the sub-formations in
    ``self.subs`` order (their legs, movements, least and largest member
    distance to the centre, adjusted or not, sizes), in order of leg, then
    least distance (ties in ``subs`` order, as Python's stable sort): an
    adjusted one entirely outside ``R1`` and not merged takes the
    sub-formations behind it on its leg, skipping other movements that do
    not conflict with its own (one that conflicts ends the search) and
    those already merged, while the next one of its movement is adjusted,
    outside ``R1``, starts within ``merge_range`` of its rear (the largest
    distance of it and of what it took so far) and the two fit in
    ``max_node_size``; the first that does not ends the search. Returns the
    ``(taker, taken)`` pairs in the order they merge, as indices into the
    arrays."""
    K = leg.shape[0]
    o = np.empty(K, dtype=np.int64)
    for q in range(K):
        p = q
        while p > 0 and (leg[o[p - 1]] > leg[q] or (leg[o[p - 1]] == leg[q] and dmin[o[p - 1]] > dmin[q])):
            o[p] = o[p - 1]
            p -= 1
        o[p] = q
    merged = np.zeros(K, dtype=np.bool_)
    pairs = np.empty((K, 2), dtype=np.int64)
    m = 0
    for i in range(K):
        a = o[i]
        if not adjusted[a] or merged[a] or dmin[a] <= R1:
            continue
        rear = dmax[a]
        n_a = size[a]
        for j in range(i + 1, K):
            b = o[j]
            if leg[b] != leg[a]:
                break
            if merged[b]:
                continue
            if mv[b] != mv[a]:
                if conflict[mv[a], mv[b]]:
                    break  # something conflicting lies between them
                continue
            if adjusted[b] and dmin[b] > R1 and dmin[b] - rear <= merge_range and n_a + size[b] <= max_node_size:
                pairs[m, 0] = a
                pairs[m, 1] = b
                m += 1
                merged[b] = True
                n_a += size[b]
                if dmax[b] > rear:
                    rear = dmax[b]
            else:
                break  # the nearest same-movement sub-formation behind decides
    return pairs[:m]


@nb.njit(cache=True)
def stuck_in_zone(phase, lc_lane, dist, R1, coordinated, klane, tlane):
    """The test of :meth:`icv_envs.policies.platoon_expert.PlatoonExpert._reroute_stuck`
    (from stop 42; the array expression it replaced is frozen in
    ``tests/test_expert_kernels.py``): approaching vehicles inside ``R1``
    (``dist <= R1``), not coordinated, not in their expected lane and with
    no lane change under way. Returns their rows."""
    n = phase.shape[0]
    out = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if phase[i] == 0 and lc_lane[i] < 0 and dist[i] <= R1 and not coordinated[i] and klane[i] != tlane[i]:
            out[m] = i
            m += 1
    return out[:m]


@nb.njit(cache=True)
def _crossed_pair(rows, klane, tlane, lc_lane):
    """Whether two members (``rows``) wait to change lanes (none under way,
    not in their target lane) each into the lane the other is in: the
    first exchange ``Regrouping._swap_crossed_targets`` makes (it makes one
    whenever such a pair exists)."""
    m = rows.shape[0]
    for a in range(m):
        ra = rows[a]
        if not (klane[ra] != tlane[ra] and lc_lane[ra] < 0):
            continue
        for b in range(a + 1, m):
            rb = rows[b]
            if klane[rb] != tlane[rb] and lc_lane[rb] < 0 and klane[ra] == tlane[rb] and klane[rb] == tlane[ra]:
                return True
    return False


@nb.njit(cache=True)
def regroup_pass(rows, sizes, n_form, is_lc, leg, mv, adjusted, u, dist, R2, vid, fslot, ref, xg, klane, tlane, lc_lane,
                 conflict, R1, merge_range, max_node_size):
    """:meth:`icv_envs.policies.regrouping.Regrouping._regroup`'s kernels in
    one call (from stop 47), over one table of groups (members in ``rows``,
    group ``k`` the next ``sizes[k] >= 1``): the first ``n_form`` the
    formations not yet divided, the rest every sub-formation in
    ``self.subs`` order (``is_lc``, ``leg``, ``mv``, ``adjusted`` of
    those). In order, each with the arguments of its separate call:

    * :func:`approach_fronts` of the formations (``ref``, ``xg`` written in
      place; the mask of those to divide);
    * :func:`lane_change_state` of the sub-formations changing lanes
      (``is_lc``; computed for all, each one's on its own rows): the
      indices (into the sub-formations) of those settled or with two
      members waiting to change into each other's lanes (the exchange of
      ``Regrouping._swap_crossed_targets``: two waiting members that do not
      cross change nothing there), the adjusting's work (``act``), with
      their ``pending`` and ``settled``;
    * :func:`segment_bounds` of the sub-formations and :func:`merge_pairs`
      on them, valid when nothing above is to be done (no division, ``act``
      empty: the sub-formations are then what the merging reads).

    Returns ``(divide, act, pending, settled, bounds, pairs)``."""
    q_f = 0
    for k in range(n_form):
        q_f += sizes[k]
    divide = approach_fronts(rows[:q_f], sizes[:n_form], u, dist, R2, vid, fslot, ref, xg)
    s_rows = rows[q_f:]
    s_sizes = sizes[n_form:]
    pending, settled = lane_change_state(s_rows, s_sizes, klane, tlane, lc_lane)
    ns = s_sizes.shape[0]
    act = np.empty(ns, dtype=np.int64)
    m = 0
    q0 = 0
    for k in range(ns):
        if is_lc[k] and (settled[k] or (pending[k] >= 2 and _crossed_pair(s_rows[q0:q0 + s_sizes[k]], klane, tlane,
                                                                          lc_lane))):
            act[m] = k
            m += 1
        q0 += s_sizes[k]
    bounds = segment_bounds(s_rows, s_sizes, dist)
    pairs = merge_pairs(leg, mv, bounds[0], bounds[1], adjusted, s_sizes, conflict, R1, merge_range, max_node_size)
    return divide, act[:m], pending, settled, bounds, pairs
