"""Compiled loops of the env layer (the rules every kernel follows:
:mod:`icv_envs.sim._kernels`): which actions are the expert's, and one
world's step written into the fixed-K slot arrays of
:class:`icv_envs.vector.BatchedWorlds`, and which on-ramp spawn points are
occupied."""

from __future__ import annotations

import numba as nb
import numpy as np

from icv_envs.sim._kernels.formation import _wrap1
from icv_envs.sim._kernels.physics import lane_of1

__all__ = ["expert_match_rows", "scatter_world_rows", "scatter_expert_rows", "ramp_spawns_blocked"]


@nb.njit(cache=True)
def expert_match_rows(acts, ex, tol):
    """Per row, whether both components of ``acts`` (float64) are within
    ``tol`` of the expert's ``ex`` (float32, widened exactly):
    ``np.all(np.abs(acts - ex) <= tol, axis=1)`` in one pass (a NaN
    difference is no match, as there)."""
    n = acts.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for i in range(n):
        ok = True
        for k in range(acts.shape[1]):
            if not abs(acts[i, k] - np.float64(ex[i, k])) <= tol:
                ok = False
        out[i] = ok
    return out


@nb.njit(cache=True)
def scatter_world_rows(obs, mask, rewards, terminated, truncated, b, k, o_obs, o_rew, o_term, o_trunc):
    """World ``b``'s step into the batch's slot arrays, in place: its
    observations zeroed and its mask cleared, then for each returned row
    ``q`` (slot ``k[q]``, the slots distinct) the observation ``o_obs[q]``
    (``obs`` is ``(B, K, D)`` and ``o_obs`` ``(n, D)``: the observation
    flattened), reward, terminated and truncated flags, and the mask set
    where the agent neither terminated nor truncated. The assignments of
    the numpy code it replaced (``BatchedWorlds.step`` before stop 38),
    element by element: values are copied, never computed."""
    K = obs.shape[1]
    D = obs.shape[2]
    for s in range(K):
        mask[b, s] = False
        for d in range(D):
            obs[b, s, d] = 0.0
    for q in range(k.shape[0]):
        s = k[q]
        for d in range(D):
            obs[b, s, d] = o_obs[q, d]
        rewards[b, s] = o_rew[q]
        terminated[b, s] = o_term[q]
        truncated[b, s] = o_trunc[q]
        mask[b, s] = not (o_term[q] or o_trunc[q])


@nb.njit(cache=True)
def scatter_expert_rows(out, b, k, ex):
    """World ``b``'s expert actions into the batch's ``(B, K, 2)`` array, in
    place: zeros, then row ``q`` of ``ex`` into slot ``k[q]``."""
    for s in range(out.shape[1]):
        out[b, s, 0] = 0.0
        out[b, s, 1] = 0.0
    for q in range(k.shape[0]):
        out[b, k[q], 0] = ex[q, 0]
        out[b, k[q], 1] = ex[q, 1]


@nb.njit(cache=True)
def ramp_spawns_blocked(cx, cy, lane_width, total_lanes, ramp_lane, x0, length, lo, hi):
    """``HighwayRampsEnv._spawn_due``'s test of every on-ramp's spawn point
    at once (from stop 56; before, one NumPy expression per ramp and step):
    spawn point ``k`` is occupied when a vehicle in the ramp lane
    (:meth:`~icv_envs.sim.road.RoadLayout.lane_of` of ``cy``) lies strictly
    between ``lo`` and ``hi`` metres of ``x0[k]`` along the road
    (:meth:`~icv_envs.sim.road.RoadLayout.wrap` of ``cx - x0[k]``; ``length
    < 0`` on a straight road). The same subtraction, wrap and comparisons as
    the NumPy code, element by element."""
    m = x0.shape[0]
    out = np.zeros(m, dtype=np.bool_)
    for i in range(cx.shape[0]):
        if lane_of1(cy[i], lane_width, total_lanes) != ramp_lane:
            continue
        for k in range(m):
            if not out[k]:
                d = _wrap1(cx[i] - x0[k], length)
                if d > lo and d < hi:
                    out[k] = True
    return out
