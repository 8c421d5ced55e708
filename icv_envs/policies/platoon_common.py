"""Shared state of the intersection experts: vehicle stages, longitudinal modes, the corridor index.

Used by :mod:`icv_envs.policies.regrouping` (paper Sec. 5),
:mod:`icv_envs.policies.virtual_platoon` (Sec. 4.2) and
:mod:`icv_envs.policies.platoon_expert` (control).
"""

from __future__ import annotations

import itertools
import operator

import numpy as np

from icv_envs.policies._kernels import corridor_add_signals, corridor_index, corridor_neighbours

__all__ = ["Corridors", "group_rows", "same_objects", "MODE_FREE", "MODE_FOLLOW", "MODE_TREE", "MODE_PLAN",
           "ST_APPROACH", "ST_LC", "ST_ADJUSTED", "ST_COORD"]

MODE_FREE, MODE_FOLLOW, MODE_TREE, MODE_PLAN = 0, 1, 2, 3
# vehicle stages
ST_APPROACH, ST_LC, ST_ADJUSTED, ST_COORD = 0, 1, 2, 3


def same_objects(a: tuple, b: tuple) -> bool:
    """Whether ``a`` and ``b`` hold the same objects in the same order
    (identity, not equality): the key test of the experts' kept answers
    (:meth:`~icv_envs.policies.virtual_platoon.VirtualPlatoon._member_rows`,
    :meth:`~icv_envs.policies.regrouping.Regrouping._sub_distances`), whose
    parts (the fleet's id array, the route state, the groups' member lists)
    are replaced, never changed in place, when what they stand for changes.
    A kept key holds its objects, so none is freed and its id reused."""
    return len(a) == len(b) and all(map(operator.is_, a, b))


