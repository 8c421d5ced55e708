"""The parameter checks both experts make once, when they are built, for the
paper's control laws they then call unchecked (issue 10): the vehicle model
of the pure-pursuit steering (wheelbase, steering limit) and the gains of
the longitudinal feedback law (paper eq. (22); ``kp, kv < 0`` because ``X``
points forward). Each error names the parameters' class and the bad value."""

from __future__ import annotations

import numpy as np

__all__ = ["real_param", "check_steering_and_gains"]


def real_param(cls: str, name: str, v) -> float:
    """``v`` as a float; an error naming ``cls.name`` if it is not a finite real number."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
        raise ValueError(f"{cls}.{name} = {v!r}; allowed: a finite number")
    return float(v)


def check_steering_and_gains(p, cls: str) -> None:
    """``p.wheelbase > 0``, ``0 < p.steer_max < pi/2``, ``p.kp < 0`` and ``p.kv < 0``."""
    if not real_param(cls, "wheelbase", p.wheelbase) > 0.0:
        raise ValueError(f"{cls}.wheelbase = {p.wheelbase!r}; allowed: > 0 metres")
    if not 0.0 < real_param(cls, "steer_max", p.steer_max) < 0.5 * np.pi:
        raise ValueError(f"{cls}.steer_max = {p.steer_max!r}; allowed: in (0, pi/2) rad")
    for name in ("kp", "kv"):
        if not real_param(cls, name, getattr(p, name)) < 0.0:
            raise ValueError(f"{cls}.{name} = {getattr(p, name)!r}; allowed: < 0 (X points forward, "
                             f"a positive gain is unstable)")
