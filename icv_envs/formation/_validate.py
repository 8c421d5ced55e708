"""Input checks shared by the formation algorithms: each raises ValueError
naming the argument, the bad value and what is allowed."""

from __future__ import annotations

import numpy as np

__all__ = ["finite"]


def finite(name: str, value, ndim: int | None = None) -> np.ndarray:
    """``value`` as a float64 array of finite numbers (of ``ndim`` dimensions if given)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of finite numbers, got {value!r}") from None
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.atleast_1d(arr)[~np.isfinite(np.atleast_1d(arr))]
        raise ValueError(f"{name} must be finite, got non-finite value(s) {bad.tolist()}")
    return arr
