"""The virtual platoon in the coordinating zone (paper Sec. 4.2): nodes, tree, references.

A mixin of :class:`icv_envs.policies.platoon_expert.PlatoonExpert`; the
behaviour is documented in that module's docstring ("Coordinating zone").
The pure algorithms (tree depths, reference positions) are in
:mod:`icv_envs.platoon.tree`.
"""

from __future__ import annotations


import numpy as np

from icv_envs.formation.targets import formation_length, interlaced_targets
from icv_envs.policies._kernels import detach_candidates, nodes_cleared, vp_references, vp_tree, zone_orphans
from icv_envs.policies.platoon_common import (
    MODE_FOLLOW,
    MODE_FREE,
    MODE_TREE,
    ST_COORD,
    Corridors,
    group_rows,
    same_objects,
)
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
        # (compiled from stop 41: policies/_kernels.zone_orphans, nodes_cleared;
        # the array code they replaced is frozen in tests/test_expert_kernels.py)
        for r in zone_orphans(rs.dist, float(R1), f.node, f.sub, rs.phase, f.cleared, f.klane, f.tlane,
                              f.lc_lane).tolist():
            self._new_node(world, [int(f.vid[r])], int(f.mv[r]), n_lanes=1, length=0.0)
        if not single:
            self._detach_inverted(world, rs)
        if self.nodes:
            ids, rows, seg, sizes = self._member_rows(f)
            done = nodes_cleared(rows, sizes, f.cleared)
            for k in flatnonzero(done).tolist():
                r = rows[seg == k]
                f.node[r] = -1
                f.ref[r] = -1
                del self.nodes[ids[k]]

    def _member_rows(self, f):
        """Every node's member rows in one array, nodes in insertion order,
        each node's in member order: ``(node ids, rows, index into the ids of
        each row's node, node sizes)`` (one ``f.rows`` call instead of one per
        node). The arrays are read-only: the last answer is kept while the
        fleet's rows (``f.vid``, replaced by every spawn and removal) and the
        member lists, in that order, are the same objects (a node's list is
        replaced when its members change, never changed in place); three
        calls a step, most of them answered so. (Until stop 40 it also
        answered for a given order of the nodes; the tree now gives its
        order's live members itself, ``T["live"]``.)"""
        ids = list(self.nodes)
        members = [self.nodes[nid]["members"] for nid in ids]
        key = (f.vid, *members)
        c = self._member_rows_kept
        if c is not None and same_objects(c[0], key):
            return (ids, *c[1])
        rows, sizes = group_rows(f, members)
        seg = np.repeat(np.arange(len(ids)), sizes)
        for arr in (rows, seg, sizes):
            arr.setflags(write=False)
        self._member_rows_kept = (key, (rows, seg, sizes))
        return ids, rows, seg, sizes

    def _detach_inverted(self, world, rs) -> None:
        """A node member whose leader in its approach lane is a vehicle of
        another group (still before the box) would be ordered before it but
        cannot pass it: that member and every member of its node further
        from the centre leave the node and form a node of their own (ordered
        after the foreign vehicle)."""
        f = world.fleet
        if not self.nodes:
            return
        # the test compiled (policies/_kernels.detach_candidates, from stop
        # 41; the array code it replaced is frozen in tests/test_expert_kernels.py):
        # the members' leaders in their approach corridors, foreign and
        # approaching, between the node's first vehicle and the member
        cor = Corridors.plain(world, rs)
        ids, mr, seg, _ = self._member_rows(f)
        rows, bad = detach_candidates(f.node, rs.phase, f.leg, rs.lane, rs.s, rs.dist, cor.keys, cor.corr, cor.rows,
                                      cor.coord, float(cor.BIG), mr, seg,
                                      np.fromiter(ids, dtype=np.int64, count=len(ids)))
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
        """Per-vehicle longitudinal mode and references for :meth:`compute`,
        in this order, all but the tree (:meth:`tree`) and the lane-change
        yields (:meth:`Regrouping._apply_yields`) in one compiled call
        (:func:`~icv_envs.policies._kernels.vp_references`, from stop 41;
        the array code of each part is frozen in
        ``tests/test_expert_kernels.py``).

        **Formation following** (approach and adjusting zones, and followers of nodes before
        ``R1``). A safety net: two vehicles referring to each other (must not happen): the
        nearer one drops its reference.  A follower ahead of the vehicle it follows, in that
        vehicle's own lane, is that vehicle's leader on the road: holding its slot (ahead of
        the reference, in another lane) makes each wait for the other once the lane change
        to the slot is blocked, a circular wait (multi-vp, 3500 veh/h, seed 0: a member
        stood 1 m ahead of its sub-formation's first vehicle in lane 2, waiting for a gap in
        lane 1, for 150 s). Such a follower drives free until the lane change separates the
        two.  The same holds in the lane that vehicle waits to change into: it is listed
        there too (its turn signal), brakes behind the follower alongside or ahead of it,
        and the follower stood waiting to drop back to its slot behind it (multi-vp, 3000
        veh/h, seed 23: from 450 s to the end of the run, 39 vehicles jammed behind the
        two).

        **The tree's references** (the nodes' live members). A node's first vehicle never
        chases a reference ahead of it: it then drives at v0 (the virtual platoon only holds
        vehicles back); followers track their slot relative to the first vehicle's slot,
        which is not slot 0 once the members ahead of it have left the road (with the
        absolute slot, multi-vp, 3000 veh/h, seed 2: a member with x_g = 72 m following the
        node's new first vehicle 9-11 m behind got a reference 30-50 m behind it, braked to
        a stop in the box and held the whole virtual platoon: 9 jammed at R1).  The hard
        spacing to an earlier conflicting node is already lost (a node that entered late,
        close to the box): the virtual lane cannot restore it, so the vehicle stops before
        the box until that node's rear has moved D_safe ahead of it (hold).

        **The speed advisory inside R1** (``_advise_in_zone`` until stop 40), too: a node vehicle whose
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
        zone's advisory (the anticipation's, below) with ``L`` its distance to the
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
        switches it off.

        **Anticipation in the adjusting zone** (``_anticipate`` until stop 40): track the
        virtual platoon's reference from ``R2`` on (our addition;
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

        **The virtual lane's cap** (``_virtual_cap`` until stop 40): a safe-speed cap in the
        virtual lane (Gipps): every not yet cleared
        vehicle of node ``k`` keeps ``X_v - X_rear,i >= D_safe`` to the rearmost
        vehicle of every earlier node ``i`` it conflicts with, even if that
        vehicle brakes at ``|a_min|`` from now on and this one reacts
        ``cap_tau`` later::

            v_safe = -b tau + sqrt((b tau)^2 + v_i^2 + 2 b (X_v - X_rear,i - D_safe))
            a_cap = (v_safe - v) / tau

        In steady state at ``v0`` it keeps ``D_safe + v0 tau`` (21 m with the
        defaults, = the default ``D_t``).  ``inf`` for vehicles outside the
        virtual platoon.

        **Stop flags.** May a vehicle enter the box? Only from an allowed lane, lane change
        finished; in the coordinating zone only coordinated vehicles (a node / a
        reservation); not while held or advised (the hold lasts: it waits at the stop line
        at most); a vehicle already at the line goes on.
        """
        p = self.p
        f = world.fleet
        lay = world.layout
        i64 = np.int64
        fk = flatnonzero((f.ref >= 0) & (f.node < 0))
        if len(fk):
            fk_rows, sig = f.rows(f.ref[fk]), self._signals(f)
        else:
            fk_rows = sig = fk
        self.node_depth = {}
        self.node_order = []
        self._tree = T = None
        e_i, e_f = np.zeros(0, dtype=i64), np.zeros(0)
        rows_all = kk = t_ids = e_i
        if self.nodes:
            ids, depths, T = self.tree(world, rs)
            self.node_order = ids
            self.node_depth = dict(zip(ids, depths[1:].tolist()))
            rows_all, kk = T["live"]  # (the members not yet cleared, in the tree's order)
            t_ids = np.fromiter(ids, dtype=i64, count=len(ids))
            self._tree = T
        self._tree_rows = (rows_all, kk)
        t = T if T is not None else {"first": e_i, "refs": e_f, "lb": e_f, "pred": e_i, "rear_row": e_i, "rear": e_f,
                                     "U": np.zeros((0, 0), dtype=bool), "mvs": e_i, "depths": e_i, "lens": e_f}
        b = abs(p.a_min)
        tau = p.cap_tau
        mode, Fr, Bo, counts, zone, Z, adv, A, ant, AR, bound = vp_references(
            fk, fk_rows, f.ref, f.vid, rs.dist, f.klane, sig, rs.phase, rs.u, f.xg, f.speed, rs.X, f.length, f.mv,
            f.leg, f.node, f.cleared, T is not None, rows_all, kk, t["first"], t["refs"], t["lb"], t["pred"],
            t["rear_row"], t["rear"], t["U"], t_ids, t["mvs"], t["depths"], t["lens"], lay.conflict, lay.leg_of,
            lay.allowed, f.lc_lane, f.tlane, np.asarray(self._coordinated(f), dtype=bool), float(p.v0),
            float(p.D_t - p.D_safe), float(p.D_t), float(2.0 * abs(p.comfort[0])), float(p.stop_margin),
            float(QUEUE_GAP), bool(p.zone_advisory), bool(p.anticipate), float(lay.R1), float(lay.R2),
            float(p.advisory_speed_floor), float(p.D_safe), float(b), float(tau), float((b * tau) ** 2), MODE_FREE,
            MODE_FOLLOW, MODE_TREE)
        st = self.stats
        n_cyc, n_ahead, held = counts.tolist()
        if len(fk):
            st["ref_cycles_broken"] += n_cyc
            st["ahead_of_reference"] += n_ahead
        # rows, advised speed, hold H, the tree's speed reference: tests, and the
        # observation, which keeps reporting the tree's reference (PlatoonExpert.references)
        self._zone_advised = (zone, Z[0], Z[1], Z[2])
        st["advised_in_zone"] += len(zone)
        if p.anticipate:
            # for inspection (tests, plots): the advised rows, speed and hold; the
            # holding rows, reference and bounding node id (-1: the layer reference binds)
            self._advised = (adv, A[0], A[1])
            self._anticipation = (ant, AR, bound)
            st["advised"] += len(adv)
            st["anticipating"] += len(ant)
        self._mode, self._xref, self._vref, self._tight = mode, Fr[0], Fr[1], Bo[0]
        self._apply_yields(world, rs)
        self._vcap = Fr[2]
        self._stop = Bo[1]
        st["held_at_line"] += held
