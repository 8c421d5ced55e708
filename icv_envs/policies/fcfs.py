"""First-come-first-served tile reservation at the intersection (the paper's reference).

After Dresner & Stone's AIM (docs/intersection.md#reference-methods), with the tile table of
:class:`icv_envs.platoon.reservation.ReservationTable`.  The approaching and
adjusting zones are those of :class:`~icv_envs.policies.platoon_expert.
PlatoonExpert` (interlaced formations, division, lane changes to the
expected lanes), so the three methods differ only in the coordinating zone.
There every vehicle drives on its own (IDM, 1 s time gap, towards ``v0``):

* the box is a grid of ``tile`` x ``tile`` tiles (1 m);
* every policy step, each vehicle without a reservation that is in its
  expected (allowed) lane, within ``request_distance`` (80 m) of the stop
  line and first in its lane among the vehicles without a reservation asks
  for the tiles its footprint, buffered by ``space_buffer`` on every side
  (0.5 m here and in the env's ``fcfs-tight``; 0 in the env's ``fcfs``,
  whose buffers match the virtual platoon's minimum PET, see
  ``icv_envs.envs.intersection._FCFS_DEFAULTS``), covers at every simulation step of a proposed crossing: from its
  current position and speed, accelerate at ``a_plan`` (1.5 m/s^2) to ``v0``
  and hold it until the buffered body has left the box.  The tiles of a
  path at every position are precomputed (0.1 m apart, the buffer grown by
  those 0.1 m so that the lookup stays conservative);
* requests are answered in arrival order (the order in which vehicles
  entered the coordinating zone): a request is granted iff none of its tiles
  is held by another vehicle at that step or within ``time_buffer`` steps
  (5 = 0.2 s here and in ``fcfs-tight``, 0 in ``fcfs``) of it, and a proposal that would not keep 2 m + 0.5 s of headway
  behind the reserved plan of the vehicle ahead in the same lane is not
  sent, nor one that would not keep that headway to a reserved vehicle
  leaving by the same departure lane (the tiles only cover the box);
* a rejected vehicle slows down (it brakes for the stop line, IDM towards a
  standing obstacle 1 m before it) and asks again at the next step; a vehicle
  without a reservation stops before the box;
* a vehicle with a reservation follows its plan: the plan's acceleration plus
  the feedback ``plan_kp (s - s_plan) + plan_kv (v - v_plan)``
  (``-1.0, -2.0``: critically damped, stiffer than the formation law because
  being late or early by more than the buffers would break the reservation);
  its tiles are released once it has cleared the box.  A vehicle that is
  more than ``plan_tolerance`` (1 m) off its plan before the stop line (held
  up by the vehicle ahead) gives its reservation up and asks again: a
  reservation is only useful if it is kept.
"""

from __future__ import annotations

import math

import numpy as np

from icv_envs.platoon.reservation import ReservationTable, footprint_mask
from icv_envs.policies.platoon_expert import (
    MODE_FREE,
    MODE_PLAN,
    ST_COORD,
    Corridors,
    PlatoonExpert,
    PlatoonParams,
)

__all__ = ["FcfsExpert"]


