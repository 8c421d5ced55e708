"""Checks of function arguments shared by every layer (the batched worlds,
the experiment runners, the benchmarks, the datasets): each raises
``ValueError`` naming the argument, the value given and what is allowed, in
one wording, ``"name = value; allowed: ..."`` (stop 45: a float seed was
truncated, a string flag taken as True; the checks had one copy per
module)."""

from __future__ import annotations

import numpy as np

__all__ = ["check_int", "check_int_list", "check_float", "check_flag", "check_config"]


def check_int(name: str, v, lo: int) -> int:
    """``v`` as an int if it is an integer (not a bool, not a float) >= ``lo``."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < lo:
        raise ValueError(f"{name} = {v!r}; allowed: an integer >= {lo}")
    return int(v)


def check_int_list(name: str, values, lo: int, what: str = "integers") -> list[int]:
    """``values`` (a list, tuple, range or 1-D array) as a list of ints if
    it is non-empty and each is an integer (not a bool, not a float) >=
    ``lo``; the message names every bad value. (Stop 55: the scaling
    curve's ``sizes`` and ``bench_highway_formation``'s had a check each,
    and the first raised a ``TypeError`` for a bare number.)"""
    allowed = f"allowed: a non-empty list of {what} >= {lo}"
    if not isinstance(values, (list, tuple, range, np.ndarray)) or not len(values):
        raise ValueError(f"{name} = {values!r}; {allowed}")
    values = list(values)
    bad = [v for v in values if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or v < lo]
    if bad:
        raise ValueError(f"{name} = {values!r}; {allowed} (bad: {bad})")
    return [int(v) for v in values]


def check_float(name: str, v, lo: float, *, strict: bool = True, hi: float | None = None, unit: str = "") -> float:
    """``v`` as a float if it is a finite real number (not a bool, not a
    string) ``> lo`` (``>= lo`` with ``strict=False``) and ``<= hi`` if
    given; ``unit`` ends the allowed range in the message (stop 55: the
    benches checked their seconds by hand, one wording each, and some let a
    string or None reach a comparison, a NaN reach ``int()``, or a negative
    window reach the env's config under another name)."""
    ok = (not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.integer, np.floating))
          and np.isfinite(v) and (v > lo if strict else v >= lo) and (hi is None or v <= hi))
    if not ok:
        rng = f"{'>' if strict else '>='} {lo:g}" + (f" and <= {hi:g}" if hi is not None else "")
        raise ValueError(f"{name} = {v!r}; allowed: a finite number {rng}{' ' + unit if unit else ''}")
    return float(v)


def check_flag(name: str, v) -> bool:
    """``v`` as a bool if it is one (a string such as ``"no"`` is not)."""
    if not isinstance(v, (bool, np.bool_)):
        raise ValueError(f"{name} = {v!r}; allowed: True or False")
    return bool(v)


def check_config(config, what: str = "env config") -> dict:
    """``config`` as a new dict: None (empty) or a dict of ``what``."""
    if config is not None and not isinstance(config, dict):
        raise ValueError(f"config = {config!r}; allowed: None or a dict of {what}")
    return dict(config or {})
