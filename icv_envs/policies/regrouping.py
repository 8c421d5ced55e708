"""Vehicle regrouping in the adjusting zone (paper Sec. 5): division, lane change, formation adjusting, merging.

The lane changes are :mod:`icv_envs.policies.lane_changes_regrouping`'s (a
mixin of this one's). A mixin of :class:`icv_envs.policies.platoon_expert.PlatoonExpert`; the
behaviour is documented in that module's docstring ("Adjusting zone").
"""

from __future__ import annotations

import numpy as np

from icv_envs.formation.assignment import assign_targets
from icv_envs.formation.targets import interlaced_targets
from icv_envs.policies._kernels import (
    approach_fronts,
    lane_change_state,
    merge_pairs,
    regroup_pass,
    segment_bounds,
)
from icv_envs.policies.lane_changes_regrouping import LaneChanges
from icv_envs.policies.platoon_common import (
    ST_ADJUSTED,
    ST_LC,
    group_rows,
    same_objects,
)
from icv_envs._ufuncs import flatnonzero

__all__ = ["Regrouping"]


class Regrouping(LaneChanges):
    """Division, lane changes (:class:`~icv_envs.policies.lane_changes_regrouping.LaneChanges`),
    adjusting and merging of sub-formations (Sec. 5)."""

    # ----------------------------------------------------- approach, division
    def _approach_and_division(self, world, rs) -> None:
        """Formations not yet divided: members track the front with their
        spawn slots while it approaches; once the front is within ``R2``
        the formation divides (:meth:`_divide`). The fronts and slots of all
        of them in one compiled call (policies/_kernels.approach_fronts, from
        stop 41; each formation's rows are its own, so dividing after the
        others' slots are set changes nothing)."""
        f = world.fleet
        todo = [F for F in self.formations.values() if not F["divided"]]
        if not todo:
            return
        rows, sizes = group_rows(f, [F["members"] for F in todo])
        divide = approach_fronts(rows, sizes, rs.u, rs.dist, float(world.layout.R2), f.vid, f.fslot, f.ref, f.xg)
        self._divide_marked(world, rs, todo, rows, sizes, divide)

    def _divide_marked(self, world, rs, todo: list, rows, sizes, divide) -> None:
        """The formations ``todo[k]`` marked in ``divide`` divide
        (:meth:`_divide`), in order; formation ``k``'s members are the next
        ``sizes[k]`` of ``rows``."""
        if np.count_nonzero(divide):
            start = np.cumsum(sizes) - sizes
            for k in flatnonzero(divide).tolist():
                self._divide(world, rs, todo[k], rows[start[k]:start[k] + sizes[k]])

    def _divide(self, world, rs, F, rows) -> None:
        """Division (Sec. 5): split by movement, keep every lane's order, one file of slots ``gap_out`` apart."""
        p = self.p
        f = world.fleet
        lay = world.layout
        F["divided"] = True
        self.stats["divisions"] += 1
        order = rows[np.lexsort((f.klane[rows], -rs.u[rows]))]
        queues = [[r for r in order if f.klane[r] == ln] for ln in range(3)]
        seq, groups = [], []
        cur = None
        while any(queues):
            heads = [(q[0], ln) for ln, q in enumerate(queues) if q]
            same = [h for h in heads if f.mv[h[0]] == cur]
            if same:
                r, ln = max(same, key=lambda h: rs.u[h[0]])
            else:
                r, ln = max(heads, key=lambda h: rs.u[h[0]])
                cur = int(f.mv[r])
                groups.append([])
            queues[ln].pop(0)
            seq.append(r)
            groups[-1].append(r)
        front = seq[0]
        for rank, r in enumerate(seq):
            f.ref[r] = f.vid[front] if rank else -1
            f.xg[r] = rank * p.gap_out
            f.stage[r] = ST_LC
        for g in groups:
            g = np.asarray(g, dtype=np.int64)
            mv = int(f.mv[g[0]])
            lanes = lay.lane_use[mv]
            sid = self._new_id()
            n = len(g)
            if len(lanes) == 1:
                tl = np.full(n, lanes[0])
                tidx = np.arange(n)
            else:
                tx, tlid = interlaced_targets(n, len(lanes), p.gap_out)
                vx = rs.u[g[0]] - rs.u[g]
                vl = f.klane[g] - lanes[0] + 1
                asg = assign_targets(vx, vl, tx, tlid, p.w1, p.w2)
                tidx = asg
                tl = np.asarray(lanes)[tlid[asg] - 1]
            f.tlane[g] = tl
            f.tidx[g] = tidx
            f.sub[g] = sid
            members = [int(f.vid[r]) for r in g[np.argsort(tidx)]]
            self.subs[sid] = {"id": sid, "leg": int(f.leg[g[0]]), "mv": mv, "members": members,
                              "lanes": tuple(lanes), "state": "lc", "form": F["id"]}
            self.stats["subformations"] += 1

    def _slot_error(self, world, rs, rows) -> np.ndarray:
        f = world.fleet
        ref = f.rows(f.ref[rows])
        ok = ref >= 0
        err = np.zeros(len(rows))
        err[ok] = rs.u[rows[ok]] - (rs.u[ref[ok]] - f.xg[rows[ok]])
        return err

    # ------------------------------------------------------ adjusting, merging
    def _set_sub_targets(self, world, S) -> None:
        """Interlaced targets with the in-zone gap behind the sub-formation's first vehicle."""
        f = world.fleet
        rows = f.rows(S["members"])
        n = len(rows)
        tx, _ = interlaced_targets(n, len(S["lanes"]), self.p.gap_in)
        # within each lane, hand that lane's targets out in the physical order
        # (a vehicle is never asked to overtake another in its own lane)
        dist = world.route().dist[rows]
        tidx = f.tidx[rows].copy()
        for ln in np.unique(f.tlane[rows]):
            k = flatnonzero(f.tlane[rows] == ln)
            tidx[k[np.argsort(dist[k], kind="stable")]] = np.sort(tidx[k])
        f.tidx[rows] = tidx
        # ranks in physical order (distance to the centre; ties: target order):
        # the first vehicle is the sub-formation's physical front and every
        # member's slot is behind every member ahead of it, whatever lane it
        # is in, so no member has to pass another one (a member ranked ahead
        # of one in front of it in its current lane waits for it, and it for
        # the member: a circular wait); a member still waiting to change lanes
        # counts as behind a member alongside it in the lane it needs
        # (:meth:`_order_keys`)
        key = self._order_keys(world, rows, dist)
        rank = np.argsort(np.lexsort((tidx, key)), kind="stable")
        if not np.array_equal(rank, np.argsort(np.lexsort((tidx, dist)), kind="stable")):
            self.stats["lc_ranked_behind"] += 1
        f.tidx[rows] = rank
        first = rows[rank == 0][0]
        f.ref[rows] = f.vid[first]
        f.xg[rows] = tx[rank]
        f.ref[first] = -1
        f.xg[first] = 0.0

    def _order_keys(self, world, rows, dist) -> np.ndarray:
        """Sort keys (metres to the centre) for the ranks of a sub-formation's members.

        The physical order (``dist``), except that a member that still has to
        change lanes (none started) is put right behind every member of the
        group occupying the lane it changes into whose body it overlaps
        (bumper gap < 0), and so behind every member that one is behind in
        its lane: the order the safety envelope enforces at low speed, where
        the waiting vehicle's turn signal lists it in that lane behind the
        vehicle alongside it (:meth:`PlatoonExpert._envelope`).  Ranked in
        front instead, the member alongside got its slot behind the waiting
        vehicle: it stood (it cannot back up), and the waiting vehicle stood
        behind it in the lane it wants, both for ever (multi-vp, 2000 veh/h,
        seed 7: from 268 s to the end of the run, 39 jammed behind them).
        Two members that would swap lanes are not ordered this way (each
        would wait for the other)."""
        f = world.fleet
        key = np.asarray(dist, dtype=np.float64).copy()
        n = len(rows)
        if n < 2:
            return key
        u = world.route().u[rows]
        klane = f.klane[rows]
        pend = (klane != f.tlane[rows]) & (f.lc_lane[rows] < 0)
        if not pend.any():
            return key
        nxt = np.where(pend, klane + np.sign(f.tlane[rows] - klane), -1)
        occ = np.where(f.lc_lane[rows] >= 0, f.lc_lane[rows], klane)  # the lane a member is in / going into
        half = 0.5 * f.length[rows]
        # behind[c, m]: c must be ranked behind m
        beside = (u[:, None] - u[None, :] - half[:, None] - half[None, :]) < 0.0
        behind = pend[:, None] & (occ[None, :] == nxt[:, None]) & beside & (nxt[None, :] != klane[:, None])
        # ... and, in its own lane, every member is behind the members ahead of it
        same = (occ[:, None] == occ[None, :]) & (u[:, None] < u[None, :])
        np.fill_diagonal(behind, False)
        eps = 1e-3
        for _ in range(2 * n):  # longest-path relaxation over an acyclic "behind" relation
            cand = np.where(behind | same, key[None, :] + eps, -np.inf).max(axis=1)
            upd = cand > key
            if not upd.any():
                break
            key = np.maximum(key, cand)
        return key

    def _adjusting(self, world, rs) -> None:
        """Sub-formations changing lanes: two members waiting to change into
        each other's lane swap targets (:meth:`_swap_crossed_targets`); once
        every member is in its target lane with no change under way, the
        sub-formation is adjusted (stage, in-zone targets). Which ones have
        two members waiting and which are settled, in one compiled call
        (policies/_kernels.lane_change_state, from stop 41; each
        sub-formation changes only its own members' rows)."""
        f = world.fleet
        lc = [S for S in self.subs.values() if S["state"] == "lc"]
        if not lc:
            return
        rows_all, sizes = group_rows(f, [S["members"] for S in lc])
        pending, settled = lane_change_state(rows_all, sizes, f.klane, f.tlane, f.lc_lane)
        # (only those with two members waiting or settled have anything to do:
        # most steps none, from stop 42)
        act = flatnonzero((pending >= 2) | settled)
        if len(act):
            self._adjust_marked(world, lc, rows_all, sizes, pending, settled, act)

    def _adjust_marked(self, world, groups: list, rows_all, sizes, pending, settled, act) -> bool:
        """The adjusting's work on the sub-formations ``groups[k]`` for ``k``
        in ``act`` (in order; sub-formation ``k``'s members the next
        ``sizes[k]`` of ``rows_all``, ``pending[k]`` of them waiting to
        start a lane change, ``settled[k]`` all in their target lanes).
        Returns whether a sub-formation changed (two members exchanged
        targets, or it is adjusted): most calls, two members wait for lane
        changes that do not cross, and none does."""
        f = world.fleet
        start = np.cumsum(sizes) - sizes
        changed = False
        for k in act.tolist():
            S = groups[k]
            rows = rows_all[start[k]:start[k] + sizes[k]]
            done = settled[k]
            if pending[k] >= 2:
                changed |= self._swap_crossed_targets(S, f, rows)
                done = np.all((f.klane[rows] == f.tlane[rows]) & (f.lc_lane[rows] < 0))
            if done:
                S["state"] = "adjusted"
                f.stage[rows] = np.maximum(f.stage[rows], ST_ADJUSTED)
                self._set_sub_targets(world, S)
                changed = True
        return changed

    def _regroup_steps(self, world, rs) -> None:
        """The regrouping's approach and division, adjusting and merging, as
        separate calls (what :meth:`_regroup` stands for)."""
        self._approach_and_division(world, rs)
        self._adjusting(world, rs)
        self._merging(world, rs)

    def _regroup(self, world, rs) -> None:
        """:meth:`_approach_and_division`, :meth:`_adjusting` and
        :meth:`_merging`, in this order, with their kernels in one call
        (:func:`~icv_envs.policies._kernels.regroup_pass`, from stop 47) over
        one table of the groups' rows (the formations not yet divided, then
        every sub-formation): the same reads and writes as the three calls.
        What follows a division, or an adjusting that changes a
        sub-formation, runs as the separate calls do (the sub-formations
        changed; an adjusting with work that changes nothing, most of the
        time, does not count); otherwise the merging's pairs and its table
        (kept for :meth:`_sub_distances`, as :meth:`_sub_table` keeps it)
        come from the same call. A group
        without members takes the separate calls (and their error)."""
        f = world.fleet
        todo = [F for F in self.formations.values() if not F["divided"]]
        subs = list(self.subs.values())
        if not todo and not subs:
            return
        nf, K = len(todo), len(subs)
        s_members = [S["members"] for S in subs]
        f_members = [F["members"] for F in todo]
        rows, sizes = group_rows(f, f_members + s_members)
        if np.count_nonzero(sizes) < len(sizes):
            self._regroup_steps(world, rs)
            return
        lay = world.layout
        p = self.p
        divide, act, pending, settled, bounds, pairs = regroup_pass(
            rows, sizes, nf, np.fromiter([S["state"] == "lc" for S in subs], dtype=bool, count=K),
            *self._sub_columns(subs), rs.u, rs.dist, float(lay.R2), f.vid, f.fslot, f.ref, f.xg, f.klane, f.tlane,
            f.lc_lane, lay.conflict, float(lay.R1), float(p.merge_range), int(p.max_node_size))
        q_f = sum(map(len, f_members))
        if np.count_nonzero(divide):
            self._divide_marked(world, rs, todo, rows[:q_f], sizes[:nf], divide)
            self._adjusting(world, rs)
            self._merging(world, rs)
            return
        if len(act) and self._adjust_marked(world, subs, rows[q_f:], sizes[nf:], pending, settled, act):
            self._merging(world, rs)
            return
        if not K:
            return
        self._keep_sub_table((f.vid, rs, *s_members), bounds, sizes[nf:])
        for a, b in pairs.tolist():
            self._merge(world, rs, subs[a], subs[b])

    def _swap_crossed_targets(self, S, f, rows) -> bool:
        """Two members of one sub-formation that each wait to change into the
        lane the other is in exchange their targets (lane and slot).

        They have one movement, so each one's lane serves the other's
        target; after the exchange neither needs a lane change, where before
        both did, and side by side each blocked the other's (multi-vp, 4000
        veh/h, seed 0: two members 2.6 m apart in lanes 1 and 2, each
        assigned the other's lane at division, stood from the warm-up to the
        end of the run and 92 vehicles jammed behind them).  The division's
        assignment (Sec. 3.2's cost) is kept everywhere else. Returns
        whether two exchanged."""
        pend = flatnonzero((f.klane[rows] != f.tlane[rows]) & (f.lc_lane[rows] < 0))
        if len(pend) < 2:
            return False
        done = set()
        for ia, a in enumerate(pend):
            if a in done:
                continue
            for b in pend[ia + 1:]:
                ra, rb = rows[a], rows[b]
                if b in done or f.klane[ra] != f.tlane[rb] or f.klane[rb] != f.tlane[ra]:
                    continue
                f.tlane[ra], f.tlane[rb] = f.tlane[rb], f.tlane[ra]
                f.tidx[ra], f.tidx[rb] = f.tidx[rb], f.tidx[ra]
                done.update((a, b))
                self.stats["crossed_targets_swapped"] += 1
                break
        if done:
            S["members"] = [int(v) for v in f.vid[rows[np.argsort(f.tidx[rows], kind="stable")]]]
        return bool(done)

    def _sub_distances(self, f, rs) -> tuple[list, list, list, list]:
        """``(ids, sub-formations, least, largest distance to the centre of
        their members)``, in ``self.subs`` order (:meth:`_sub_table`)."""
        return self._sub_table(f, rs)[:4]

    def _sub_table(self, f, rs) -> tuple:
        """:meth:`_sub_distances` and the same bounds as a ``(2, K)`` array
        with the sub-formations' sizes (the merging's kernel takes them):
        one row lookup for all members, one reduction per bound (``min``/``max``
        of each one's ``rs.dist``, as a loop over them would give)."""
        sids, subs = list(self.subs), list(self.subs.values())
        if not subs:
            return [], [], [], [], np.zeros((2, 0)), np.zeros(0, dtype=np.int64)
        members = [S["members"] for S in subs]
        # the last answer, while the fleet's rows, the route state and the
        # member lists (replaced when members change, never changed in place)
        # are the same objects, in the same order (two calls a step, the
        # merging's and the coordinating zone's; what it returns is only read)
        key = (f.vid, rs, *members)
        c = self._sub_distances_kept
        if c is not None and same_objects(c[0], key):
            return (sids, subs, *c[1])
        rows, sizes = group_rows(f, members)
        if np.count_nonzero(sizes) < len(sizes):
            raise ValueError(f"sub-formation {sids[int(np.argmin(sizes))]} has no members")
        # (compiled: policies/_kernels.segment_bounds, from stop 41; the two
        # reduceat calls it replaced are its reference in tests/test_expert_kernels.py)
        bounds = segment_bounds(rows, sizes, rs.dist)
        return (sids, subs, *self._keep_sub_table(key, bounds, sizes))

    def _keep_sub_table(self, key: tuple, bounds: np.ndarray, sizes: np.ndarray) -> tuple:
        """Keep the sub-formations' distance bounds and sizes for ``key``
        (the fleet's rows, the route state and the member lists:
        :meth:`_sub_table`), read-only; returns ``(dmin, dmax, bounds, sizes)``."""
        dmin, dmax = bounds.tolist()
        for arr in (bounds, sizes):
            arr.setflags(write=False)
        self._sub_distances_kept = (key, (dmin, dmax, bounds, sizes))
        return dmin, dmax, bounds, sizes

    @staticmethod
    def _sub_columns(subs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The merging's columns of sub-formations ``subs``: legs,
        movements, and which are adjusted."""
        K = len(subs)
        return (np.fromiter([S["leg"] for S in subs], dtype=np.int64, count=K),
                np.fromiter([S["mv"] for S in subs], dtype=np.int64, count=K),
                np.fromiter([S["state"] == "adjusted" for S in subs], dtype=bool, count=K))

    def _merging(self, world, rs) -> None:
        p = self.p
        f = world.fleet
        lay = world.layout
        if not self.subs:
            return
        _, subs, _, _, bounds, sizes = self._sub_table(f, rs)
        # which sub-formation takes which, in order (compiled:
        # policies/_kernels.merge_pairs, from stop 42; the loop it replaced is
        # frozen in tests/test_expert_kernels.py), then the merges in that order
        # (a merge changes only the taker's members and state, which the
        # order's test reads as they were, the taker's size as it grows)
        leg, mv, adjusted = self._sub_columns(subs)
        pairs = merge_pairs(leg, mv, bounds[0], bounds[1], adjusted, sizes, lay.conflict, float(lay.R1),
                            float(p.merge_range), int(p.max_node_size))
        for a, b in pairs.tolist():
            self._merge(world, rs, subs[a], subs[b])

    def _merge(self, world, rs, A, B) -> None:
        p = self.p
        f = world.fleet
        ra = f.rows(A["members"])
        rb = f.rows(B["members"])
        na, nb = len(ra), len(rb)
        # A's targets are 0..na-1 (members that left may have left gaps)
        f.tidx[ra] = np.argsort(np.argsort(f.tidx[ra], kind="stable"), kind="stable")
        tx, tl = interlaced_targets(na + nb, len(A["lanes"]), p.gap_in)
        first = ra[np.argmin(f.tidx[ra])]
        vx = rs.u[first] - rs.u[rb]
        vl = f.klane[rb] - A["lanes"][0] + 1
        asg = assign_targets(vx, vl, tx[na:], tl[na:], p.w1, p.w2)
        f.tidx[rb] = na + asg
        f.tlane[rb] = np.asarray(A["lanes"])[tl[na + asg] - 1]
        f.sub[rb] = A["id"]
        f.form[rb] = f.form[first]
        A["members"] = A["members"] + [int(f.vid[r]) for r in rb[np.argsort(asg)]]
        del self.subs[B["id"]]
        self.stats["merges"] += 1
        self._set_sub_targets(world, A)
        need_lc = f.tlane[rb] != f.klane[rb]
        if need_lc.any():
            # the sub-formation is re-adjusted once they are in lane; until then
            # they keep the merged targets
            A["state"] = "lc"
            f.stage[rb[need_lc]] = ST_LC
