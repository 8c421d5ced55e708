"""The formation layer's segment reductions and drivable-lane windows,
compiled (the rules every kernel here follows:
:mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["segment_max", "drivable_lane_bits"]


@nb.njit(cache=True)
def segment_max(values, starts, ends):
    """``max(values[starts[g]:ends[g]])`` per segment (``-inf`` if empty)."""
    out = np.full(starts.shape[0], -np.inf)
    for g in range(starts.shape[0]):
        best = -np.inf
        for i in range(starts[g], ends[g]):
            if values[i] > best:
                best = values[i]
        out[g] = best
    return out


@nb.njit(cache=True)
def drivable_lane_bits(a, span, x0, x1, periodic, length, lane_ends, ob_lane, ob_lo, ob_hi, allowed):
    """Vectorised :meth:`icv_envs.sim.road.RoadLayout.drivable_main_lanes`
    over many windows, as bit sets (bit ``l`` set = lane ``l`` drivable
    over the whole window and in ``allowed``). On a ring, ``a`` is the
    window start folded onto the road and ``span`` its clipped length (both
    computed by the caller with numpy, as the scalar code does); on a
    straight road ``x0``/``x1`` are the window ends."""
    G = a.shape[0]
    n_lanes = lane_ends.shape[0]
    out = np.zeros(G, dtype=np.int64)
    p0s = np.empty(2)
    p1s = np.empty(2)
    for g in range(G):
        if periodic:
            if a[g] + span[g] <= length:
                npc = 1
                p0s[0] = a[g]
                p1s[0] = a[g] + span[g]
            else:
                npc = 2
                p0s[0] = a[g]
                p1s[0] = length
                p0s[1] = 0.0
                p1s[1] = a[g] + span[g] - length
        else:
            npc = 1
            lo = max(x0[g], 0.0)
            p0s[0] = lo
            p1s[0] = max(x1[g], lo)
        bits = 0
        for lane in range(n_lanes):
            if not allowed[lane]:
                continue
            ok = True
            for p in range(npc):
                if not lane_ends[lane] > p1s[p]:
                    ok = False
                    break
                for o in range(ob_lane.shape[0]):
                    if ob_lane[o] == lane and ob_hi[o] >= p0s[p] and ob_lo[o] <= p1s[p]:
                        ok = False
                        break
                if not ok:
                    break
            if ok:
                bits |= 1 << lane
        out[g] = bits
    return out
