"""The physics substep and the road surface, compiled: the bicycle-model
integration fused with the standing time and the body centres, the
drivable-surface and road-end check, lane interval ends and availability
(the rules every kernel here follows: :mod:`icv_envs.sim._kernels`)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from icv_envs.formation._kernels import clip1

__all__ = ["npy_mod", "npy_maximum", "npy_minimum", "lane_of1", "lane_of_rows", "controls_rows", "cos_sin_rows", "kinematic_substep", "kinematic_substep_carry", "kinematic_substep_into", "road_check", "interval_ends",
           "interval_ends_at", "lanes_available"]


@nb.njit(cache=True, inline="always")
def npy_mod(a, b):
    """``numpy.mod`` of two floats, NumPy's own algorithm (``npy_divmod``):
    ``fmod`` then a shift by ``b`` when the signs differ, ``+0`` with the
    sign of ``b`` for an exact multiple. For ``0 < a < b`` that is ``a``
    itself (``fmod`` is exact), returned without the ``fmod`` call (glibc's
    costs tens of ns: the observations fold every neighbour's distance)."""
    if a > 0.0 and a < b:
        return a
    m = np.fmod(a, b)
    if m != 0.0:
        if (b < 0.0) != (m < 0.0):
            m += b
    else:
        m = math.copysign(0.0, b)
    return m


@nb.njit(cache=True, inline="always")
def npy_maximum(a, b):
    """``numpy.maximum`` of two floats: NaN if either is, ``b`` on a tie."""
    if a != a or b != b:
        return a + b
    return a if a > b else b


@nb.njit(cache=True, inline="always")
def npy_minimum(a, b):
    """``numpy.minimum`` of two floats: NaN if either is, ``b`` on a tie."""
    if a != a or b != b:
        return a + b
    return a if a < b else b


@nb.njit(cache=True)
def cos_sin_rows(h):
    """``(2, n)``: libm's ``cos`` and ``sin`` of the headings ``h`` by rows
    (:meth:`icv_envs.sim.traffic.Traffic.heading_cos_sin` when the compiled
    substeps did not leave them; the same calls as theirs, from stop 51:
    NumPy's ``cos`` and ``sin`` before, whose AVX-512 loops may round
    differently, the kernels' rule)."""
    n = h.shape[0]
    out = np.empty((2, n))
    for i in range(n):
        out[0, i] = math.cos(h[i])
        out[1, i] = math.sin(h[i])
    return out


@nb.njit(cache=True)
def controls_rows(acts, a_min, a_max, steer_max):
    """:func:`icv_envs.envs.actions.action_to_controls` of ``(n, 2)``
    normalised actions in one pass (paper Sec. 2.2 limits): each clipped to
    ``[-1, 1]`` as numpy's clip does, the acceleration ``u_a a_max`` for
    ``u_a >= 0`` and ``-u_a a_min`` below, the steering angle ``u_s
    steer_max``; the same operations on the same values as the array code
    (``tests/test_kernels.py``). Returns ``(a, phi)``."""
    n = acts.shape[0]
    a = np.empty(n)
    phi = np.empty(n)
    for i in range(n):
        ua = clip1(acts[i, 0], -1.0, 1.0)
        us = clip1(acts[i, 1], -1.0, 1.0)
        a[i] = ua * a_max if ua >= 0 else -ua * a_min
        phi[i] = us * steer_max
    return a, phi


@nb.njit(cache=True)
def kinematic_substep(x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase, lat_accel_max,
                      dt, v_max, period):
    """One forward-Euler step of the rear-axle kinematic bicycle model for
    every vehicle, fused (:meth:`icv_envs.sim.world.World.substep` with
    :meth:`icv_envs.sim.traffic.Traffic.step` and
    :func:`icv_envs.sim.traffic.limit_steering`, paper Sec. 2.2): a crashed
    vehicle brakes at -6 m/s^2 with the wheels straight; the steering angle
    is limited by the lateral acceleration ``v^2 tan(phi) / L <=
    lat_accel_max`` (``lat_accel_max < 0``: no limit); speed is kept in
    ``[0, v_max]``; ``x`` is folded onto a ring of length ``period``
    (``period <= 0``: no ring). Also the standing time (speed < 0.1 m/s)
    and the body centres of the new state (``wheelbase / 2`` ahead of the
    rear axle, ``cx`` folded on a ring), as :meth:`Traffic.center`.

    Returns ``(x, y, heading, speed, accel, steer, stopped_for, cx, cy)``
    as new arrays (the inputs are not touched)."""
    # (:func:`kinematic_substep_carry`'s first frame: every sine, cosine and
    # tangent computed, the carried values written to a scratch array)
    return kinematic_substep_carry(x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase,
                                   lat_accel_max, dt, v_max, period, np.empty((4, x.shape[0])), True)


@nb.njit(cache=True)
def kinematic_substep_carry(x, y, heading, speed, accel, steer, crashed, stopped_for, wheelbase, lat_accel_max,
                            dt, v_max, period, trig, first):
    """:func:`kinematic_substep` for the frames of one call with the same
    controls (from stop 43), carrying from frame to frame what they repeat:
    ``trig (4, n)`` holds by rows ``cos`` and ``sin`` of each vehicle's
    heading, its last steering angle ``s`` and ``tan(s)``. ``first``: fill
    them (the first frame); after it the heading's cosine and sine are those
    of the new heading the frame before computed for the body centre (the
    same double, the same ``math`` call), and ``tan(s)`` is computed again
    only when ``s`` changed (bit for bit: the sign of a zero counts). So the
    same numbers as :func:`kinematic_substep`, with two or three sines,
    cosines and tangents fewer per vehicle and frame. On return ``trig``
    holds the new headings' cosines and sines (the collision test's).
    Returns nine new arrays (:func:`kinematic_substep_into` writes them)."""
    n = x.shape[0]
    out = (np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
           np.empty(n))
    kinematic_substep_into(out[0], out[1], out[2], out[3], out[4], out[5], out[6], out[7], out[8], x, y, heading,
                           speed, accel, steer, crashed, stopped_for, wheelbase, lat_accel_max, dt, v_max, period,
                           trig, first)
    return out


@nb.njit(cache=True)
def kinematic_substep_into(nx, ny, nh, nv, na, ns, nst, cx, cy, x, y, heading, speed, accel, steer, crashed,
                           stopped_for, wheelbase, lat_accel_max, dt, v_max, period, trig, first):
    """:func:`kinematic_substep_carry` writing the new ``x, y, heading,
    speed, accel, steer, stopped_for, cx, cy`` into the arrays given first
    (from stop 52: the frames of one compiled call write into two sets of
    arrays in turn instead of nine new ones per frame; none of them may be
    an input)."""
    n = x.shape[0]
    lat_wb = lat_accel_max * wheelbase
    half = 0.5 * wheelbase
    for i in range(n):
        a = accel[i]
        s = steer[i]
        if crashed[i]:
            a = -6.0
            s = 0.0
        v = speed[i]
        if lat_accel_max >= 0.0:
            v2 = max(v * v, 1e-9)
            z = lat_wb / v2
            # (the limit pm = atan(z) binds only for |s| >= pm; atan(z) >= z /
            # (1 + z) for z >= 0, so below 0.99 of that bound, far above the
            # roundings of both sides, the clip leaves s as it is and atan is
            # not called: the same s, bit for bit, without libm's atan for
            # almost every vehicle and frame; from stop 52)
            if not abs(s) <= 0.99 * z / (1.0 + z):
                pm = math.atan(z)
                s = min(max(s, -pm), pm)
        h = heading[i]
        if first:
            ch = math.cos(h)
            sh = math.sin(h)
            ts = math.tan(s)
        else:
            ch = trig[0, i]
            sh = trig[1, i]
            s0 = trig[2, i]
            if s == s0 and math.copysign(1.0, s) == math.copysign(1.0, s0):
                ts = trig[3, i]
            else:
                ts = math.tan(s)
        xi = x[i] + v * ch * dt
        nyi = y[i] + v * sh * dt
        hi = h + v * ts / wheelbase * dt
        vi = min(max(v + a * dt, 0.0), v_max)
        if period > 0.0:
            xi = npy_mod(xi, period)
        nx[i] = xi
        ny[i] = nyi
        nh[i] = hi
        nv[i] = vi
        na[i] = a
        ns[i] = s
        nst[i] = stopped_for[i] + dt if vi < 0.1 else 0.0
        chi = math.cos(hi)
        shi = math.sin(hi)
        c = xi + half * chi
        if period > 0.0:
            c = npy_mod(c, period)
        cx[i] = c
        cy[i] = nyi + half * shi
        trig[0, i] = chi
        trig[1, i] = shi
        trig[2, i] = s
        trig[3, i] = ts


@nb.njit(cache=True)
def lane_of1(y, lane_width, total_lanes):
    """``RoadLayout.lane_of`` of one lateral position: ``rint(y /
    lane_width)`` clipped to ``[0, total_lanes - 1]``."""
    li = np.rint(y / lane_width)
    li = min(max(li, 0.0), total_lanes - 1.0)
    return np.int64(li)


@nb.njit(cache=True)
def lane_of_rows(y, lane_width, total_lanes):
    """``RoadLayout.lane_of`` of a 1-D float64 array of finite lateral
    positions (:func:`lane_of1` of each; NumPy's five calls on a state's
    ``cy`` in one)."""
    out = np.empty(y.shape[0], dtype=np.int64)
    for i in range(y.shape[0]):
        out[i] = lane_of1(y[i], lane_width, total_lanes)
    return out


@nb.njit(cache=True)
def road_check(cx, cy, lane_width, n_lanes, total_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv, edge_margin,
               road_end):
    """Per vehicle: the lane whose centre is nearest
    (:meth:`icv_envs.sim.road.RoadLayout.lane_of`) and whether the body
    centre is off the drivable surface there: the lane is not available at
    ``cx`` (:meth:`RoadLayout.available`: a main lane past its end or inside
    an obstacle's interval, a ramp lane outside every ramp interval) or
    more than ``lane_width / 2 + edge_margin`` beside the lane centre.
    ``cx`` is already folded onto a ring. Also whether it has reached the
    end of a straight road (``cx >= road_end``; ``inf`` on a ring), and
    then it is not off the road. Returns ``(lane, off, at_end, n_off,
    n_at_end)``."""
    n = cx.shape[0]
    off = np.empty(n, dtype=np.bool_)
    at_end = np.empty(n, dtype=np.bool_)
    lane = lane_of_rows(cy, lane_width, total_lanes)
    ok = lanes_available(lane, cx, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    n_off = 0
    n_end = 0
    for i in range(n):
        ln = lane[i]
        x = cx[i]
        o = (not ok[i]) or abs(cy[i] - ln * lane_width) > 0.5 * lane_width + edge_margin
        e = x >= road_end
        at_end[i] = e
        off[i] = o and not e
        n_off += off[i]
        n_end += e
    return lane, off, at_end, n_off, n_end


@nb.njit(cache=True)
def interval_ends(lane, x, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv):
    """:meth:`icv_envs.sim.road.RoadLayout._interval_end` compiled, over
    flat arrays: where the drivable stretch of ``lane`` containing (or
    following) ``x`` ends. A main lane: its end, or the rear of the
    nearest obstacle in it whose front is at or ahead of ``x``, whichever
    comes first; the ramp lane (``n_lanes``): the end of the first ramp
    interval whose end is at or ahead of ``x`` (``inf`` if none, ``-inf``
    without ramps); any other lane: ``-inf``."""
    n = lane.shape[0]
    out = np.empty(n)
    n_ob = ob_lane.shape[0]
    n_ramps = ramp_iv.shape[0]
    for i in range(n):
        ln = lane[i]
        xi = x[i]
        end = -np.inf
        if ln >= 0 and ln < n_lanes:
            cand = np.inf
            for o in range(n_ob):
                if ob_lane[o] == ln and ob_hi[o] >= xi and ob_lo[o] < cand:
                    cand = ob_lo[o]
            e = lane_ends[ln]
            end = e if e <= cand else cand
        elif ln == n_lanes and n_ramps:
            cand = np.inf
            for r in range(n_ramps):
                if ramp_iv[r, 1] >= xi and ramp_iv[r, 1] < cand:
                    cand = ramp_iv[r, 1]
            end = cand
        out[i] = end
    return out


@nb.njit(cache=True)
def lanes_available(lane, x, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv):
    """:meth:`icv_envs.sim.road.RoadLayout.available` compiled, over flat
    arrays (``x`` already folded onto a ring): whether lane ``lane[i]`` is
    drivable at ``x[i]``: a main lane from 0 to its end, outside every
    obstacle's closed interval in it; the ramp lane (``n_lanes``) inside a
    ramp interval (closed); any other lane never.

    The rule is written once, here, over arrays, as is
    :func:`interval_ends`'s: a helper taking the road's arrays and looping
    over them, called once per vehicle inside a compiled loop, cost about
    75 ns a call (measured, with or without ``inline="always"``; the ring,
    442 vehicles: :func:`road_check` 37 -> 3 us), so the kernels that need the
    rule for many vehicles call these once."""
    n = lane.shape[0]
    out = np.empty(n, dtype=np.bool_)
    n_ob = ob_lane.shape[0]
    n_ramps = ramp_iv.shape[0]
    for i in range(n):
        ln = lane[i]
        xi = x[i]
        ok = False
        if ln >= 0 and ln < n_lanes:
            ok = xi >= 0.0 and xi < lane_ends[ln]
            if ok:
                for o in range(n_ob):
                    if ob_lane[o] == ln and xi >= ob_lo[o] and xi <= ob_hi[o]:
                        ok = False
                        break
        elif ln == n_lanes:
            for r in range(n_ramps):
                if xi >= ramp_iv[r, 0] and xi <= ramp_iv[r, 1]:
                    ok = True
                    break
        out[i] = ok
    return out


@nb.njit(cache=True)
def interval_ends_at(lane, x, period, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv):
    """``RoadLayout.interval_end(lane, x)`` compiled: :func:`interval_ends`
    at ``mod(x, period)``, moved back by ``x - mod(x, period)`` on a ring
    (``period < 0``: a straight road, ``x`` as it is)."""
    if period < 0.0:
        return interval_ends(lane, x, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    n = x.shape[0]
    xm = np.empty(n)
    for i in range(n):
        xm[i] = npy_mod(x[i], period)
    out = interval_ends(lane, xm, n_lanes, lane_ends, ob_lane, ob_lo, ob_hi, ramp_iv)
    for i in range(n):
        out[i] = out[i] + (x[i] - xm[i])
    return out


