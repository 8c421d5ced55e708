"""Time spent in numba's compiler inside a benchmark's timed window.

The kernels are compiled with numba's on-disk cache on: the first process on a machine (or
after a kernel's source changed) compiles each one at its first call and
writes it to numba's on-disk cache; later processes load it from there
(about a millisecond each). Either happens at the first call, which a
benchmark's warm-up usually covers, but not always: the intersection's
virtual-platoon kernels are first called when the first node forms, more
than 50 s into a run, and the single-agent env's bench times from the
first step. On a fresh machine ``icv-envs bench intersection --warmup 50``
then timed about 4-5 s of compilation with 0.3 s of stepping and reported
5,629-6,000 agent-steps per CPU second instead of 75k-87k (stop 54,
``results/bench/stop54/``).

:class:`JitClock` measures that time: while it is active it adds up the
time numba spends holding its global compiler lock, in wall time and in
this process's CPU time (the event
``numba:compiler_lock``, which covers a cache load, a compilation and the
cache write after it, each exactly once however deep the nesting) and
counts the compilations (the outermost events ``numba:compile``, fired
only on a cache miss: the kernels called, not the functions compiled
inside them). A benchmark times its window with the clock itself: the
window's CPU seconds less :attr:`JitClock.cpu_seconds`
(:attr:`JitClock.cpu`) and its wall seconds less :attr:`JitClock.seconds`
(:attr:`JitClock.wall`; numba compiles in the calling thread; on a loaded
machine the wall time of a compilation exceeds its CPU time, and
subtracting it from CPU time could leave a negative window), and reports
both, so what it prints is the simulator's
steady rate and says how much was taken out. Steps a process has run
before hold the lock at none of their calls (``tests/test_jit_clock.py``);
a new process loads each kernel from the cache at its first call (0.02 s
in all on the intersection's window after its warm-up, 0.17 s in the
single-agent env's first steps: measured at stop 54).

Decision (stop 54), as the engineers of a JIT-compiled simulator would:
the compiler's one-off cost is not the simulator's speed; it is excluded
and reported, never silently included. Re-running the window instead
would be exact but doubles the bench's time on every first run.
"""

from __future__ import annotations

import time

from numba.core import event

__all__ = ["JitClock", "jit_note", "rss_note"]


class JitClock(event.Listener):
    """Seconds in numba's compiler and compilations while active (module
    docstring), and the windows it was active in. A re-entrant context
    manager (a window runs from the outermost entry to its exit); entered
    again after it was left, it adds more windows (every figure
    accumulates). A bench times its window with it: :attr:`wall` and
    :attr:`cpu` are the windows' seconds without the compiler's."""

    def __init__(self) -> None:
        self.seconds = 0.0  # wall seconds
        self.cpu_seconds = 0.0  # this process's CPU seconds
        self.compiles = 0
        self._depth = 0
        self._t0 = 0.0
        self._c0 = 0.0
        self._entered = 0
        self.window_seconds = 0.0  # the windows' wall seconds, compiler included
        self.window_cpu_seconds = 0.0  # and their CPU seconds
        self._w0 = (0.0, 0.0)
        self._compile = _CompileCounter(self)

    # -- numba's listener protocol (the compiler lock is re-entrant: only the outermost pair counts)
    def on_start(self, ev) -> None:
        if self._depth == 0:
            self._t0 = event.timer()
            self._c0 = time.process_time()
        self._depth += 1

    def on_end(self, ev) -> None:
        self._depth -= 1
        if self._depth == 0:
            self.seconds += event.timer() - self._t0
            self.cpu_seconds += time.process_time() - self._c0

    def __enter__(self) -> "JitClock":
        # (re-entrant: it listens from the outermost entry to the matching exit)
        if self._entered == 0:
            event.register("numba:compiler_lock", self)
            event.register("numba:compile", self._compile)
            self._w0 = (event.timer(), time.process_time())
        self._entered += 1
        return self

    def __exit__(self, *exc) -> None:
        if self._entered == 0:  # (leaving a clock not entered changes nothing)
            return
        self._entered -= 1
        if self._entered == 0:
            self.window_seconds += event.timer() - self._w0[0]
            self.window_cpu_seconds += time.process_time() - self._w0[1]
            event.unregister("numba:compile", self._compile)
            event.unregister("numba:compiler_lock", self)

    @property
    def wall(self) -> float:
        """The windows' wall seconds without the compiler's (read after the window closed)."""
        return self.window_seconds - self.seconds

    @property
    def cpu(self) -> float:
        """The windows' CPU seconds without the compiler's (read after the window closed)."""
        return self.window_cpu_seconds - self.cpu_seconds

    def as_dict(self) -> dict:
        """The JSON fields a bench reports: ``jit_seconds_excluded`` (wall),
        ``jit_cpu_seconds_excluded``, ``jit_compiles``."""
        return {"jit_seconds_excluded": float(self.seconds), "jit_cpu_seconds_excluded": float(self.cpu_seconds),
                "jit_compiles": int(self.compiles)}

    def note(self, where: str = "the timed window") -> str:
        """A line for the bench's output when numba held its compiler lock
        inside ``where``; empty otherwise (:func:`jit_note`)."""
        return jit_note(self.seconds, self.compiles, where)


def jit_note(seconds: float, compiles: int, where: str = "the timed window") -> str:
    """What a bench prints about the compiler time it excluded: ``seconds``
    in numba's compiler lock, ``compiles`` kernels compiled (not loaded
    from the cache); empty when ``seconds`` is 0."""
    if seconds <= 0.0:
        return ""
    if compiles:
        return (f"(numba compiled {compiles} kernel(s) inside {where} (a first run on this machine, or kernels "
                f"changed) and spent {seconds:.2f} s in its compiler, cache loads included: excluded from the figures "
                f"above; a first run can still run lower than the next, so quote a second run)")
    return (f"(numba spent {seconds:.3f} s loading compiled kernels from its cache inside {where}: excluded from "
            f"the figures above)")


def rss_note(compiles: int) -> str:
    """What a bench prints when its peak memory includes a first run's
    compilation of ``compiles`` kernels (the peak cannot leave it out)."""
    return (f"(the peak RSS includes numba's compiler, which compiled {compiles} kernel(s) in this run: a run with "
            f"the kernels in its cache peaks lower; stop 54, the 600 s ring: 643 MB on a first run, 326 MB on the next)")


class _CompileCounter(event.Listener):
    """Counts ``numba:compile`` events (cache misses) for its clock."""

    def __init__(self, clock: JitClock) -> None:
        self._clock = clock
        self._depth = 0

    def on_start(self, ev) -> None:
        # (only the outermost: compiling a kernel compiles the functions it calls inside the same event)
        if self._depth == 0:
            self._clock.compiles += 1
        self._depth += 1

    def on_end(self, ev) -> None:
        self._depth -= 1
