"""The formation layer: which ICVs form which formation, where each
formation's front target is, and which target each member holds.

This is the coordination layer of the paper's Sec. 3 (target generation,
Sec. 3.2; position assignment, Sec. 3.3), run by the environment as the
V2X infrastructure would: it publishes each member's reference
``(X_ref, lane_ref, v_ref)``, which is part of every agent's observation
and of the formation-keeping reward. How a vehicle tracks its reference is
the policy's business (:class:`icv_envs.policies.FormationExpert` or a
learned one).

Decisions the paper leaves open (docs/decisions.md), each a config value:

* the front target (``anchor``) moves at the formation speed; it is held back
  so that it never leads the best-placed member's implied front by more than
  ``max_anchor_lead`` metres (a blocked formation does not run away from its
  members);
* the formation re-forms (new targets for the new count and lanes, then a
  new minimum-cost assignment) whenever a member leaves or joins, or the set
  of main lanes drivable over ``[rear - 10 m, front + lookahead]`` changes
  (lane drop, blocking obstacle, lane re-opening after an obstacle). Between
  events the assignment is kept (re-assigning every step would make vehicles
  chase one another);
* a member's reference does not jump to its target: whenever a vehicle
  gets a new target (it joins, or a re-assignment moves its slot) the layer
  plans a reference that starts at the vehicle's position, speed and
  acceleration and reaches the slot at rest relative to it with bounded
  acceleration and jerk (:func:`icv_envs.formation.control.join_profile`,
  limits ``profile_accel``/``profile_decel``/``profile_jerk``, speeds
  within ``profile_speeds``: the paper's main-road range 15..30 m/s, the top
  lowered by 1 m/s so the feedback keeps room above the reference); a member
  that falls more than ``replan_error`` metres off its reference (traffic
  held it back) gets a new plan from where it is. The published
  ``X_ref``/``v_ref`` are this reference, :meth:`reference_accel` its
  acceleration;
* a member still farther than ``stall_error`` metres from its target
  ``stall_time`` seconds after its first plan for that target should have
  arrived also triggers a re-assignment (from the current positions), so an
  assignment that traffic makes unreachable is revised;
* a free ICV joins a formation when it is within ``join_distance`` of the
  formation's span and the formation has fewer than ``max_size`` members; a
  member whose exit's diverge segment is less than ``exit_lookahead`` ahead
  leaves.
"""

from __future__ import annotations

import functools

import numpy as np

from icv_envs.formation.assignment import _check_weight
from icv_envs.formation.control import (
    FEEDBACK_ERROR,
    PROFILE_ACCEL,
    PROFILE_DECEL,
    PROFILE_JERK,
    PROFILE_MIN_DURATION,
)
from icv_envs.formation.targets import formation_targets
from icv_envs.sim._kernels.formation import drivable_lane_bits1, reference_rows
from icv_envs.sim._kernels.formation_step import (
    off_reference_rows,
    reform_members,
    update_pass,
)
from icv_envs._ufuncs import count_nonzero, flatnonzero
from icv_envs.sim.formation_views import FormationViews
from icv_envs.sim.join_plans import JoinPlans

__all__ = ["FormationManager"]

_EMPTY_READONLY = np.zeros(0)
_EMPTY_READONLY.flags.writeable = False


def _obstacles(road) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The road's obstacles as the lane-window kernels take them: lanes, rear and front ends."""
    return (np.asarray(road._ob_lane, dtype=np.int64), np.asarray(road._ob_lo, dtype=np.float64),
            np.asarray(road._ob_hi, dtype=np.float64))


