"""Argument checks of the experiment runners (``run``, ``compare``; the
general ones, a seed or a flag, are :mod:`icv_envs._args`): each raises ``ValueError`` naming the argument, the value given and what is
allowed (stop 45: a float seed was truncated, a config key that an argument
also sets was silently overridden one way or the other)."""

from __future__ import annotations

import numpy as np

from icv_envs._args import check_config, check_float

__all__ = ["check_run_config", "check_throughput", "check_vgr", "check_workers"]


def check_vgr(vgr) -> float:
    """One run's or bench's VGR (vehicles/s per ramp) as a float in ``(0,
    MAX_VGR]``, checked before the env sees it (a bool or a string became
    1.0 or a ``float()`` error before stop 56); one wording for
    ``run_ramps``, ``bench_highway_ramps`` and ``ramps_vs_sumo``."""
    from icv_envs.envs.highway_ramps import MAX_VGR

    return check_float("vgr", vgr, 0, hi=MAX_VGR, unit="vehicles/s per ramp")


def check_throughput(throughput) -> float:
    """One intersection run's or bench's demand (vehicles/h) as a float in
    ``(0, MAX_THROUGHPUT]`` (as :func:`check_vgr`), for ``run_intersection``
    and ``bench_intersection``."""
    from icv_envs.envs.intersection_config import MAX_THROUGHPUT

    return check_float("throughput", throughput, 0, hi=MAX_THROUGHPUT, unit="vehicles/h")


def check_run_config(config, owned: dict) -> dict:
    """``config``: None or a dict of env config keys, none of which is set by
    an argument of the run (``owned``: config key -> the argument that sets
    it, e.g. ``{"duration": "seconds (--seconds)"}``). Returns a copy."""
    config = check_config(config, "env config keys")
    clash = [k for k in config if k in owned]
    if clash:
        raise ValueError("config key(s) " + ", ".join(f"{k!r} (set by {owned[k]})" for k in clash)
                         + " are the run's own arguments; give them as those arguments, not in config")
    return config


def check_workers(workers, backend: str) -> int | None:
    """``workers``: None (one per core) or an integer >= 1, for the local
    process pool only (Ray schedules on its own cluster)."""
    if workers is None:
        return None
    if isinstance(workers, (bool, np.bool_)) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers = {workers!r}; allowed: an integer >= 1 (or None: one per core)")
    if backend == "ray":
        raise ValueError(f"workers = {workers!r} applies to backend 'process' only; Ray schedules the runs on its "
                         f"cluster's resources")
    return int(workers)
