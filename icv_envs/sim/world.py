"""The simulation core: road layout + traffic arrays + formation layer.

:class:`World` advances all vehicles at once with array operations. It knows
nothing about Gymnasium or PettingZoo; the environments in
:mod:`icv_envs.envs` are thin layers over it.
"""

from __future__ import annotations

import numpy as np

from icv_envs._ufuncs import count_nonzero
from icv_envs.sim._kernels import kinematic_substep, lane_gap_pass, own_lane_gap_rows, quiet_substeps, road_check
from icv_envs.sim.formations import FormationManager
from icv_envs.sim.metrics import HEADWAY_BIN, STOPPED_SPEED, HeadwayStats, MotionStats
from icv_envs.sim.road import RoadLayout
from icv_envs.sim.traffic import LANE_INDEX_GHOST, LaneIndex, Traffic, find_collisions, lane_index, rect_overlap

__all__ = ["World", "StepEvents", "JAM_STOP_TIME", "JAM_FREE_GAP", "COLLISION_KINDS"]

#: Collision kinds by the at-fault vehicle (:meth:`World.classify_collisions`)
COLLISION_KINDS = ("struck_ahead", "struck_from_behind", "side_swipe", "road")
#: lateral speed [m/s] above which a vehicle counts as moving sideways (cut-in)
CUT_IN_SPEED = 0.2

#: A vehicle standing (below 0.1 m/s) longer than this [s] ...
JAM_STOP_TIME = 30.0
#: ... while the road ahead of it is free over at least this distance [m] is
#: jammed: nothing physical holds it. The distance is the IDM desired gap at
#: the top speed, s0 + v_max T = 2 + 30 * 1 m (Treiber et al. 2000): a vehicle
#: this far behind its leader (or the end of its lane) would accelerate.
JAM_FREE_GAP = 32.0
#: how far [m] a body centre may be beside its lane's outer half-width before it is off the road
EDGE_MARGIN = 0.5


class StepEvents:
    """What happened during one :meth:`World.advance` call (vehicle ids)."""

    __slots__ = ("crashed", "exited", "left_road", "collision_pairs")

    def __init__(self) -> None:
        self.crashed: set[int] = set()
        self.exited: set[int] = set()
        self.left_road: set[int] = set()
        self.collision_pairs: list[tuple[int, int]] = []