class FcfsExpert(PlatoonExpert):
    """Reservation (FCFS) coordination + controller; same interface as :class:`PlatoonExpert`."""

    _allow_other_method = True

    def __init__(self, layout, params: PlatoonParams | None = None, frames: int = 5, dt: float = 0.04,
                 tile: float = 1.0, time_buffer: int = 5, space_buffer: float = 0.5,
                 request_distance: float = 80.0, a_plan: float = 1.5, plan_kp: float = -1.0,
                 plan_kv: float = -2.0, vehicle_length: float = 5.0, vehicle_width: float = 2.0) -> None:
        super().__init__(layout, params, method="fcfs", frames=frames)
        self.dt = float(dt)
        self.table = ReservationTable(tile, layout.box_half, dt, time_buffer)
        self.space_buffer = float(space_buffer)
        self.request_distance = float(request_distance)
        self.a_plan = float(a_plan)
        self.plan_kp, self.plan_kv = float(plan_kp), float(plan_kv)
        self.plan_tolerance = 1.0  # [m] see _coordinate
        self.plans: dict[int, dict] = {}
        self.stats.update({"requests": 0, "granted": 0, "rejected": 0, "not_sent_headway": 0, "cancelled": 0,
                           "max_plan_error": 0.0})
        self._ds = 0.1
        self._veh = (float(vehicle_length), float(vehicle_width))
        self._masks: dict[int, tuple[float, np.ndarray]] = {}
        for m, lanes in layout.lane_use.items():
            for a in lanes:
                self._masks[3 * m + a] = self._path_masks(3 * m + a)

    def _path_masks(self, pid: int):
        lay = self.layout
        length, width = self._veh
        hl = 0.5 * length + self.space_buffer + 2 * self._ds
        s = np.arange(-hl, lay.L[pid] + hl + self._ds, self._ds)
        x, y, h = lay.route_points(np.full(len(s), pid), s)
        mask = footprint_mask(np.column_stack([x, y]), h, length, width, self.space_buffer + self._ds,
                              self.table.tile, lay.box_half)
        return float(s[0]), mask

    # ------------------------------------------------------------ coordinating
    def _coordinate(self, world, rs) -> None:
        f = world.fleet
        lay = world.layout
        new = np.flatnonzero((rs.dist <= lay.R1) & (f.stage < ST_COORD))
        if len(new):
            new = new[np.argsort(rs.dist[new], kind="stable")]
            for r in new:
                f.order[r] = self._order_counter
                self._order_counter += 1
            f.stage[new] = ST_COORD
            f.ref[new] = -1
            gone = set(f.vid[new].tolist())
            for sid in list(self.subs):
                S = self.subs[sid]
                S["members"] = [v for v in S["members"] if v not in gone]
                if not S["members"]:
                    del self.subs[sid]
            f.sub[new] = -1
        # release the plans of vehicles that cleared the box (or left); the
        # plan holders' rows in one lookup (-1: no longer on the road; from
        # stop 42, one f.rows call per plan and loop before)
        ids = list(self.plans)
        row_of = dict(zip(ids, f.rows(np.asarray(ids, dtype=np.int64)).tolist())) if ids else {}
        cleared = f.cleared
        for vid in ids:
            r = row_of[vid]
            if r < 0 or cleared[r]:
                self.table.release(vid)
                del self.plans[vid]
        # a reservation that its vehicle can no longer keep (more than
        # plan_tolerance off its plan before the stop line) is given up
        for vid in list(self.plans):
            r = row_of[vid]
            P = self.plans[vid]
            k = min(world.step_count - P["k0"], len(P["s"]) - 1)
            if rs.phase[r] == 0 and abs(rs.s[r] - P["s"][k]) > self.plan_tolerance:
                self.table.release(vid)
                del self.plans[vid]
                self.stats["cancelled"] += 1
        self.table.advance(world.step_count)
        self._requests(world, rs)

    def _plan(self, s0: float, v0: float, pid: int, length: float):
        """Proposed crossing: accelerate (or slow) at ``a_plan`` to ``v0``, then hold it (Euler steps as the simulator)."""
        p = self.p
        lay = self.layout
        dt = self.dt
        end = lay.L[pid] + 0.5 * length + self.space_buffer + 1.0
        v_t = p.v0
        a = self.a_plan
        # enough steps: reach v_t, then cruise
        t_acc = abs(v_t - v0) / a
        n = int(math.ceil(t_acc / dt + (end - s0) / max(v_t, 0.5) / dt)) + 5
        k = np.arange(n + 1)
        if v0 <= v_t:
            v = np.minimum(v0 + a * k * dt, v_t)
        else:
            v = np.maximum(v0 - a * k * dt, v_t)
        s = s0 + dt * np.concatenate([[0.0], np.cumsum(v[:-1])])
        stop = int(np.searchsorted(s, end)) + 1
        s, v = s[:stop], v[:stop]
        acc = np.diff(v) / dt
        acc = np.append(acc, 0.0)
        return s, v, acc

    def _tiles(self, pid: int, s: np.ndarray, k0: int):
        s_min, mask = self._masks[pid]
        idx = np.floor((s - s_min) / self._ds).astype(np.int64)
        inside = (idx >= 0) & (idx + 1 < len(mask))
        ks = np.flatnonzero(inside)
        lo = mask[idx[ks]] | mask[idx[ks] + 1]
        touch = lo.any(axis=1)
        ks = ks[touch]
        lo = lo[touch]
        return (k0 + ks).astype(np.int64), [np.flatnonzero(row) for row in lo]

    def _requests(self, world, rs) -> None:
        f = world.fleet
        lay = world.layout
        klane = np.clip(f.klane, 0, 2)
        ok_lane = lay.allowed[f.mv, klane] & (f.klane == f.tlane) & (f.lc_lane < 0)
        has_plan = self._coordinated(f)
        cand = np.flatnonzero((f.stage == ST_COORD) & (rs.phase == 0) & ~has_plan & ok_lane
                              & (rs.u >= -self.request_distance) & ~f.crashed)
        if not len(cand):
            return
        cand = cand[np.argsort(f.order[cand], kind="stable")]
        cor = Corridors.plain(world, rs)
        lr, _, _, _ = cor.neighbours(cand, 3 * f.leg[cand] + klane[cand], rs.u[cand])
        k0 = world.step_count
        for r, lead in zip(cand.tolist(), lr.tolist()):
            vid = int(f.vid[r])
            lead_plan = None
            if lead >= 0:
                lvid = int(f.vid[lead])
                if lvid in self.plans:
                    lead_plan = self.plans[lvid]
                elif rs.phase[lead] == 0:
                    continue  # not first in its lane among vehicles without a reservation
            pid = 3 * int(f.mv[r]) + int(klane[r])
            s, v, acc = self._plan(float(rs.u[r]), float(f.speed[r]), pid, float(f.length[r]))
            if lead_plan is not None and not self._headway_ok(lead_plan, s, v, k0, pid, float(f.length[r])):
                self.stats["not_sent_headway"] += 1
                continue
            if not self._departure_ok(s, v, k0, pid, float(f.length[r])):
                self.stats["not_sent_headway"] += 1
                continue
            steps, tiles = self._tiles(pid, s, k0)
            self.stats["requests"] += 1
            if self.table.request(vid, steps, tiles):
                self.plans[vid] = {"k0": k0, "s": s, "v": v, "a": acc, "pid": pid, "length": float(f.length[r])}
                self.stats["granted"] += 1
            else:
                self.stats["rejected"] += 1

    def _headway_ok(self, L, s, v, k0, pid, length) -> bool:
        off = k0 - L["k0"]
        n = len(s)
        idx = off + np.arange(n)
        ls = L["s"]
        last = len(ls) - 1
        s_l = np.where(idx <= last, ls[np.minimum(idx, last)], ls[last] + (idx - last) * self.dt * L["v"][last])
        need = 0.5 * (L["length"] + length) + 2.0 + 0.5 * v
        check = np.ones(n, dtype=bool) if L["pid"] == pid else s <= 10.0
        return bool(np.all((s_l - s >= need) | ~check))

    def _departure_ok(self, s, v, k0, pid, length) -> bool:
        """Headway on the shared departure lane: against every reserved plan
        that leaves by the same departure lane, whichever of the two leaves the
        box first, the second keeps ``2 m + 0.5 s`` behind it from 10 m before
        the exit edge on (plans are extrapolated at their final speed).  The
        tiles only separate the two inside the box."""
        lay = self.layout
        e, j = lay.exit_of[pid // 3], lay.dlane[pid]
        n = len(s)
        t_new = np.arange(n) + k0
        x_new = s - lay.L[pid]
        for P in self.plans.values():
            q = P["pid"]
            if q == pid or lay.exit_of[q // 3] != e or lay.dlane[q] != j:
                continue
            x_old = P["s"] - lay.L[q]
            idx = t_new - P["k0"]
            last = len(x_old) - 1
            ok_idx = idx >= 0
            xo = np.where(idx <= last, x_old[np.clip(idx, 0, last)],
                          x_old[last] + (idx - last) * self.dt * P["v"][last])
            vo = np.where(idx <= last, P["v"][np.clip(idx, 0, last)], P["v"][last])
            new_first = np.argmax(x_new >= 0) if np.any(x_new >= 0) else n
            old_first = np.argmax(xo >= 0) if np.any(xo >= 0) else n
            if new_first < old_first:  # the new vehicle leaves first: the old one follows
                gap, vf, near = x_new - xo, vo, xo >= -10.0
            else:
                gap, vf, near = xo - x_new, v, x_new >= -10.0
            need = 0.5 * (P["length"] + length) + 2.0 + 0.5 * vf
            if np.any(ok_idx & near & (gap < need)):
                return False
        return True

    # -------------------------------------------------------------- references
    def _references(self, world, rs) -> None:
        super()._references(world, rs)
        f = world.fleet
        coord = f.stage == ST_COORD
        self._mode[coord & (self._mode != MODE_FREE)] = MODE_FREE
        if self.plans:
            rows = f.rows(np.fromiter(self.plans, dtype=np.int64, count=len(self.plans)))
            rows = rows[rows >= 0]
            self._mode[rows] = MODE_PLAN
        no_plan = coord & (self._mode != MODE_PLAN) & (rs.phase == 0)
        self._stop = self._stop | no_plan

    def _longitudinal(self, world, rs) -> np.ndarray:
        acc = super()._longitudinal(world, rs)
        f = world.fleet
        p = self.p
        rows = np.flatnonzero(self._mode == MODE_PLAN)
        worst = 0.0
        for r in rows.tolist():
            P = self.plans[int(f.vid[r])]
            k = world.step_count - P["k0"]
            n = len(P["s"])
            if k >= n - 1:
                acc[r] = 0.0
                continue
            a_ff = float(P["a"][k:k + self.frames].mean())
            err = float(rs.s[r] - P["s"][k])
            if rs.phase[r] == 1:
                worst = max(worst, abs(err))
            acc[r] = a_ff + self.plan_kp * err + self.plan_kv * (float(f.speed[r]) - float(P["v"][k]))
        self.stats["max_plan_error"] = max(self.stats["max_plan_error"], worst)
        return np.clip(acc, p.a_min, p.a_max)

    def _group(self, f) -> np.ndarray:
        # in the coordinating zone every vehicle is on its own
        return np.where(f.stage == ST_COORD, -1 - f.vid, super()._group(f))

    def _coordinated(self, f) -> np.ndarray:
        # the rows of the vehicles holding a plan (plans of vehicles no longer
        # on the road have no row); the same mask as np.isin(f.vid, plan ids),
        # which sorted both for it (from stop 42)
        out = np.zeros(f.n, dtype=bool)
        if self.plans:
            r = f.rows(np.fromiter(self.plans, dtype=np.int64, count=len(self.plans)))
            out[r[r >= 0]] = True
        return out

    def references(self, world):
        self._check_stamp(world)
        f = world.fleet
        rs = world.route()
        has, d, dv, go = super().references(world)
        for r in np.flatnonzero(self._mode == MODE_PLAN).tolist():
            P = self.plans[int(f.vid[r])]
            k = min(world.step_count - P["k0"], len(P["s"]) - 1)
            has[r] = True
            d[r] = P["s"][k] - rs.s[r]
            dv[r] = P["v"][k] - f.speed[r]
        go = (self._mode == MODE_PLAN) & ~self._stop
        return has, d, dv, go

    def groups(self, world):
        f = world.fleet
        out = []
        rows = f.rows(np.fromiter(self.plans, dtype=np.int64, count=len(self.plans)))
        rows = rows[rows >= 0]
        if len(rows):
            out.append(("reserved", 0, rows, 1))
        for sid, S in self.subs.items():
            out.append(("sub", sid, f.rows(S["members"]), -1))
        return out
