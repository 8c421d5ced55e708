"""Shared state of the intersection experts: vehicle stages, longitudinal modes, the corridor index.

Used by :mod:`icv_envs.policies.regrouping` (paper Sec. 5),
:mod:`icv_envs.policies.virtual_platoon` (Sec. 4.2) and
:mod:`icv_envs.policies.platoon_expert` (control).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Corridors", "MODE_FREE", "MODE_FOLLOW", "MODE_TREE", "MODE_PLAN", "ST_APPROACH", "ST_LC",
           "ST_ADJUSTED", "ST_COORD"]

MODE_FREE, MODE_FOLLOW, MODE_TREE, MODE_PLAN = 0, 1, 2, 3
# vehicle stages
ST_APPROACH, ST_LC, ST_ADJUSTED, ST_COORD = 0, 1, 2, 3


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
        f = world.fleet
        lay = world.layout
        w = lay.lane_width
        n = f.n
        rows, corr, coord, sigflag = [], [], [], []
        appr = rs.phase == 0
        idx = np.arange(n)
        # half the footprint's lateral extent, heading included: a vehicle
        # stopped at an angle in the middle of a lane change reaches further
        # into the lane it leaves than its width says (single-vp, 4500 veh/h,
        # seed 0: the follower in that lane, no longer seeing it with the
        # former 0.3 m slack on the width, hit its rear corner)
        ad = lay.app_dir[f.leg]
        dh = f.heading - np.arctan2(ad[:, 1], ad[:, 0]) if n else np.zeros(0)
        reach = 0.5 * w + 0.5 * (f.length * np.abs(np.sin(dh)) + f.width * np.abs(np.cos(dh)))
        for dl in (-1, 0, 1):
            ln = rs.lane + dl
            ok = appr & (ln >= 0) & (ln < 3) & (np.abs(rs.lat_leg - (ln + 0.5) * w) < reach)
            rows.append(idx[ok])
            corr.append((3 * f.leg + ln)[ok])
            coord.append(rs.s[ok])
            sigflag.append(np.zeros(int(ok.sum()), dtype=bool))
        sig = appr & (signal_lane >= 0)
        if sig.any():
            rows.append(idx[sig])
            corr.append((3 * f.leg + signal_lane)[sig])
            coord.append(rs.s[sig])
            sigflag.append(np.ones(int(sig.sum()), dtype=bool))
        box = rs.phase == 1
        if box.any():
            rows.append(idx[box])
            corr.append(24 + rs.pid[box])
            coord.append(rs.s[box])
            sigflag.append(np.zeros(int(box.sum()), dtype=bool))
            early = box & (rs.s < diverge)
            rows.append(idx[early])
            corr.append((3 * f.leg + np.maximum(f.plane, 0))[early])
            coord.append(rs.s[early])
            sigflag.append(np.zeros(int(early.sum()), dtype=bool))
        dep = (rs.phase == 2) | (box & (rs.s > rs.L - diverge))
        if dep.any():
            ex = np.where(f.exit_leg >= 0, f.exit_leg, lay.exit_of[f.mv])
            rows.append(idx[dep])
            corr.append((12 + 3 * ex + lay.dlane[rs.pid])[dep])
            coord.append((rs.s - rs.L)[dep])
            sigflag.append(np.zeros(int(dep.sum()), dtype=bool))
        rows = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
        corr = np.concatenate(corr) if corr else np.zeros(0, dtype=np.int64)
        coord = np.concatenate(coord) if coord else np.zeros(0)
        sigflag = np.concatenate(sigflag) if sigflag else np.zeros(0, dtype=bool)
        if len(rows):
            # first occurrence wins: a vehicle whose body covers its signal
            # lane is listed there physically, not as a signal only
            pair = rows * 64 + corr
            _, first = np.unique(pair, return_index=True)
            first = np.sort(first)
            rows, corr, coord, sigflag = rows[first], corr[first], coord[first], sigflag[first]
        keys = corr * self.BIG + coord
        order = np.lexsort((rows, keys))
        self.rows = rows[order].astype(np.int64)
        self.corr = corr[order].astype(np.int64)
        self.coord = coord[order]
        self.keys = keys[order]
        #: the entry exists only because the vehicle waits to change into that lane
        self.signal_only = sigflag[order]
        m = len(self.rows)
        lead = np.full(m, -1, dtype=np.int64)
        if m > 1:
            same = self.corr[1:] == self.corr[:-1]
            lead[:-1][same] = np.arange(1, m)[same]
        self.lead = lead  # entry index of the leader of each entry (-1 none)

    def neighbours(self, q_rows, q_corr, q_coord):
        """Nearest other vehicle ahead (coordinate >) and behind (<=) in corridor ``q_corr``.

        Returns ``(lead_row, lead_coord, foll_row, foll_coord)`` (-1 / +-inf when none).
        """
        q_rows = np.asarray(q_rows, dtype=np.int64)
        k = len(q_rows)
        lr = np.full(k, -1, dtype=np.int64)
        lc = np.full(k, np.inf)
        fr = np.full(k, -1, dtype=np.int64)
        fc = np.full(k, -np.inf)
        m = len(self.keys)
        if not m or not k:
            return lr, lc, fr, fc
        qk = q_corr * self.BIG + q_coord
        pos = np.searchsorted(self.keys, qk, side="right")
        todo = np.ones(k, dtype=bool)
        for j in range(4):
            p = pos + j
            valid = todo & (p < m)
            pc = np.minimum(p, m - 1)
            valid &= self.corr[pc] == q_corr
            hit = valid & (self.rows[pc] != q_rows)
            lr[hit] = self.rows[pc[hit]]
            lc[hit] = self.coord[pc[hit]]
            todo &= ~hit & valid
        todo = np.ones(k, dtype=bool)
        for j in range(1, 5):
            p = pos - j
            valid = todo & (p >= 0)
            pc = np.maximum(p, 0)
            valid &= self.corr[pc] == q_corr
            hit = valid & (self.rows[pc] != q_rows)
            fr[hit] = self.rows[pc[hit]]
            fc[hit] = self.coord[pc[hit]]
            todo &= ~hit & valid
        return lr, lc, fr, fc