@functools.lru_cache(maxsize=1024)
def _targets_of(n: int, n_lanes: int, spacing: float, geometry: str) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~icv_envs.formation.targets.formation_targets`, memoised for
    the process (a pure function of its arguments; the arrays are
    read-only). Shared by every manager from stop 52: a manager's own memo
    started empty at each reset, and training resets often."""
    out = formation_targets(n, n_lanes, spacing, geometry)
    for arr in out:
        arr.flags.writeable = False
    return out


@functools.lru_cache(maxsize=4096)
def _length_of(n: int, n_lanes: int, spacing: float, geometry: str) -> float:
    """The formation's length: the largest of :func:`_targets_of`'s
    distances behind the front target (``0.0`` for no member), memoised
    with them (a re-forming asked for it twice a call; from stop 53)."""
    return float(_targets_of(n, n_lanes, spacing, geometry)[0].max()) if n else 0.0


class FormationManager(FormationViews):
    """The formation layer (module docstring); its read-only views of the
    formations' state are :class:`~icv_envs.sim.formation_views.FormationViews`."""

    def __init__(
        self,
        *,
        spacing: float = 20.0,
        geometry: str = "interlaced",
        w1: float = 1.0,
        w2: float = 10.0,
        speed: float = 25.0,
        lookahead: float = 200.0,
        join_distance: float = 60.0,
        exit_lookahead: float = 400.0,
        exit_lookahead_per_lane: float = 0.0,
        max_size: int = 16,
        max_anchor_lead: float = 15.0,
        stall_error: float = 30.0,
        stall_time: float = 5.0,
        allowed_lanes=None,
        create: bool = False,
        new_formation_gap: float = 60.0,
        formation_gap: float = 40.0,
        anchor_brake: float = 5.0,
        profile_accel: float = PROFILE_ACCEL,
        profile_decel: float = PROFILE_DECEL,
        profile_jerk: float = PROFILE_JERK,
        profile_min_duration: float = PROFILE_MIN_DURATION,
        replan_error: float = FEEDBACK_ERROR,
        profile_speeds: tuple = (15.0, 29.0),
    ) -> None:
        self.spacing = float(spacing)
        self.geometry = geometry
        self.w1, self.w2 = _check_weight("w1", w1), _check_weight("w2", w2)  # checked once: _reform assigns unchecked
        self.speed = float(speed)
        self.lookahead = float(lookahead)
        self.join_distance = float(join_distance)
        self.exit_lookahead = float(exit_lookahead)
        self.exit_lookahead_per_lane = float(exit_lookahead_per_lane)
        self.max_size = int(max_size)
        self.max_anchor_lead = float(max_anchor_lead)
        self.stall_error = float(stall_error)
        self.stall_time = float(stall_time)
        self.create_new = bool(create)
        self.new_formation_gap = float(new_formation_gap)
        self.formation_gap = float(formation_gap)
        self.anchor_brake = float(anchor_brake)
        self.allowed_lanes = None if allowed_lanes is None else tuple(int(v) for v in allowed_lanes)
        # the formations' state, in arrays indexed by formation id (one entry
        # per id ever made, grown as ids appear): front target (``nan``: no
        # such formation, or one that has dissolved), length, member count,
        # lane set as a bit set, how long it has been stalled; the lane sets
        # as tuples in ``_lanes`` (see the read-only dict views ``anchor``,
        # ``length``, ``count``, ``lanes``, ``stalled_for``)
        self._A = np.full(16, np.nan)
        self._L = np.zeros(16)
        self._cnt = np.zeros(16, dtype=np.int64)
        self._bits = np.zeros(16, dtype=np.int64)
        self._stall = np.zeros(16)
        self._lanes: dict[int, tuple[int, ...]] = {}
        self._live = None  # cached _gids()
        self.next_gid = 0
        self.reforms = 0
        self.profile_limits = dict(accel=float(profile_accel), decel=float(profile_decel), jerk=float(profile_jerk),
                                   t_min=float(profile_min_duration))
        self.replan_error = float(replan_error)
        self.profile_speeds = (float(profile_speeds[0]), float(profile_speeds[1]))
        self.time = 0.0
        self._version = 0  # bumped whenever the formation state may change (update, create): references' cache key
        self._refs_cache = None  # (key, references): see references
        self._bits_memo: dict[tuple, int] = {}  # lane set -> bit set (_lane_bitset)
        self._lanes_memo: dict[int, tuple] = {}  # bit set -> lane set (_lane_set)
        self._allowed_memo: dict[int, np.ndarray] = {}  # lane count -> allowed-lane mask (_allowed)
        self._road_c = None  # (road, the update's arguments that depend on the road only): _road_args
        self._lane_arrays: dict[tuple, tuple] = {}  # lane set -> (float64, int64) arrays (_lane_arrays_of)
        # per vehicle id: the join plans and the slot each was made for (sim/join_plans.py)
        self._plans = JoinPlans(self.profile_limits, self.profile_speeds, self.speed)

    # ------------------------------------------------- formation state views
    def _gids(self) -> np.ndarray:
        """Ids of the live formations, ascending (the order they were made),
        read-only; kept until a formation is made or dissolves."""
        g = self._live
        if g is None:
            g = self._live = flatnonzero(~np.isnan(self._A[:self.next_gid]))
            g.flags.writeable = False
        return g

    def _new_gid(self, anchor: float) -> int:
        """A new formation id with front target ``anchor``, no members yet."""
        gid = self.next_gid
        self.next_gid += 1
        self._live = None
        self._reserve(self.next_gid + 1)  # room for the id and the lookup table's extra entry (_anchor_lut)
        self._A[gid] = anchor
        self._L[gid] = 0.0
        self._cnt[gid] = 0
        self._stall[gid] = 0.0
        return gid

    def _reserve(self, size: int) -> None:
        """Room in the formation arrays for ids below ``size`` (doubling, as
        :meth:`_new_gid` grows them; new entries as it leaves them)."""
        cap = len(self._A)
        if size <= cap:
            return
        pad = max(size, 2 * cap) - cap
        self._A = np.concatenate([self._A, np.full(pad, np.nan)])
        self._L, self._stall = (np.concatenate([x, np.zeros(pad)]) for x in (self._L, self._stall))
        self._cnt, self._bits = (np.concatenate([x, np.zeros(pad, dtype=np.int64)]) for x in (self._cnt, self._bits))

    # ---------------------------------------------------------------- helpers
    def _lane_set(self, road, anchor: float, length: float) -> tuple[int, ...]:
        """The main lanes drivable over the window a formation with front
        target ``anchor`` and ``length`` spans (``road.drivable_main_lanes``
        over ``[anchor - length - 10, anchor + lookahead]``) that this
        manager may use, ascending: one compiled pass
        (:func:`icv_envs.sim._kernels.formation.drivable_lane_bits1`), the
        bit set decoded through a memo."""
        bits = drivable_lane_bits1(anchor - length - 10.0, anchor + self.lookahead, bool(road.periodic),
                                   float(road.length), road.lane_ends, *_obstacles(road), self._allowed(road.n_lanes))
        lanes = self._lanes_memo.get(bits)
        if lanes is None:
            lanes = self._lanes_memo[bits] = tuple(lane for lane in range(bits.bit_length()) if bits >> lane & 1)
        return lanes

    def _road_args(self, road) -> dict:
        """The arguments of :meth:`update`'s compiled passes that depend on
        the road only, converted once per road (a reset builds a new one)."""
        c = self._road_c
        if c is not None and c[0] is road:
            return c[1]
        length = float(road.length) if road.periodic else -1.0
        d = {"membership": (length, int(road.n_exits), float(road.lane_width), int(road.total_lanes),
                            int(road.n_lanes), bool(road.has_ramp_lane), road._diverge_iv),
             "hold": (length, float(road.length), road.lane_ends, *_obstacles(road))}
        self._road_c = (road, d)
        return d

    def _allowed(self, n_lanes: int) -> np.ndarray:
        """The lanes this manager may use, as a read-only mask over ``n_lanes`` main lanes."""
        allowed = self._allowed_memo.get(n_lanes)
        if allowed is None:  # (fixed per lane count)
            allowed = np.ones(n_lanes, dtype=bool)
            if self.allowed_lanes is not None:
                allowed[:] = False
                allowed[[lane for lane in self.allowed_lanes if lane < n_lanes]] = True
            allowed.flags.writeable = False
            self._allowed_memo[n_lanes] = allowed
        return allowed

    def _lane_bitset(self, lanes: tuple) -> int:
        """A lane set as a bit set (bit ``l`` for lane ``l``), memoised."""
        b = self._bits_memo.get(lanes)
        if b is None:
            b = self._bits_memo[lanes] = sum(1 << lane for lane in lanes)
        return b

    def _lane_arrays_of(self, lanes: tuple) -> tuple[np.ndarray, np.ndarray]:
        """A lane set as read-only float64 and int64 arrays, memoised."""
        out = self._lane_arrays.get(lanes)
        if out is None:
            out = (np.asarray(lanes, dtype=np.float64), np.asarray(lanes, dtype=np.int64))
            for arr in out:
                arr.flags.writeable = False
            self._lane_arrays[lanes] = out
        return out

    def targets(self, n: int, n_lanes: int) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~icv_envs.formation.targets.formation_targets` of this
        manager's spacing and geometry, memoised (:func:`_targets_of`)."""
        return _targets_of(n, n_lanes, float(self.spacing), self.geometry)

    def _target_length(self, n: int, n_lanes: int) -> float:
        """The length of :meth:`targets` ``(n, n_lanes)``: ``tx.max()``, 0 for none (memoised, :func:`_length_of`)."""
        return _length_of(n, n_lanes, float(self.spacing), self.geometry)

    def _slot_x(self, traffic, rows) -> np.ndarray:
        # each row's front target minus its place behind it, through a lookup
        # table over the formation ids (nan where none; one entry per id ever
        # made, a few thousand after an hour on the ring: cheaper than the
        # sort a per-formation lookup needs)
        return self._anchor_lut()[traffic.group[rows]] - traffic.tgt_behind[rows]

    def _anchor_lut(self) -> np.ndarray:
        """Front target by formation id (``nan`` for ids with none), one
        entry per id ever made and one more (a view of the state: read it,
        do not keep it)."""
        return self._A[:self.next_gid + 1]

    def _plan(self, traffic, road, rows, cx) -> np.ndarray:
        """Plan references for members ``rows`` from their current state
        (:meth:`JoinPlans.plan_members`: the offsets from their slots,
        ``road.wrap(cx - slot)``, speeds relative to the formation and
        clipped accelerations, the search and the store in one compiled
        call); returns the plans' durations."""
        if not len(rows):
            return np.zeros(0)
        return self._plans.plan_members(np.asarray(rows, dtype=np.int64), traffic.group, traffic.tgt_behind,
                                        self._anchor_lut(), np.asarray(cx, dtype=np.float64), traffic.speed,
                                        traffic.accel, traffic.vid, float(road.length) if road.periodic else -1.0,
                                        self.time)

    def _profile(self, traffic, rows):
        """``join_profile`` of the members at ``rows`` now (:meth:`JoinPlans.profile`, cached)."""
        vid = traffic.vid
        # (rows of traffic, whose ids are sorted: none above the last)
        return self._plans.profile(vid[rows], self.time, int(vid[-1]) + 1 if len(vid) else None)

    def create(self, traffic, rows, road, anchor: float | None = None) -> int:
        """Make a new formation of vehicles ``rows`` and assign them targets."""
        rows = np.asarray(rows, dtype=np.int64)
        cx, _ = traffic.center()
        self._version += 1
        gid = self._new_gid(float(cx[rows].max() if anchor is None else anchor))
        traffic.group[rows] = gid
        self._reform(traffic, road, gid, cx)
        return gid

    def _reform(self, traffic, road, gid: int, cx: np.ndarray) -> None:
        """Paper Sec. 3.2-3.3: generate targets for the members on the
        drivable lanes and assign them by minimum total cost F_w."""
        rows = flatnonzero(traffic.group == gid)
        n = len(rows)
        self._cnt[gid] = n
        if n == 0:
            return
        anchor = float(self._A[gid])
        lanes, tx, tl = self._reform_lanes(road, gid, n)
        # vehicles in the formation frame (metres behind the front target and
        # a fractional formation lane id interpolated over the lane set),
        # their costs, the minimum-cost assignment (SciPy's answer), the
        # slots written and, for the members whose slot changed, a reference
        # from where they are (a join plan, its slot and deadline stored), in
        # one compiled call (sim/_kernels/formation_step.reform_members, from
        # stop 56: reform_costs, SciPy's linear_sum_assignment, reform_slots
        # and the plan one by one before)
        _, cy = traffic.center()
        lanes_f, lanes_i = self._lane_arrays_of(lanes)
        jp = self._plans
        jp.grow(int(traffic.vid[rows[-1]]) + 1)  # (the largest id: rows ascend, and so do the ids by row)
        vid = traffic.vid
        # (the plans' tables hold every id, as JoinPlans.plan_members makes
        # them before it plans: almost always; otherwise the plans below)
        plan = jp.capacity() >= int(vid[-1]) + 1
        length = float(road.length) if road.periodic else -1.0
        r = reform_members(rows, cx, cy, anchor, float(road.lane_width), lanes_f, lanes_i, tx, tl, float(self.w1),
                           float(self.w2), length, gid, vid, traffic.tgt_behind, traffic.tgt_lane, plan, traffic.group,
                           self._anchor_lut(), traffic.speed, traffic.accel, float(jp.speed), float(self.time),
                           *jp.search_args(), jp.slot_gid, jp.slot_behind, jp.deadline, *jp.tables())
        self.reforms += 1
        if plan:
            jp.count += len(r)  # (the plans made inside, as plan_members counts them)
        elif len(r):  # members with a new slot get a reference from where they are
            T = self._plan(traffic, road, r, cx)
            jp.slot_gid[vid[r]] = gid
            jp.slot_behind[vid[r]] = traffic.tgt_behind[r]
            jp.deadline[vid[r]] = self.time + T

    def _reform_lanes(self, road, gid: int, n: int) -> tuple[tuple, np.ndarray, np.ndarray]:
        """Paper Sec. 3.2: the lane set and targets of formation ``gid``
        re-formed with ``n`` members (the main lanes drivable over the window
        the *new* formation will span: its length depends on the lane count
        and vice versa, so twice at most), recorded as its lanes, lane bits
        and length. Returns ``(lanes, tx, tl)``."""
        anchor = float(self._A[gid])
        old_length = float(self._L[gid])
        lanes = self._lane_set(road, anchor, old_length)
        if not lanes:
            lanes = (0,)
        for _ in range(2):
            length = self._target_length(n, len(lanes))
            if length <= old_length:
                # (the window is the one just asked about: the same lanes; the
                # call was made and gave them until stop 53)
                break
            new = self._lane_set(road, anchor, length) or lanes
            if new == lanes:
                break
            lanes = new
        tx, tl = self.targets(n, len(lanes))
        self._lanes[gid] = lanes
        self._bits[gid] = self._lane_bitset(lanes)
        self._L[gid] = self._target_length(n, len(lanes))
        return lanes, tx, tl

    # ----------------------------------------------------------------- update
    def update(self, traffic, road, dt: float) -> list[int]:
        """Advance the front targets by ``dt`` and process membership and
        lane-set events; returns the ids of formations that re-formed.

        Order: front targets advance; members about to exit leave; free
        vehicles near a formation with room join it; with ``create`` set,
        a free vehicle farther than ``new_formation_gap`` from every
        formation founds a new one; each front target is held back behind
        the formation ahead (``formation_gap``) and within
        ``max_anchor_lead`` of its members; lane-set changes and stalls are
        detected; every formation that changed re-forms; members farther
        than ``replan_error`` from their reference re-plan.

        The hold (per formation, all at once): the front target slows down
        (by at most ``anchor_brake`` m/s, so members see a smooth reference)
        when it leads its best-placed member by more than
        ``max_anchor_lead`` or comes closer than ``formation_gap`` to the
        formation ahead. The lead is measured against each member's
        REFERENCE (slot + join profile), not its slot: a member on its join
        plan is meant to be behind its slot, and holding the front target
        back for it would move the slot slower than the plan assumes, so
        the reference would never pull the member up (a positive feedback
        that left whole formations at the speed floor). A change of the
        drivable lane set over the formation's window, or a member far from
        its target AFTER its plan should have brought it there (the join
        profile's deadline) for ``stall_time`` in a row (e.g. it joined
        ahead of the formation and its target lies beyond a member in its
        lane), marks it for re-forming (the stall count restarts; a
        formation that re-forms anyway restarts it too). Everything up to
        the re-forming is one compiled call
        (:func:`icv_envs.sim._kernels.formation_step.update_pass`, from stop
        50), the arithmetic of the array code it replaced, element by
        element."""
        cx, cy = traffic.center()
        self._version += 1
        self.time += dt
        n = traffic.n
        length = float(road.length) if road.periodic else -1.0
        jp = self._plans
        if n:
            jp.grow(int(traffic.vid[-1]) + 1)  # (rows sorted by id)
        self._reserve(self.next_gid + n + 1)  # room for one new formation per vehicle (step 5 below)
        # front targets, leaving members, member counts, joins, new
        # formations and the room ahead of each formation
        # (sim/_kernels/formation_step.membership_pass: the array code it
        # replaced is frozen in tests/test_formation_update.py), then the
        # members' join profiles, the front-target hold, lane windows and
        # stall clocks and, when nothing re-forms, the re-plan test, the
        # re-plans and the references, in one compiled call (update_pass,
        # from stop 50)
        ra = self._road_args(road)
        rh = ra["hold"]  # (period or -1, length, lane ends, obstacles)
        changed, next_gid, M, P, off, R, lane_ref, member = update_pass(
            traffic.group, traffic.tgt_lane, traffic.vid, traffic.crashed, cx, cy, traffic.lc_lane, traffic.exit,
            jp.slot_gid, self._A, self._L, self._cnt, self._stall, self._gids(), self.next_gid,
            self.speed * dt, *ra["membership"], float(self.exit_lookahead),
            float(self.exit_lookahead_per_lane), self.max_size, float(self.join_distance), self.create_new,
            float(self.new_formation_gap), float(self.formation_gap), self._bits, traffic.tgt_behind, jp.deadline,
            float(self.time), float(self.max_anchor_lead), -self.anchor_brake * dt, float(self.stall_error),
            float(dt), float(self.stall_time), float(self.lookahead), *rh[1:], self._allowed(road.n_lanes),
            float(self.replan_error), traffic.speed, traffic.accel, float(self.speed),
            -1.0 if traffic.period is None else float(traffic.period), *jp.search_args(), *jp.tables())
        if next_gid != self.next_gid:
            self.next_gid = next_gid
            self._live = None
        jp.count += len(off)  # (the re-plans made inside)
        if M.shape[1]:  # the members' profiles now: the answer every later caller in this step asks for
            jp.keep(M[1], self.time, P)
        changed = changed.tolist()
        for gid in changed:  # ascending
            self._reform(traffic, road, gid, cx)
        if changed and n:
            # members that fell off their reference (held back by traffic)
            # re-plan from where they are, tested after the re-forming
            # (which moves slots; compiled, off_reference_rows)
            m = flatnonzero(traffic.group >= 0)
            if len(m):
                off = off_reference_rows(traffic.group, m, cx, self._anchor_lut(), traffic.tgt_behind,
                                         self._profile(traffic, m)[0], length, float(self.replan_error))
                if len(off):
                    self._plan(traffic, road, off, cx)
        g_arr = self._gids()
        cnt = self._cnt[g_arr]
        if count_nonzero(cnt) != len(cnt):  # (the count first: most steps nobody's formation empties)
            for gid in g_arr[cnt == 0].tolist():  # formations without members dissolve
                self._A[gid] = np.nan
                self._lanes.pop(gid, None)
                self._live = None
        self._version += 1
        if not changed:  # the references of this state, made in the same call: kept for references()
            self._keep_refs(traffic, ((R[0], lane_ref, R[1], member), R[2]))
        return changed

    def references(self, traffic) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per-vehicle ``(x_ref, lane_ref, v_ref, member)``: body-centre
        reference position, target lane, reference speed, membership mask.
        The target is ``X_slot = anchor - x_g`` (paper Sec. 4 uses the same
        form) at the formation speed; the reference is the slot plus the
        member's join profile ``d(t)`` (module docstring), equal to the slot
        once the profile has ended. Free vehicles get ``nan`` / ``-1``.

        Computed once per state (the observations and the expert both ask):
        the answer is kept, keyed on the clock, the vehicle ids and this
        manager's state version (bumped by :meth:`update` and :meth:`create`,
        the only writers of the formation state), and returned read-only."""
        return self._refs(traffic)[0]

    def _refs(self, traffic) -> tuple:
        """``(references, reference_accel)`` of the current state, cached
        (see :meth:`references`)."""
        key = (self.time, self._version, id(traffic), traffic.vid.tobytes())
        c = self._refs_cache
        if c is not None and c[0] == key:
            return c[1]
        return self._keep_refs(traffic, self._references(traffic), key)

    def _keep_refs(self, traffic, out: tuple, key: tuple | None = None) -> tuple:
        """Keep ``out`` as the references of ``traffic``'s current state (read-only; see :meth:`references`)."""
        for arr in out[0] + (out[1],):
            arr.setflags(write=False)
        self._refs_cache = (key or (self.time, self._version, id(traffic), traffic.vid.tobytes()), out)
        return out

    def _references(self, traffic) -> tuple:
        """``((x_ref, lane_ref, v_ref, member), a_ref)`` computed (compiled:
        :func:`icv_envs.sim._kernels.reference_rows`, the arithmetic of the
        array code it replaced, tests/test_join_reference.py)."""
        m = flatnonzero(traffic.group >= 0)
        if len(m):
            d, dv, dd = self._profile(traffic, m)
        else:  # read-only like the profiles (one numba specialisation of reference_rows)
            d = dv = dd = _EMPTY_READONLY
        R, lane_ref, member = reference_rows(
            traffic.group, traffic.tgt_lane, traffic.tgt_behind, self._anchor_lut(), m, d, dv, dd, float(self.speed),
            -1.0 if traffic.period is None else float(traffic.period))
        x_ref, v_ref, a_ref = R  # (row views)
        return (x_ref, lane_ref, v_ref, member), a_ref

    def reference_accel(self, traffic) -> np.ndarray:
        """Per-vehicle acceleration of the reference (the join profile's
        ``d''``; 0 for settled members, ``nan`` for free vehicles), read-only
        (computed with :meth:`references`, and cached with them)."""
        return self._refs(traffic)[1]
