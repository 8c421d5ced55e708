"""The virtual platoon in the coordinating zone (paper Sec. 4.2): nodes, tree, references.

A mixin of :class:`icv_envs.policies.platoon_expert.PlatoonExpert`; the
behaviour is documented in that module's docstring ("Coordinating zone").
The pure algorithms (tree depths, reference positions) are in
:mod:`icv_envs.platoon.tree`.
"""

from __future__ import annotations

import itertools

import numpy as np

from icv_envs.formation.targets import formation_length, interlaced_targets
from icv_envs.policies._kernels import (
    anticipated_references,
    follow_references,
    stop_flags,
    tree_references,
    virtual_caps,
    vp_tree,
)
from icv_envs.policies.platoon_common import MODE_FOLLOW, MODE_FREE, MODE_TREE, ST_COORD, Corridors, same_objects
from icv_envs.sim.intersection_metrics import QUEUE_GAP
from icv_envs._ufuncs import flatnonzero

__all__ = ["VirtualPlatoon"]


class VirtualPlatoon:
    """Nodes enter and leave, the tree and its references, the virtual-lane cap (Sec. 4.2)."""

    # ------------------------------------------------------- coordinating zone
    def _settled(self, world, rs, rows) -> np.ndarray:
        """May these vehicles join the virtual platoon now?  In their expected
        lane, no lane change in progress, and at most ``settle_tolerance``
        behind the slot they track (their formation reference, when they have
        one).  Only settled vehicles hold a node's bound over later nodes: a
        member still changing lanes, or a slot behind, cannot be relied on to
        move up, and the later nodes it would hold could block its way (the
        circular wait of issue 8)."""
        f = world.fleet
        ok = (f.klane[rows] == f.tlane[rows]) & (f.lc_lane[rows] < 0) & (rs.phase[rows] == 0)
        ok |= rs.phase[rows] > 0
        err = self._slot_error(world, rs, rows)
        return ok & (-err <= self.p.settle_tolerance)

    def _coordinate(self, world, rs) -> None:
        """Nodes enter the virtual platoon; nodes that cleared the box leave.

        ``multi-vp``: when a sub-formation's first vehicle crosses ``R1`` its
        members get the in-zone targets, and the longest prefix of them (in
        target order) that is settled (:meth:`_settled`) becomes a node; the
        rest stays a sub-formation, with the next member as its first, and is
        handled the same way at every later step until all are in nodes.
        ``single-vp``: a vehicle becomes a node once inside ``R1`` and settled.
        """
        f = world.fleet
        lay = world.layout
        R1 = lay.R1
        single = self.method == "single-vp"
        if single:
            for sid, S in list(self.subs.items()):
                rows = f.rows(S["members"])
                # a member whose node already left (it cleared the box) is
                # done: it must not become a node again (a phantom node would
                # be re-inserted into the order at every step and, through the
                # yield rule of _insert_node, reshuffle the nodes still waiting)
                done = f.cleared[rows] | (rs.phase[rows] == 2)
                cand = rows[(rs.dist[rows] <= R1) & (f.node[rows] < 0) & ~done]
                # one vehicle per node: no slot to keep, only the lane
                new = cand[((f.klane[cand] == f.tlane[cand]) & (f.lc_lane[cand] < 0)) | (rs.phase[cand] > 0)]
                for r in new:
                    self._new_node(world, [int(f.vid[r])], int(f.mv[r]), n_lanes=1, length=0.0)
                if np.all((f.node[rows] >= 0) | done):
                    del self.subs[sid]
        else:
            # the sub-formations whose first vehicle is inside R1 (nothing below
            # changes another one's members or the distances)
            sids, subs, dmin, _ = self._sub_distances(f, rs)
            for sid, S in [(sid, S) for sid, S, d in zip(sids, subs, dmin) if d <= R1]:
                n_l = len(S["lanes"])
                self._set_sub_targets(world, S)
                rows = f.rows(S["members"])  # target order
                rows = rows[np.argsort(f.tidx[rows], kind="stable")]
                ok = self._settled(world, rs, rows)
                k = int(np.argmin(ok)) if not ok.all() else len(rows)
                if k == 0:
                    continue
                members = [int(v) for v in f.vid[rows[:k]]]
                rest = [int(v) for v in f.vid[rows[k:]]]
                self._new_node(world, members, S["mv"], n_lanes=n_l,
                               length=formation_length(k, n_l, self.p.gap_in))
                f.sub[rows[:k]] = -1
                if rest:
                    S["members"] = rest
                    self._set_sub_targets(world, S)
                    self.stats["held_out_of_node"] += len(rest)
                else:
                    del self.subs[sid]
        # vehicles in the zone without a sub-formation (not expected, but safe)
        orphan = flatnonzero((rs.dist <= R1) & (f.node < 0) & (f.sub < 0) & (rs.phase < 2) & ~f.cleared)
        if len(orphan):
            orphan = orphan[(f.klane[orphan] == f.tlane[orphan]) & (f.lc_lane[orphan] < 0) | (rs.phase[orphan] > 0)]
        for r in orphan:
            self._new_node(world, [int(f.vid[r])], int(f.mv[r]), n_lanes=1, length=0.0)
        if not single:
            self._detach_inverted(world, rs)
        if self.nodes:
            ids, rows, seg, sizes = self._member_rows(f)
            done = np.bincount(seg, weights=~f.cleared[rows], minlength=len(ids)) == 0
            for k in flatnonzero(done).tolist():
                r = rows[seg == k]
                f.node[r] = -1
                f.ref[r] = -1
                del self.nodes[ids[k]]

    def _member_rows(self, f, ids=None):
        """Every node's member rows in one array, each node's in member order:
        ``(node ids, rows, index into the ids of each row's node, node sizes)``
        (one ``f.rows`` call instead of one per node); nodes ``ids`` in that
        order (default: all, in insertion order). The arrays are read-only:
        the last answer for each of the two orders asked for (insertion order,
        a given order) is kept while the fleet's rows (``f.vid``, replaced by
        every spawn and removal) and the member lists, in that order, are the
        same objects (a node's list is replaced when its members change, never
        changed in place); four calls a step, most of them answered so."""
        slot = 0 if ids is None else 1
        ids = list(self.nodes) if ids is None else ids
        members = [self.nodes[nid]["members"] for nid in ids]
        key = (f.vid, *members)
        c = self._member_rows_kept[slot]
        if c is not None and same_objects(c[0], key):
            return (ids, *c[1])
        sizes = np.fromiter(map(len, members), dtype=np.int64, count=len(ids))
        seg = np.repeat(np.arange(len(ids)), sizes)
        rows = f.rows(np.fromiter(itertools.chain.from_iterable(members), dtype=np.int64, count=int(sizes.sum())))
        for arr in (rows, seg, sizes):
            arr.setflags(write=False)
        self._member_rows_kept[slot] = (key, (rows, seg, sizes))
        return ids, rows, seg, sizes

    def _detach_inverted(self, world, rs) -> None:
        """A node member whose leader in its approach lane is a vehicle of
        another group (still before the box) would be ordered before it but
        cannot pass it: that member and every member of its node further
        from the centre leave the node and form a node of their own (ordered
        after the foreign vehicle)."""
        f = world.fleet
        rows = flatnonzero((f.node >= 0) & (rs.phase == 0))
        if not len(rows):
            return
        cor = Corridors.plain(world, rs)
        lr, _, _, _ = cor.neighbours(rows, 3 * f.leg[rows] + rs.lane[rows], rs.s[rows])
        lr0 = np.maximum(lr, 0)
        bad = (lr >= 0) & (f.node[lr0] != f.node[rows]) & (rs.phase[lr0] == 0)
        if not np.count_nonzero(bad):
            return
        # only a foreign vehicle between the node's first vehicle and this member counts
        ids, mr, seg, _ = self._member_rows(f)
        dmin = np.full(len(ids), np.inf)
        np.minimum.at(dmin, seg, rs.dist[mr])
        first_d = dict(zip(ids, dmin.tolist()))
        fd = np.array([first_d.get(int(nd), np.inf) for nd in f.node[rows]])
        bad &= (rs.dist[lr0] > fd + 1e-9) & (rs.dist[rows] > fd + 1e-9)
        if not np.count_nonzero(bad):
            return
        for nid in sorted(set(f.node[rows[bad]].tolist())):
            N = self.nodes.get(nid)
            if N is None:
                continue
            mrows = f.rows(N["members"])
            cut = float(rs.dist[rows[bad & (f.node[rows] == nid)]].min())
            first = mrows[np.argmin(rs.dist[mrows])]
            out = mrows[(rs.dist[mrows] >= cut) & (mrows != first)]
            if not len(out):
                continue
            keep = [int(v) for v in f.vid[mrows] if v not in set(f.vid[out].tolist())]
            N["members"] = keep
            N["length"] = formation_length(len(keep), N["n_lanes"], self.p.gap_in)
            n_out = len(out)
            out = out[np.argsort(rs.dist[out])]
            tx, _ = interlaced_targets(n_out, N["n_lanes"], self.p.gap_in)
            f.ref[out] = f.vid[out[0]]
            f.xg[out] = tx
            f.ref[out[0]] = -1
            self._new_node(world, [int(v) for v in f.vid[out]], N["mv"], N["n_lanes"],
                           formation_length(n_out, N["n_lanes"], self.p.gap_in))
            self.stats["detached"] += n_out

    def _new_node(self, world, members, mv, n_lanes, length) -> None:
        f = world.fleet
        nid = self._new_id()
        rows = f.rows(members)
        self.nodes[nid] = {"id": nid, "mv": int(mv), "members": list(members), "n_lanes": n_lanes,
                           "length": float(length)}
        self._insert_node(world, nid, rows)
        f.node[rows] = nid
        f.stage[rows] = ST_COORD
        if len(rows) == 1:
            f.ref[rows] = -1
            f.xg[rows] = 0.0
        self.stats["nodes"] += 1

    def _insert_node(self, world, nid, rows) -> None:
        """Place a new node in the virtual platoon's order (``self.vp_order``).

        The paper orders nodes by the distance of their first vehicle to the
        centre when they enter at ``R1``; with every node entering there,
        that is the entry order.  A node that enters later (members held out
        until they settled, detached members) would, placed by distance,
        impose its bound ``rear + D_t`` on conflicting nodes that are already
        closer to the box than that bound and cannot stop behind it at the
        comfortable deceleration (they may be in the box).  So (our rule):
        the node goes to its distance rank, then behind every later
        conflicting node of ANOTHER leg whose first vehicle cannot stop
        comfortably (``comfort[0]``) before ``X_rear + D_t``; nodes of its
        own leg that it passes this way and that are physically behind it
        (further from the centre) move along right behind it, so no node is
        ever ordered before a node it physically follows in its own leg.  A
        node with a vehicle already in the box is never moved back."""
        f = world.fleet
        rs = world.route()
        lay = world.layout
        N = self.nodes[nid]
        order = [k for k in self.vp_order if k in self.nodes and k != nid]
        d_new = float(rs.dist[rows].min())
        xr_new = float(rs.X[rows].max())
        leg = int(lay.leg_of[N["mv"]])
        info = {}
        for k in order:
            r = f.rows(self.nodes[k]["members"])
            r = r[r >= 0]
            i0 = r[np.argmin(rs.dist[r])]
            info[k] = (float(rs.dist[i0]), float(rs.X[i0]), float(f.speed[i0]), np.count_nonzero(rs.phase[r] > 0) > 0)
        pos = next((i for i, k in enumerate(order) if info[k][0] > d_new), len(order))
        b = abs(self.p.comfort[0])
        j = pos
        while j < len(order):
            k = order[j]
            K = self.nodes[k]
            if lay.conflict[N["mv"], K["mv"]] and int(lay.leg_of[K["mv"]]) != leg:
                d_k, x_k, v_k, _ = info[k]
                if x_k - v_k * v_k / (2.0 * b) < xr_new + self.p.D_t:
                    # N goes behind k; same-leg nodes physically behind N that it passes come along
                    mid = order[pos:j]
                    # (a node with a vehicle already in the box keeps its place)
                    follow = [m for m in mid if int(lay.leg_of[self.nodes[m]["mv"]]) == leg and info[m][0] > d_new
                              and not info[m][3]]
                    rest = [m for m in mid if m not in follow]
                    order = order[:pos] + rest + [k] + follow + order[j + 1:]
                    pos = pos + len(rest) + 1
                    j = pos + len(follow)
                    self.stats["node_yielded"] += 1
                    continue
            j += 1
        order.insert(pos, nid)
        self.vp_order = order

    def tree(self, world, rs):
        """Current virtual platoon: ``(node ids in order, depths (with the leader at 0), references)``.

        Per node the first vehicle (least distance to the centre) and the
        rear one (largest ``X``), ties to the earlier member; the nodes in
        the virtual platoon's order (:meth:`_insert_node`), repaired so that
        no node comes before a node of its own leg that has a vehicle ahead
        of one of its vehicles in the same approach lane (that node would
        wait behind it for a reference it cannot reach, a circular wait: the
        pair test over (node, node, approach lane) of the nearest and the
        farthest member distance, the later node scanned first, the first
        such pair moving the later node to the earlier one's place,
        :func:`~icv_envs.policies._kernels.repair_order`); the paper's tree
        and references (Sec. 4.2: the conflict graph of the nodes'
        movements, the tree-layers, the layer references from the first
        vehicles' ``X`` made nondecreasing) and
        the bound ``D_t`` behind the rear of each node's earlier conflicting
        nodes. All of it in one compiled call
        (:func:`~icv_envs.policies._kernels.vp_tree`, from stop 41; before,
        ``node_heads``, a stable argsort of the ranks, ``repair_order`` and
        ``tree_layers`` one by one, each frozen in the tests). ``T["live"]``
        holds the members not yet cleared in this order, with the place of
        their node."""
        f = world.fleet
        p = self.p
        nodes = self.nodes
        ids = list(nodes)
        if not ids:
            return [], np.zeros(1, dtype=np.int64), None
        K = len(ids)
        _, rows, seg, sizes = self._member_rows(f)
        i64 = np.int64
        mvs = np.fromiter([nodes[nid]["mv"] for nid in ids], dtype=i64, count=K)
        lens = np.fromiter([nodes[nid]["length"] for nid in ids], dtype=np.float64, count=K)
        moves, I, F, depths, refs, U, live_rows, live_node = vp_tree(
            rows, seg, sizes, np.fromiter(ids, dtype=i64, count=K),
            np.fromiter(self.vp_order, dtype=i64, count=len(self.vp_order)), mvs, lens, rs.X, rs.dist,
            rs.phase.astype(i64, copy=False), rs.lane.astype(i64, copy=False), f.cleared, world.layout.leg_of,
            world.layout.conflict, float(p.D_t))
        if moves:
            self.stats["order_repaired"] = self.stats.get("order_repaired", 0) + moves
        ids = [ids[i] for i in I[0].tolist()]
        placed = set(ids)
        self.vp_order = ids + [k for k in self.vp_order if k not in placed]
        return ids, depths, {"xf": F[0], "rear": F[1], "first": I[1], "rear_row": I[2], "refs": refs, "lb": F[2],
                             "pred": I[3], "mvs": I[4], "U": U, "depths": depths[1:], "lens": F[3],
                             "live": (live_rows, live_node)}

    # -------------------------------------------------------------- references
    def _references(self, world, rs) -> None:
        """Per-vehicle longitudinal mode and references for :meth:`compute`."""
        p = self.p
        f = world.fleet
        lay = world.layout
        n = f.n
        mode = np.full(n, MODE_FREE, dtype=np.int64)
        xref = np.zeros(n)  # MODE_FOLLOW: u reference; MODE_TREE: X reference
        vref = np.full(n, p.v0)
        tight = np.zeros(n, dtype=bool)  # the safety bound binds: full braking allowed
        hold = np.zeros(n, dtype=bool)  # the bound is violated: stop before the box
        # formation following (approach / adjusting zones, and followers of nodes before R1)
        fol = (f.ref >= 0) & (f.node < 0)
        if np.count_nonzero(fol):
            k = flatnonzero(fol)
            # safety net: two vehicles referring to each other (must not
            # happen): the nearer one drops its reference.  A follower ahead
            # of the vehicle it follows, in that vehicle's own lane, is that
            # vehicle's leader on the road: holding its slot (ahead of the
            # reference, in another lane) makes each wait for the other once
            # the lane change to the slot is blocked, a circular wait
            # (multi-vp, 3500 veh/h, seed 0: a member stood 1 m ahead of its
            # sub-formation's first vehicle in lane 2, waiting for a gap in
            # lane 1, for 150 s). Such a follower drives free until the lane
            # change separates the two.  The same holds in the lane that
            # vehicle waits to change into: it is listed there too (its turn
            # signal), brakes behind the follower alongside or ahead of it,
            # and the follower stood waiting to drop back to its slot behind
            # it (multi-vp, 3000 veh/h, seed 23: from 450 s to the end of the
            # run, 39 vehicles jammed behind the two).  Compiled:
            # policies/_kernels.follow_references (the array code it replaced
            # is frozen in tests/test_expert_kernels.py)
            n_cyc, n_ahead = follow_references(k, f.rows(f.ref[k]), f.ref, f.vid, rs.dist, f.klane, self._signals(f),
                                               rs.phase, rs.u, f.xg, f.speed, MODE_FOLLOW, mode, xref, vref)
            self.stats["ref_cycles_broken"] += int(n_cyc)
            self.stats["ahead_of_reference"] += int(n_ahead)
        self.node_depth = {}
        self.node_order = []
        self._tree = None
        self._tree_rows = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
        if self.nodes:
            ids, depths, T = self.tree(world, rs)
            self.node_order = ids
            self.node_depth = dict(zip(ids, depths[1:].tolist()))
            rows_all, kk = T["live"]  # (the members not yet cleared, in the tree's order)
            self._tree, self._tree_rows = T, (rows_all, kk)
            # a node's first vehicle never chases a reference ahead of it: it
            # then drives at v0 (the virtual platoon only holds vehicles back)
            # followers: their slot relative to the first vehicle's slot, which is
            # not slot 0 once the members ahead of it have left the road (with
            # the absolute slot, multi-vp, 3000 veh/h, seed 2: a member with
            # x_g = 72 m following the node's new first vehicle 9-11 m behind
            # got a reference 30-50 m behind it, braked to a stop in the box
            # and held the whole virtual platoon: 9 jammed at R1).  The hard
            # spacing to an earlier conflicting node is already lost (a node
            # that entered late, close to the box): the virtual lane cannot
            # restore it, so the vehicle stops before the box until that
            # node's rear has moved D_safe ahead of it (hold).  Compiled:
            # policies/_kernels.tree_references
            tree_references(rows_all, kk, T["first"], T["refs"], T["lb"], T["pred"], T["rear_row"], rs.X, f.xg,
                            f.speed, float(p.v0), float(p.D_t - p.D_safe), MODE_TREE, mode, xref, vref, tight, hold)
        self._zone_advised = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(0))
        advised = self._advise_in_zone(world, rs, xref, vref, tight) if p.zone_advisory else self._zone_advised[0]
        if p.anticipate:
            self._anticipate(world, rs, mode, xref, vref)
        self._mode, self._xref, self._vref, self._tight = mode, xref, vref, tight
        self._apply_yields(world, rs)
        self._vcap = self._virtual_cap(world, rs)
        # may a vehicle enter the box? only from an allowed lane, lane change
        # finished; in the coordinating zone only coordinated vehicles (a node
        # / a reservation); not while held or advised (the hold lasts: it
        # waits at the stop line at most); a vehicle already at the line goes
        # on (compiled: policies/_kernels.stop_flags)
        self._stop, held = stop_flags(rs.phase, lay.allowed, f.mv, f.klane, f.lc_lane, f.tlane, rs.dist,
                                      float(lay.R1), np.asarray(self._coordinated(f), dtype=bool), hold,
                                      np.asarray(advised, dtype=np.int64), rs.u, f.length)
        self.stats["held_at_line"] += int(held)

    def _advise_in_zone(self, world, rs, xref, vref, tight) -> np.ndarray:
        """The speed advisory inside ``R1`` too: a node vehicle whose
        reference lies further behind it than comfortable braking absorbs
        meets it at the stop line instead of standing (our rule; the paper
        is silent).

        Tracking a reference ``H = X_ref - X > 0`` behind it (a deep
        tree-layer, or ``D_t`` behind the rear of an earlier conflicting node),
        a vehicle brakes and, when ``H`` exceeds what braking at
        ``comfort[0]`` absorbs before standing (``v^2 / 2|comfort[0]|``),
        stands until the reference arrives, typically right after ``R1``, 285
        m from the stop line (issue 8: the virtual platoon's only jams on the
        20-seed sweep, vehicles standing at ``R1`` for 10-20 s with the lanes
        behind them blocked).  Such a vehicle instead gets the adjusting
        zone's advisory (:meth:`_anticipate`) with ``L`` its distance to the
        stop line: ``v0 L / (L + H)``, at which it reaches the line when a
        reference moving at ``v0`` does, tracked with no position error and
        braking at most ``comfort[0]``; recomputed every step, so a reference
        that moves slower slows it further.  While advised it gets ``_stop``
        (it cannot enter the box while advised), so it waits at most at the
        stop line, in the queue there.  Only where standing would
        leave it away from the line: its comfortable braking distance ends
        more than :data:`~icv_envs.sim.intersection_metrics.QUEUE_GAP` (10 m,
        the jam watch's queue gap) before the stop line.  Closer, or with a
        hold that braking absorbs, it tracks its reference as before (a first
        version advised up to the line; vehicles then reached the line early
        and started from rest: multi-vp, 3000 veh/h, seed 3, mean delay 6.85
        -> 9.08 s).  It stays a node all the time, so later conflicting nodes
        keep their bound ``D_t`` behind its rear.
        ``PlatoonParams.zone_advisory`` (env config ``vp_zone_advisory``)
        switches it off.  Returns the advised rows."""
        p = self.p
        f = world.fleet
        rows, _ = self._tree_rows
        if not len(rows):
            return np.zeros(0, dtype=np.int64)
        H = xref[rows] - rs.X[rows]
        room = f.speed[rows] ** 2 / (2.0 * abs(p.comfort[0]))
        L = np.maximum(-rs.u[rows] - 0.5 * f.length[rows] - p.stop_margin, 0.0)
        w = (rs.phase[rows] == 0) & (H > room) & (L - room > QUEUE_GAP)
        k = rows[w]
        if not len(k):
            return k
        v_tree = vref[k].copy()
        vref[k] = p.v0 * L[w] / (L[w] + H[w])
        xref[k] = rs.X[k]
        tight[k] = False
        # rows, advised speed, hold H, the tree's speed reference: tests, and the
        # observation, which keeps reporting the tree's reference (PlatoonExpert.references)
        self._zone_advised = (k, vref[k].copy(), H[w], v_tree)
        self.stats["advised_in_zone"] += len(k)
        return k

    def _anticipate(self, world, rs, mode, xref, vref) -> None:
        """Track the virtual platoon's reference from ``R2`` on (our addition;
        the paper is silent).

        A node is made when its first vehicle crosses ``R1``; if its reference
        (its tree-layer's ``X_ref``, or ``D_t`` behind the rear of an earlier
        conflicting node) then lies behind it, it had to brake hard and stand
        at ``R1`` until the reference passed (issue 8: the virtual platoon's
        only jams on the 20-seed sweep).  Here every vehicle of the adjusting
        zone (``R2 >= X > R1``) that drives free (a sub-formation's first
        vehicle; followers track it) gets, already there, the reference it
        would get if its node were made now: appended behind the current
        nodes (every current node is inside ``R1``, hence closer), at depth
        ``1 + max`` depth of the nodes it conflicts with,
        ``X_ref = X_0 + m D_t + sum_{i<m} max len`` (:func:`reference_positions`),
        and never closer than ``D_t`` behind the rear of a conflicting node;
        only nodes ordered before the first node of its own leg with a
        vehicle behind it count (its node would be ordered before that one).
        When that reference is behind it, it tracks it with the same
        feedback law as inside ``R1`` but at most the comfortable
        deceleration (``comfort[0]``): the wait is spread over the 200 m of
        the adjusting zone instead of spent standing at ``R1``.  Only holds
        that such braking absorbs before standing (``X_ref - X <= v^2 /
        2|comfort[0]|``) are tracked so.  A larger hold ``H = X_ref - X``
        gets a speed advisory instead (the reference moves towards the box at
        about ``v0``; driving the rest ``L = dist - R1`` of the zone at
        ``v0 L / (L + H)`` meets it at ``R1``), never below
        ``advisory_speed_floor`` (default ``v0 / 2``: at most twice the time
        through the zone); the feedback law tracks the advised speed (no
        position error), braking at most ``comfort[0]``.  The floor keeps a
        vehicle whose reference keeps deepening (nodes of other legs enter
        ``R1`` first; tracking the full reference kept such a vehicle outside
        ``R1``: starvation) moving, so it reaches ``R1`` in bounded time and
        waits there what the zone did not absorb (before the advisory, the
        whole hold: multi-vp, 3000 veh/h, seed 3, 30 jammed vehicles, 153
        vehicle-seconds; with it, 13 and 54).  It never pulls a vehicle
        forward.  ``PlatoonParams.anticipate`` (env config
        ``vp_anticipation``) switches both off.
        """
        self._anticipation = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64))
        self._advised = (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))  # rows, advised speed, hold H
        T = self._tree
        if T is None:
            return
        f = world.fleet
        lay = world.layout
        p = self.p
        cand = flatnonzero((mode == MODE_FREE) & (rs.phase == 0) & (f.node < 0) & (rs.dist > lay.R1)
                              & (rs.dist <= lay.R2) & ~f.cleared)
        if not len(cand):
            return
        ids = self.node_order
        # its node would be ordered before the first node of its own leg that
        # has a vehicle behind it (the order's repair in tree()): only the nodes before that
        # one may bound it.  Bounded by that node, or by a later node that
        # waits for it, it would hold the vehicle behind it, which that node
        # waits for: a circular wait (multi-vp, 3000 veh/h, seed 1: 331
        # jammed with the own-leg node; 2500 veh/h, seed 13: 51 jammed with a
        # node of another leg bounded by it).  Its depth, layer reference, the
        # bound behind the conflicting nodes' rears and the hold, compiled
        # (policies/_kernels.anticipated_references; the array code it
        # replaced is frozen in tests/test_expert_kernels.py)
        ref, lb, pred, R, room, H = anticipated_references(
            cand, f.mv, f.leg, rs.dist, rs.X, f.speed, lay.conflict, lay.leg_of, T["mvs"], T["rear_row"], T["rear"],
            T["depths"], T["lens"], float(T["refs"][0]), float(p.D_t), float(2.0 * abs(p.comfort[0])))
        # only a hold that braking at the comfortable deceleration absorbs
        # before standing still: a larger one would hold the vehicle outside
        # R1 while nodes of other legs enter first and deepen its reference
        # (starvation: multi-vp, 3000 veh/h, seed 12, 19 jammed for 904 s);
        # it waits at R1 as the paper's zones are printed
        hold = (H > 0) & (H <= room)
        # a larger hold: a speed advisory instead of standing at R1.  The
        # reference moves towards the box at about v0, so driving the rest of
        # the adjusting zone (L = dist - R1) at v0 L / (L + H) meets it at R1;
        # never slower than advisory_speed_floor (default v0 / 2: at most twice
        # the time through the zone), so a vehicle whose reference keeps
        # deepening (nodes of other legs enter first) still reaches R1 in
        # bounded time and waits there the rest, as before
        slow = (H > room) & (p.advisory_speed_floor < p.v0)
        if not (np.count_nonzero(hold) or np.count_nonzero(slow)):
            return
        L = np.maximum(rs.dist[cand] - lay.R1, 0.0)
        v_adv = np.maximum(p.v0 * L / (L + np.maximum(H, 1e-9)), p.advisory_speed_floor)
        if np.count_nonzero(slow):
            ks = cand[slow]
            mode[ks] = MODE_TREE
            xref[ks] = rs.X[ks]  # no position error: the feedback law tracks the advised speed
            vref[ks] = v_adv[slow]
            self._advised = (ks, v_adv[slow], H[slow])
            self.stats["advised"] += len(ks)
        if not np.count_nonzero(hold):
            return
        k = cand[hold]
        mode[k] = MODE_TREE
        xref[k] = R[hold]
        vref[k] = np.where(lb[hold] >= ref[hold], f.speed[T["rear_row"][pred[hold]]], p.v0)
        # for inspection (tests, plots): rows, reference, bounding node id (-1: the layer reference binds)
        bound = np.where(lb[hold] >= ref[hold], np.asarray(ids, dtype=np.int64)[pred[hold]], -1)
        self._anticipation = (k, R[hold], bound)
        self.stats["anticipating"] += len(k)

    def _virtual_cap(self, world, rs) -> np.ndarray:
        """Safe-speed cap in the virtual lane (Gipps): every not yet cleared
        vehicle of node ``k`` keeps ``X_v - X_rear,i >= D_safe`` to the rearmost
        vehicle of every earlier node ``i`` it conflicts with, even if that
        vehicle brakes at ``|a_min|`` from now on and this one reacts
        ``cap_tau`` later::

            v_safe = -b tau + sqrt((b tau)^2 + v_i^2 + 2 b (X_v - X_rear,i - D_safe))
            a_cap = (v_safe - v) / tau

        In steady state at ``v0`` it keeps ``D_safe + v0 tau`` (21 m with the
        defaults, = the default ``D_t``).  ``inf`` for vehicles outside the
        virtual platoon."""
        p = self.p
        f = world.fleet
        cap = np.full(f.n, np.inf)
        T = self._tree
        if T is None:
            return cap
        rows_all, kk = self._tree_rows
        if not len(rows_all):
            return cap
        # (compiled: policies/_kernels.virtual_caps, the array code's
        # arithmetic per member and earlier conflicting node; frozen in
        # tests/test_expert_kernels.py)
        b = abs(p.a_min)
        tau = p.cap_tau
        return virtual_caps(f.n, rows_all, kk, T["U"], rs.X, T["rear"], T["rear_row"], f.speed, float(p.D_safe),
                            float(b), float(tau), float((b * tau) ** 2))
