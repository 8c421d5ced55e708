"""Time CPython's cyclic garbage collector takes inside a benchmark's window.

Unlike numba's compiler (:mod:`icv_envs._jit_clock`), the collector is a
running cost of this package's Python layer, so the benches report it and
never subtract it. It matters at scale: a full collection (generation 2)
walks every tracked container in the process, about 222k objects once
highway-env (which imports pandas and matplotlib), numba and SciPy are
loaded, about 85 ms each on this project's machine. What triggers them is
the containers a step keeps for a while: the per-agent info dicts (each
holds its nested ``rewards`` dict, which makes CPython track it), about
one per agent a step through PettingZoo's dicts. Measured at stop 54
(``results/bench/stop54/gc_scale.txt``): over 200 steps of
HighwayFormation through the dicts, 3200 agents spent 26.6% of the step
in the collector (five full collections, 425 ms), 1600 agents 14.7% (one,
87 ms); 800 agents 4.0% over 400 steps (none; 13% in another run that
had one), 200 agents none. ``gc.freeze()`` after building the env (the
standard remedy: the objects alive then are never walked again) took
3200 agents from 9.74 to 7.98 ms a step (the collector 6.3%). A library
must not freeze or retune the collector for its users (it would freeze
their objects too); the README says when to do it in a script.

:class:`GcClock` adds up the collector's time by generation while active
(``gc.callbacks``).
"""

from __future__ import annotations

import gc
import time

__all__ = ["GcClock"]


class GcClock:
    """Seconds in the garbage collector while active, and the number of
    collections, by generation (0, 1, 2). A context manager; entered again
    after it was left, it adds more windows."""

    def __init__(self) -> None:
        self.seconds = [0.0, 0.0, 0.0]
        self.collections = [0, 0, 0]
        self._t0 = 0.0
        self._active = False

    def _callback(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._t0 = time.perf_counter()
        else:
            g = int(info["generation"])
            self.seconds[g] += time.perf_counter() - self._t0
            self.collections[g] += 1

    def __enter__(self) -> "GcClock":
        if not self._active:
            gc.callbacks.append(self._callback)
            self._active = True
        return self

    def __exit__(self, *exc) -> None:
        if self._active:
            gc.callbacks.remove(self._callback)
            self._active = False

    @property
    def total(self) -> float:
        """Seconds in all collections."""
        return float(sum(self.seconds))

    def as_dict(self, prefix: str = "") -> dict:
        """JSON fields: ``gc_seconds`` (all generations) and
        ``gc_full_collections`` (generation 2), with ``prefix``."""
        return {f"{prefix}gc_seconds": self.total, f"{prefix}gc_full_collections": int(self.collections[2])}