def group_rows(f, members: list) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, sizes)``: the fleet rows of several groups' members (lists of
    vehicle ids), the groups' in order and each group's in member order, in
    one ``f.rows`` call, and each group's size: how the regrouping and the
    virtual platoon hand their groups to a kernel (group ``k`` the next
    ``sizes[k]`` rows)."""
    lens = list(map(len, members))
    sizes = np.fromiter(lens, dtype=np.int64, count=len(lens))
    # (the count summed in Python: numpy's sum of a few dozen sizes cost more than the lookup)
    rows = f.rows(np.fromiter(itertools.chain.from_iterable(members), dtype=np.int64, count=sum(lens)))
    return rows, sizes


class Corridors:
    """Per-corridor sorted index of the vehicles (the "per-path neighbour search").

    Corridors: approach lane ``3 leg + lane`` (0..11; a vehicle is listed in
    every lane its footprint (heading included) reaches into, in the lane it is
    changing into and in the lane it waits to change into; in-box vehicles
    stay listed in their approach lane for their first ``diverge`` metres);
    departure lane ``12 + 3 exit + lane`` (departed vehicles and in-box
    vehicles within ``diverge`` metres of the exit edge, coordinate ``s - L``);
    path ``24 + pid`` (in-box vehicles, coordinate ``s``).  One sorted key
    array, so every leader query is a ``searchsorted``.
    """

    BIG = 1.0e5

    def __init__(self, world, rs, signal_lane, diverge: float = 10.0) -> None:
        # the entries (listed in the order of the class docstring; of two
        # entries of one vehicle in one corridor, only a signal can repeat a
        # physical one, and the physical one is kept), sorted by key then
        # row; ``lead``: the entry index of each entry's leader (-1 none)
        (phase, lane, lat_leg, sin_dh, cos_dh, length, width, w, leg, s, pid, plane, L, exit_leg, exit_of, mv,
         dlane) = self._inputs(world, rs)
        self.rows, self.corr, self.coord, self.keys, self.signal_only, self.lead = corridor_index(
            phase, lane, lat_leg, sin_dh, cos_dh, length, width, w, leg, s, np.asarray(signal_lane, dtype=np.int64),
            pid, plane, L, float(diverge), exit_leg, exit_of, mv, dlane, self.BIG)

    @staticmethod
    def _inputs(world, rs) -> tuple:
        """The index's per-vehicle inputs but the signals, gathered once per
        route state (the experts and the env build two to four indices of
        one state a step, with different signals), kept as :meth:`plain` is
        (:meth:`_state_cache`); the rest of the per-vehicle work (the
        footprint's reach, the box and departure flags, the departure
        corridor) is :func:`~icv_envs.policies._kernels.corridor_index`'s."""
        cache = Corridors._state_cache(world, rs)
        if "inputs" in cache:
            return cache["inputs"]
        f = world.fleet
        lay = world.layout
        # the heading relative to the approach direction, whose sine and cosine
        # give the footprint's lateral reach: a vehicle stopped at an angle in
        # the middle of a lane change reaches further into the lane it leaves
        # than its width says (single-vp, 4500 veh/h, seed 0: the follower in
        # that lane, no longer seeing it with the former 0.3 m slack on the
        # width, hit its rear corner). (The approach directions' angles per
        # leg, IntersectionLayout.app_angle: arctan2 of the axis-aligned unit
        # vectors, exact values, so the same numbers as per vehicle.)
        dh = f.heading - lay.app_angle[f.leg]
        i64 = np.int64
        out = (rs.phase.astype(i64, copy=False), rs.lane.astype(i64, copy=False), rs.lat_leg, np.sin(dh), np.cos(dh),
               f.length, f.width, float(lay.lane_width), f.leg.astype(i64, copy=False), rs.s,
               rs.pid.astype(i64, copy=False), f.plane.astype(i64, copy=False), rs.L,
               f.exit_leg.astype(i64, copy=False), lay.exit_of, f.mv.astype(i64, copy=False), lay.dlane)
        cache["inputs"] = out
        return out

    @staticmethod
    def _state_cache(world, rs) -> dict:
        """What :meth:`plain` and :meth:`_inputs` keep for route state ``rs``:
        the world's cache while ``rs`` is its current route state and the
        fleet has the same vehicles (everything an index reads changes only
        with a new route state: the physics, a spawn, a removal or a
        rerouted movement); a new one for the current state, and one kept
        nowhere for a state that is no longer current."""
        if not world.route_is(rs):
            return {}
        n = world.fleet.n
        c = getattr(world, "_corridor_cache", None)
        if c is None or c[0] is not rs or c[1] != n:
            c = world._corridor_cache = (rs, n, {})
        return c[2]

    @classmethod
    def plain(cls, world, rs) -> "Corridors":
        """The index without turn signals (no vehicle listed in a lane it
        waits to change into) of route state ``rs``, built once per state:
        the virtual platoon's order check and the env's leaders ask for the
        same one within a step. Reused while ``rs`` is the world's current
        route state and the fleet has the same vehicles (:meth:`_state_cache`);
        callers only read it."""
        cache = cls._state_cache(world, rs)
        if "plain" not in cache:
            cache["plain"] = cls(world, rs, np.full(world.fleet.n, -1))
        return cache["plain"]

    @classmethod
    def with_signals(cls, world, rs, signal_lane) -> "Corridors":
        """The index with turn signals ``signal_lane`` (the default
        ``diverge``): the same entries, order and leaders as
        ``Corridors(world, rs, signal_lane)``, made from the index without
        signals (:meth:`plain`, built once per state and shared) by adding
        the signal entries (:func:`~icv_envs.policies._kernels.corridor_add_signals`,
        from stop 41: a merge instead of a second build; the expert's
        envelope and lane changes ask for it every step)."""
        base = cls.plain(world, rs)
        f = world.fleet
        out = cls.__new__(cls)
        out.rows, out.corr, out.coord, out.keys, out.signal_only, out.lead = corridor_add_signals(
            base.rows, base.corr, base.coord, base.keys, rs.phase.astype(np.int64, copy=False),
            f.leg.astype(np.int64, copy=False), rs.s, np.asarray(signal_lane, dtype=np.int64), cls.BIG)
        return out

    def neighbours(self, q_rows, q_corr, q_coord):
        """Nearest other vehicle ahead (coordinate >) and behind (<=) in corridor ``q_corr``.

        Returns ``(lead_row, lead_coord, foll_row, foll_coord)`` (-1 / +-inf when none).
        """
        q_rows = np.asarray(q_rows, dtype=np.int64)
        k = len(q_rows)
        # (one corridor for all, or one each; np.full instead of broadcast_to + a copy: the same keys)
        q_corr = np.full(k, q_corr, dtype=np.int64) if np.ndim(q_corr) == 0 else np.asarray(q_corr, dtype=np.int64)
        qk = q_corr * self.BIG + q_coord
        if qk.shape != (k,):
            qk = np.broadcast_to(qk, (k,))
        return corridor_neighbours(self.keys, self.corr, self.rows, self.coord, q_rows, np.ascontiguousarray(q_corr),
                                   np.ascontiguousarray(qk, dtype=np.float64))
