"""Compiled inner loops of the simulation core (numba, ``@njit(cache=True)``).

Only the loops that array operations cannot express without Python-level
iteration live here: the sweep of the collision broad phase (a loop over
sort-order offsets ``k`` that stops at the first ``k`` with no pair in
reach), the formation layer's per-formation segment reductions and
drivable-lane windows. They take and return plain arrays (no Python objects
inside), and they perform the same IEEE-754 operations, in the same order,
as the numpy code they replace: trajectories stay bit-identical
(``tests/test_trajectory_hash.py`` compares against a reference recorded
before they went in). Floating-point reassociation (``fastmath``) is off
for the same reason.

Why numba: the loops are short, data-dependent and branchy (early exits,
variable-length outputs), which is what a JIT compiles well and what numpy
vectorisation cannot do without materialising every candidate; ``cache=True``
keeps the compiled code on disk, so only the first import on a machine pays
the compile time (a few seconds).
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["sweep_candidates", "segment_max", "drivable_lane_bits"]


@nb.njit(cache=True)
def sweep_candidates(xs, ys, hxs, hys, reach):
    """Broad phase of :func:`icv_envs.sim.traffic.find_collisions` over
    vehicles sorted by ``xs``: pairs ``(a, a + k)`` whose axis-aligned
    bounding boxes overlap, for ``k = 1, 2, ...`` until no pair ``k`` places
    apart is closer in ``x`` than ``reach``. Returns the sorted positions
    ``a`` and the offsets ``k``, ordered by ``k`` then ``a``."""
    n = xs.shape[0]
    cap = 2 * n + 16
    out_a = np.empty(cap, dtype=np.int64)
    out_k = np.empty(cap, dtype=np.int64)
    m = 0
    for k in range(1, n):
        any_near = False
        for a in range(n - k):
            dx = xs[a + k] - xs[a]
            if dx < reach:
                any_near = True
                if dx < hxs[a + k] + hxs[a] and abs(ys[a + k] - ys[a]) < hys[a + k] + hys[a]:
                    if m == cap:
                        cap *= 2
                        na = np.empty(cap, dtype=np.int64)
                        nk = np.empty(cap, dtype=np.int64)
                        na[:m] = out_a[:m]
                        nk[:m] = out_k[:m]
                        out_a, out_k = na, nk
                    out_a[m] = a
                    out_k[m] = k
                    m += 1
        if not any_near:
            break
    return out_a[:m], out_k[:m]


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
