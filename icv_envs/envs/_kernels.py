"""Compiled loops of the env layer (the rules every kernel follows:
:mod:`icv_envs.sim._kernels`): which actions are the expert's, and one
world's step written into the fixed-K slot arrays of
:class:`icv_envs.vector.BatchedWorlds`."""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["expert_match_rows", "scatter_world_rows", "scatter_expert_rows"]


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