class World:
    def __init__(
        self,
        road: RoadLayout,
        manager: FormationManager,
        *,
        dt: float = 0.04,
        wheelbase: float = 2.8,
        v_max: float = 30.0,
        remove_crashed: bool = True,
    ) -> None:
        self.road = road
        self.manager = manager
        self.dt = float(dt)
        self.v_max = float(v_max)
        self.remove_crashed = remove_crashed
        self.traffic = Traffic(wheelbase, period=road.length if road.periodic else None)
        self.time = 0.0
        self._index = None
        self._gaps = None  # own_lane_gaps of the current state, with the index
        self._no_exit_rows = None  # (n, exit_id, ex_x, de) for a fleet without exits (substeps only reads them)
        self._exit_marks_kept = None  # (the exit column, the road, _exit_marks' answer)
        self._long_stops = None  # (stopped_for, how many exceed JAM_STOP_TIME): substeps' count for record_min_gap
        # run metrics (definitions in icv_envs.sim.metrics): event counts here,
        # speed/acceleration every substep in ``motion``, gaps and time
        # headways every policy step in ``headways``
        self.stats = {
            "collisions": 0,
            "exited": 0,
            "left_road": 0,
            "missed_exits": 0,
            "crashed_removed": 0,
            "jammed": 0,
            "collisions_by_fault": {k: {"expert": 0, "policy": 0} for k in COLLISION_KINDS},
        }
        self.motion = MotionStats()
        self.headways = HeadwayStats()
        # ids of vehicles driven by the expert this step (set by the env,
        # :meth:`set_expert_driven`); None: all expert-driven
        self._expert_vids: set[int] | None = None
        self._plan_vids: set[int] | None = None  # None: every vehicle carries its plan
        self._jammed: set[int] = set()

    # ---------------------------------------------------------------- queries
    def lane_index(self, reserved: bool = True):
        """Lane-sorted index of the current state (cached until the next
        step). With ``reserved`` (the controllers' view) a vehicle changing
        lanes is also listed in its target lane; without, only where its body
        is (the view used for gaps in metrics and rewards)."""
        if self._index is None:
            self._build_index(self._held_lanes())
        return self._index[0 if reserved else 1]

    def _build_index(self, res) -> None:
        """Both views of :meth:`lane_index` for the current state, given the
        reservations ``res`` (:meth:`_held_lanes`): one index when nobody
        holds a reservation (the two views are the same; nobody carrying
        out a plan: none to look for), else the two in one call (a step that
        asks for one view asks for the other: the gaps and the controllers).
        The gaps of the state before are dropped."""
        self._gaps = None
        cx, cy = self.traffic.center()
        args = (cx, cy, self.traffic.width, self.road.lane_width, self.road.total_lanes, self.road.length)
        if res is not None:
            body, held = lane_index(*args, periodic=self.road.periodic, reserved_lane=res,
                                    length=self.traffic.length, heading=self.traffic.heading, pair=True)
            self._index = [held, body]
        else:
            one = lane_index(*args, periodic=self.road.periodic, length=self.traffic.length,
                             heading=self.traffic.heading)
            self._index = [one, one]

    def _held_lanes(self):
        """The reservations of :meth:`_reservations` when some vehicle holds
        one, else None (the two views of :meth:`lane_index` are then one)."""
        res = None if self._plan_vids is not None and not self._plan_vids else self._reservations()
        return res if res is not None and count_nonzero(res >= 0) else None

    def _reservations(self) -> np.ndarray:
        """Lane-change target lanes that hold a reservation: only those of
        vehicles that carry out the plan (:meth:`set_expert_driven`).  The
        expert plans for every vehicle (its labels need it), but a vehicle a
        learned policy drives does not follow that plan; listing it in the
        plan's lane was a phantom reservation the others yielded to (issue 9:
        6.7% of the non-expert vehicle-steps on lane-drop with half the
        agents off the expert)."""
        tr = self.traffic
        if self._plan_vids is None:
            return tr.lc_lane
        if not self._plan_vids:  # nobody carries out the plan (every vehicle learned-driven)
            return np.full(tr.n, -1, dtype=np.int64)
        keep = np.fromiter((v in self._plan_vids for v in tr.vid.tolist()), dtype=bool, count=tr.n)
        return np.where(keep, tr.lc_lane, -1)

    def invalidate(self) -> None:
        self._index = None

    def own_lane_gaps(self) -> tuple[np.ndarray, np.ndarray]:
        """Bumper-to-bumper gap to the leader in each vehicle's own lane, and
        that leader's row (-1 and ``inf`` when none)."""
        gap, lead = self._own_lane_gaps_kept()
        return gap.copy(), lead.copy()

    def _own_lane_gaps_kept(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`own_lane_gaps` as kept for the current state (the step's
        readers that only read them: the headway statistics, the rewards)."""
        index = self.lane_index(reserved=False)  # (re)sets self._gaps when the state changed
        if self._gaps is None:
            tr = self.traffic
            cx, cy = tr.center()
            # the own lane (road.lane_of), its leader (traffic.leaders) and
            # the gap in one compiled pass (same arithmetic, tests/test_kernels.py)
            self._gaps = own_lane_gap_rows(index.keys, index.rows, index.lanes, index.x, float(index.offset), cx, cy,
                                           np.asarray(tr.length, dtype=np.float64), float(self.road.lane_width),
                                           int(self.road.total_lanes))
        return self._gaps

    # ---------------------------------------------------------------- dynamics
    def substep(self, accel: np.ndarray, steer: np.ndarray, events: StepEvents) -> None:
        """One integration step of ``dt`` for all vehicles, then collision
        detection (sweep and prune, see :func:`find_collisions`), exits and
        road ends."""
        tr = self.traffic
        road = self.road
        if tr.n and road.n_exits:
            cx_before = tr.center()[0]
        self.time += self.dt
        self._index = None
        if not tr.n:
            return
        # the integration, the standing time, the body centres and the road
        # check of every vehicle in one compiled pass
        # (icv_envs.sim._kernels.kinematic_substep / road_check: the same
        # IEEE operations in the same order as the numpy expressions they
        # replaced, see tests/test_trajectory_hash.py)
        v_before = tr.speed
        lat = -1.0 if tr.lat_accel_max is None else tr.lat_accel_max
        (tr.x, tr.y, tr.heading, tr.speed, tr.accel, tr.steer, tr.stopped_for, cx, cy) = kinematic_substep(
            tr.x, tr.y, tr.heading, tr.speed, np.asarray(accel, dtype=np.float64),
            np.asarray(steer, dtype=np.float64), tr.crashed, tr.stopped_for, tr.wheelbase, lat, self.dt,
            self.v_max, -1.0 if tr.period is None else tr.period)
        cx, cy = tr.set_center(cx, cy)
        self.motion.record(tr.vid, v_before, tr.speed, tr.accel, self.dt)
        i, j = find_collisions(cx, cy, tr.heading, tr.length, tr.width,
                               period=road.length if road.periodic else None)
        # leaving the drivable surface: a main-road vehicle whose lane has
        # ended, or a ramp vehicle past the ramp's end, has crashed; so has
        # one beyond the outer edge of the outermost lane (a learned policy
        # can steer off); one past the end of a straight road has left it
        lane, off, at_end, n_off, n_end = road_check(
            cx, cy, road.lane_width, road.n_lanes, road.total_lanes, road.lane_ends, road._ob_lane, road._ob_lo,
            road._ob_hi, road._ramp_iv, EDGE_MARGIN, np.inf if road.periodic else road.length)
        self._substep_events(events, cx, cy, cx_before if road.n_exits else None, i, j, lane, off, at_end, n_off,
                             n_end)

    def substeps(self, accel: np.ndarray, steer: np.ndarray, n: int, events: StepEvents) -> int:
        """Up to ``n`` calls of :meth:`substep` with the same controls, the
        quiet ones in one compiled pass (:func:`icv_envs.sim._kernels.quiet_substeps`),
        stopping after the first substep with a collision, a vehicle at the
        road's end, or an exit (handled here as :meth:`substep` does).
        Returns how many substeps ran; the state, statistics and events are
        those of as many :meth:`substep` calls, bit for bit. Roads with
        obstacles take :meth:`substep` one at a time. (From stop 52 a single
        frame is compiled too: the frame left after an event at the policy
        step's last but one, which a noisy policy's crashes make common, took
        :meth:`substep`'s Python path before, about four times the cost. From
        stop 53 a vehicle leaving the road, a noisy policy's most common
        event, is crashed inside the frames when nothing else happens in its
        frame, and its counts are added here (:meth:`_road_crashes`); a
        crashed vehicle off the road is no event: until then every frame
        after it went back to Python.)"""
        tr = self.traffic
        road = self.road
        if n < 1 or not tr.n or road.obstacles:
            self.substep(accel, steer, events)
            return 1
        nv = tr.n
        cx0 = tr.center()[0]
        self.motion.reserve(int(tr.vid[-1]) + 1)  # (rows sorted by id)
        marks = self._exit_marks()
        if marks is None:
            exit_id, ex_x, de = self._no_exits(nv)
        else:
            exit_id, (ex_x, de) = tr.exit, marks
        lat = -1.0 if tr.lat_accel_max is None else tr.lat_accel_max
        m = self.motion
        # (the clock and the run statistics advance inside, substep by
        # substep as substep() adds them: the same additions of the same doubles)
        (k, event, S, self.time, *totals, missed, E, m_pairs, n_off, n_end, n_long, n_road) = quiet_substeps(
            int(n), tr.x, tr.y, tr.heading, tr.speed, np.asarray(accel, dtype=np.float64),
            np.asarray(steer, dtype=np.float64), tr.crashed, tr.stopped_for, tr.wheelbase, lat, self.dt, self.v_max,
            road.length if road.periodic else -1.0, tr.vid, tr.length, tr.width, STOPPED_SPEED, *m.moments(),
            road.lane_width, road.n_lanes, road.total_lanes, road.lane_ends, road._ob_lane, road._ob_lo, road._ob_hi,
            road._ramp_iv, EDGE_MARGIN, np.inf if road.periodic else road.length, exit_id, ex_x, de,
            road.ramp_lane, cx0, float(self.time), *m.totals(), JAM_STOP_TIME)
        m.set_totals(*totals)
        self.stats["missed_exits"] += int(missed)
        self._index = None
        # (the state as row views of one array, the events unpacked only when there are some)
        tr.x, tr.y, tr.heading, tr.speed, tr.accel, tr.steer, tr.stopped_for, cx, cy, cx_before, ch, sh = S
        cx, cy = tr.set_center(cx, cy)
        tr.keep_cos_sin(ch, sh)  # (the headings' cos and sin, libm's: the observations' and the expert's)
        self._long_stops = (tr.stopped_for, n_long)  # (the jam watch's count of this state, record_min_gap)
        if n_road:  # (vehicles the frames crashed off the road, in frames with nothing else to handle: E's tail)
            self._road_crashes(events, E[len(E) - n_road:])
        if event:
            q = 2 * m_pairs
            i, j, lane = E[:m_pairs], E[m_pairs:q], E[q:q + nv]
            off, at_end = E[q + nv:q + 2 * nv] != 0, E[q + 2 * nv:q + 3 * nv] != 0
            self._substep_events(events, cx, cy, cx_before if road.n_exits else None, i, j, lane, off, at_end,
                                 n_off, n_end)
        return int(k)

    def _no_exits(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(exit_id, ex_x, de)`` of ``n`` vehicles without an exit (-1, inf,
        inf), kept between calls for the same ``n``: the compiled substeps
        only read them."""
        c = self._no_exit_rows
        if c is None or c[0] != n:
            c = self._no_exit_rows = (n, np.full(n, -1, dtype=np.int64), np.full(n, np.inf), np.full(n, np.inf))
        return c[1], c[2], c[3]

    def _exit_marks(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Per vehicle, the position of its exit and the end of that exit's
        diverge segment (``inf`` for vehicles without an exit), or None when
        no vehicle has one (or the road has no exits)."""
        tr = self.traffic
        road = self.road
        if not road.n_exits:
            return None
        # (kept while the fleet's exit column is the same array: adding or
        # removing vehicles replaces it and nothing writes it in place, as
        # with the ids; the callers only read the answer. From stop 56: two
        # calls a policy step on the ring, the same answer between spawns)
        kept = self._exit_marks_kept
        ex = tr.exit
        if kept is not None and kept[0] is ex and kept[1] is road:
            return kept[2]
        has = ex >= 0
        if not np.count_nonzero(has):
            out = None
        else:
            ex_x = np.full(tr.n, np.inf)
            ex_x[has] = road.exit_position(ex[has])
            de = np.full(tr.n, np.inf)
            de[has] = road.diverge_end(ex[has])
            out = (ex_x, de)
        self._exit_marks_kept = (ex, road, out)
        return out

    def _substep_events(self, events: StepEvents, cx, cy, cx_before, i, j, lane, off, at_end, n_off: int,
                        n_end: int) -> None:
        """What one substep's new state means (after :meth:`substep`'s
        integration, collision pairs ``i, j`` and road check): obstacle
        hits, exits and missed exits, crashes (classified), vehicles that
        left at the road's end, and the removal of those that exited or
        left. ``cx_before``: the body centres before the substep (roads with
        exits), else None."""
        tr = self.traffic
        road = self.road
        st = self.stats
        hit = hit_obstacle = None
        if len(i) or road.obstacles:
            hit = np.zeros(tr.n, dtype=bool)
            hit_obstacle = np.zeros(tr.n, dtype=bool)
            if len(i):
                hit[i] = True
                hit[j] = True
                for a, b in zip(tr.vid[i], tr.vid[j]):
                    events.collision_pairs.append((int(a), int(b)))
            for ob in road.obstacles:
                near = np.flatnonzero(np.abs(cx - ob.x) < 0.5 * (ob.length + tr.length.max()) + 1.0)
                if len(near):
                    h = rect_overlap(
                        cx[near], cy[near], tr.heading[near], tr.length[near], tr.width[near],
                        ob.x, ob.lane * road.lane_width, 0.0, ob.length, ob.width,
                    )
                    hit[near[h]] = True
                    hit_obstacle[near[h]] = True
        exit_now = None
        marks = self._exit_marks()
        if marks is not None:
            ex_x, de = marks
            has = tr.exit >= 0
            past = road.wrap(cx - ex_x)
            exit_now = has & (lane == road.ramp_lane) & (past >= -1.0) & (past < 10.0)
            # a vehicle that drives past the end of its diverge segment on
            # the main road has missed its exit (on a ring it tries again
            # next time round)
            crossed = has & (lane < road.n_lanes) & (road.wrap(cx_before - de) < 0) & (road.wrap(cx - de) >= 0)
            st["missed_exits"] += int(crossed.sum())
            if exit_now.any():
                off &= ~exit_now
            else:
                exit_now = None
        if hit is not None or n_off:
            new_crash = ((off | hit) if hit is not None else off) & ~tr.crashed
            if new_crash.any():
                hit_obstacle = hit_obstacle if hit_obstacle is not None else np.zeros(tr.n, dtype=bool)
                self.classify_collisions(i, j, (off | hit_obstacle) & new_crash, new_crash, cx, cy)
                tr.crashed |= new_crash
                events.crashed.update(int(v) for v in tr.vid[new_crash])
                st["collisions"] += int(new_crash.sum())
        if exit_now is not None:
            events.exited.update(int(v) for v in tr.vid[exit_now])
            st["exited"] += int(exit_now.sum())
        if n_end:
            left = at_end if exit_now is None else at_end & ~exit_now
            events.left_road.update(int(v) for v in tr.vid[left])
            st["left_road"] += int(left.sum())
        if exit_now is not None or n_end:
            tr.remove(at_end if exit_now is None else exit_now | at_end)
            self._index = None

    def set_expert_driven(self, vids, expert_mask, plan_mask=None) -> None:
        """Tell the world which vehicles the expert drives in the coming
        step (the others follow a given, e.g. learned, action), for the
        at-fault attribution of :meth:`classify_collisions`, and which carry
        out the expert's lane-change plan (``expert_mask | plan_mask``; a
        residual policy on top of the expert does), for the reservations of
        :meth:`lane_index` (:meth:`_reservations`)."""
        vids = np.asarray(vids)
        em = np.asarray(expert_mask, dtype=bool)
        if em.shape != vids.shape:
            raise ValueError(f"expert_mask has shape {em.shape}; allowed: {vids.shape}, one entry per vehicle id")
        # None: every vehicle (the physics comes next and only removes vehicles, so ``vids`` covering the
        # traffic covers every vehicle :meth:`classify_collisions` meets); an empty set when none is
        # (a learned policy drives every vehicle: the batched worlds' usual step), without a selection
        # (np.count_nonzero(m) == m.size: m.all() without a ufunc reduction)
        covers = len(vids) == self.traffic.n
        n_em = np.count_nonzero(em)
        every = n_em == em.size and covers
        self._expert_vids = None if every else set(vids[em].tolist()) if n_em else set()
        if plan_mask is None or plan_mask is expert_mask:  # (the plan mask is the expert mask)
            pm, n_pm, every_plan = em, n_em, every
        else:
            pm = em | np.asarray(plan_mask, dtype=bool)
            n_pm = np.count_nonzero(pm)
            every_plan = n_pm == pm.size and covers
        self._plan_vids = None if every_plan else set(vids[pm].tolist()) if n_pm else set()
        self._index = None

    def set_policy_driven(self) -> None:
        """:meth:`set_expert_driven` with no vehicle expert-driven and none
        carrying the expert's plan (a learned policy drives every vehicle:
        the batched worlds' usual step), without the masks (stop 51)."""
        self._expert_vids = set()
        self._plan_vids = set()
        self._index = None

    def _road_crashes(self, events: StepEvents, rows: np.ndarray) -> None:
        """The counts of vehicles the compiled frames crashed off the road
        (:meth:`substeps`, rows ``rows``, already marked crashed there), as
        :meth:`_substep_events` counts a crash off the road: the collision
        count, the crashed ids, one ``road`` fault each
        (:meth:`classify_collisions`)."""
        tr = self.traffic
        self._count_road_faults(rows.tolist())
        events.crashed.update(tr.vid[rows].tolist())
        self.stats["collisions"] += len(rows)

    def _count_road_faults(self, rows: list) -> None:
        """One ``road`` fault in ``stats["collisions_by_fault"]`` per row, by
        who drove it (:meth:`_driver`)."""
        out = self.stats["collisions_by_fault"]["road"]
        for r in rows:
            out[self._driver(r)] += 1

    def _driver(self, row: int) -> str:
        """``"expert"`` or ``"policy"``: who drove the vehicle at ``row`` this
        step (:meth:`set_expert_driven`)."""
        ev = self._expert_vids
        return "expert" if ev is None or int(self.traffic.vid[row]) in ev else "policy"

    def classify_collisions(self, i, j, road_rows, new_crash, cx, cy) -> None:
        """Count this substep's new collisions in
        ``stats["collisions_by_fault"][kind][driver]``, one per colliding pair
        (at least one of the two newly crashed) and one per vehicle that left
        the road or hit an obstacle (``road``, at fault itself).

        A pair whose bodies overlap less along the road than across it is a
        rear-end contact: the rear vehicle is at fault (``struck_ahead``)
        unless the front one was moving sideways towards it faster than
        ``CUT_IN_SPEED`` (a cut-in: the front vehicle, ``struck_from_behind``,
        is at fault). Otherwise it is a ``side_swipe``, at fault the vehicle
        moving sideways towards the other faster. ``driver`` is ``expert``
        or ``policy`` by who drove the at-fault vehicle
        (:meth:`set_expert_driven`)."""
        tr = self.traffic
        out = self.stats["collisions_by_fault"]
        driver = self._driver
        self._count_road_faults(np.flatnonzero(road_rows).tolist())
        vy = tr.speed * np.sin(tr.heading)
        for a, b in zip(np.asarray(i).tolist(), np.asarray(j).tolist()):
            if not (new_crash[a] or new_crash[b]):
                continue
            dx = float(self.road.wrap(cx[b] - cx[a]))
            dy = float(cy[b] - cy[a])
            ox = 0.5 * (tr.length[a] + tr.length[b]) - abs(dx)
            oy = 0.5 * (tr.width[a] + tr.width[b]) - abs(dy)
            if ox < oy:  # rear-end
                rear, front = (a, b) if dx > 0 else (b, a)
                towards = np.sign(cy[rear] - cy[front]) * vy[front]
                if towards > CUT_IN_SPEED:
                    out["struck_from_behind"][driver(front)] += 1
                else:
                    out["struck_ahead"][driver(rear)] += 1
            else:
                sa = np.sign(dy) * vy[a]
                sb = -np.sign(dy) * vy[b]
                out["side_swipe"][driver(a if sa >= sb else b)] += 1

    def remove_crashed_vehicles(self) -> np.ndarray:
        tr = self.traffic
        ids = tr.vid[tr.crashed]
        if self.remove_crashed and len(ids):
            tr.remove(tr.crashed)
            self._index = None
            self.stats["crashed_removed"] += len(ids)
        return ids

    def record_min_gap(self) -> None:
        """Per policy step: the smallest own-lane gap, and jam detection:
        ``stats["jammed"]`` counts the vehicles that have at some time stood
        longer than :data:`JAM_STOP_TIME` with at least :data:`JAM_FREE_GAP`
        of free lane ahead (no leader, no lane end), each vehicle once.
        The gaps and time headways feed :class:`icv_envs.sim.metrics.HeadwayStats`."""
        tr = self.traffic
        if tr.n > 1:
            recorded = False
            if self._index is None and type(self.headways) is HeadwayStats:
                # nothing built for this state yet: the reservations asked
                # once (the index is built from them when somebody holds a lane)
                res = self._held_lanes()
                if res is None:
                    # nobody holds a lane: the index, the gaps and their record
                    # in one compiled call (neighbours.lane_gap_pass, from stop
                    # 43: the three calls below with the same arguments)
                    h = self.headways
                    cx, cy = tr.center()
                    road = self.road
                    keys, xs, I, offset, gap, lead, g_min, th_min, count = lane_gap_pass(
                        cx, cy, tr.width, tr.length, tr.heading, float(road.lane_width), int(road.total_lanes),
                        bool(road.periodic), float(road.length), LANE_INDEX_GHOST, tr.speed, h._hist, HEADWAY_BIN,
                        STOPPED_SPEED)
                    one = LaneIndex(keys, I[0], I[1], xs, offset)
                    self._index = [one, one]
                    self._gaps = (gap, lead)
                    h.add_record(g_min, th_min, count)
                    recorded = True
                else:
                    self._build_index(res)
            if not recorded:
                gap, _ = self._own_lane_gaps_kept()
                self.headways.record(gap, self.traffic.speed)
        if tr.n:
            ls = self._long_stops
            if ls is not None and ls[0] is tr.stopped_for and not ls[1]:
                long_stop = None  # (the compiled substeps that left this state counted none: most steps)
            else:
                long_stop = tr.stopped_for > JAM_STOP_TIME
            if long_stop is not None and count_nonzero(long_stop):
                rows = np.flatnonzero(long_stop)
                gap = self._own_lane_gaps_kept()[0][rows] if tr.n > 1 else np.full(len(rows), np.inf)
                cx, cy = tr.center()
                lane = self.road.lane_of(cy[rows])
                to_end = self.road.interval_end(lane, cx[rows]) - cx[rows] - 0.5 * tr.length[rows]
                free = (gap > JAM_FREE_GAP) & (to_end > JAM_FREE_GAP)
                if free.any():
                    self._jammed.update(int(v) for v in tr.vid[rows[free]])
                    self.stats["jammed"] = len(self._jammed)
