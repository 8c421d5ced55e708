"""The benches' clock of numba's compiler (icv_envs/_jit_clock.py, stop 54):
it sees a compilation, sees nothing in a warm process, and the benches take
what it saw out of their timed windows and say so."""

from __future__ import annotations

import argparse

import numba
import numpy as np

from icv_envs._jit_clock import JitClock


def _fresh_kernel():
    """A kernel numba has never compiled (not cached: a new function object each call)."""

    @numba.njit
    def k(x):
        return x.sum() + 1.0

    return k


def test_clock_sees_a_compilation_and_nothing_once_warm():
    k = _fresh_kernel()
    with JitClock() as c:
        k(np.ones(3))
    assert c.compiles == 1 and c.seconds > 0.0  # one kernel called (its inner sum is not counted apart)
    assert 0.0 < c.cpu_seconds  # (the CPU time the benches take out of their CPU clocks)
    # the window it was active in, and that window without the compiler
    assert c.window_seconds >= c.seconds and c.wall == c.window_seconds - c.seconds >= 0.0
    assert c.window_cpu_seconds >= c.cpu_seconds and c.cpu == c.window_cpu_seconds - c.cpu_seconds >= 0.0
    assert "compiled 1 kernel" in c.note() and "excluded" in c.note()
    with JitClock() as warm:
        k(np.ones(5))  # same types: the compiled code
    assert warm.as_dict() == {"jit_seconds_excluded": 0.0, "jit_cpu_seconds_excluded": 0.0, "jit_compiles": 0}
    assert warm.note() == ""
    with JitClock() as new_types:
        k(np.ones(3, dtype=np.int64))
    assert new_types.compiles == 1 and new_types.seconds > 0.0
    # entered again, it adds up; after leaving, it hears nothing
    with c:
        _fresh_kernel()(np.ones(2))
    assert c.compiles == 2
    s = c.seconds
    _fresh_kernel()(np.ones(2))
    assert c.seconds == s and c.compiles == 2


def _steps(make, seed, n):
    env = make()
    env.reset(seed=seed)
    for _ in range(n):
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    return env


def test_the_same_steps_again_compile_nothing():
    """A run repeated in one process holds numba's compiler lock at no step
    (what the benches' warm-ups rely on, and a kernel whose argument types
    changed from call to call would break): the second run of the same
    seed, under the clock, sees nothing."""
    from icv_envs.envs.highway_formation_v0 import parallel_env as highway
    from icv_envs.envs.intersection_v0 import parallel_env as intersection

    makers = [lambda: highway(vehicles_count=12, initial_position=None),
              lambda: intersection(method="multi-vp", throughput=2200.0, duration=40.0)]
    for make in makers:
        _steps(make, 4, 30)
        with JitClock() as c:
            _steps(make, 4, 30)
        assert (c.compiles, c.seconds) == (0, 0.0)


def test_benches_take_the_compiler_out_of_their_windows(monkeypatch):
    """A compilation inside the timed window (here a fresh kernel called by
    the stepper: on a fresh machine, the virtual platoon's kernels) is
    reported and excluded: the intersection bench and the ring's chunks."""
    from icv_envs.experiments import intersection_bench, sumo_bench

    real = intersection_bench._stepper

    def stepper(env, api):
        step = real(env, api)

        def wrapped():
            _fresh_kernel()(np.ones(2))  # a new kernel every step: a compilation every step
            step()

        return wrapped

    monkeypatch.setattr(intersection_bench, "_stepper", stepper)
    out = []
    res = intersection_bench.run_cli(argparse.Namespace(seconds=1.0, warmup=2.0, seeds=1, throughput=None,
                                                        method=None, api="rows"), echo=out.append)
    assert res["jit_compiles"] == res["env_steps"] == 5 and res["jit_seconds_excluded"] > 0
    assert res["per_seed"][0]["jit_compiles"] == 5
    assert 0 < res["cpu_seconds"] and any("excluded" in line for line in out)

    from icv_envs.envs.highway_formation_v0 import parallel_env

    env = parallel_env(vehicles_count=8, initial_position=None)
    env.reset(seed=0)
    sumo_bench._icv_chunk(env, 2)
    r = sumo_bench._icv_chunk(env, 2)
    assert r["jit_compiles"] == 0 and r["jit_seconds_excluded"] == 0.0 and r["cpu"] > 0
    monkeypatch.setattr(sumo_bench, "_icv_steps", lambda env, n, api="dicts": _fresh_kernel()(np.ones(2)))
    r = sumo_bench._icv_chunk(env, 2)
    assert r["jit_compiles"] == 1 and r["jit_seconds_excluded"] > 0


def test_notes_tell_a_compilation_from_a_cache_load():
    from icv_envs._jit_clock import jit_note

    assert jit_note(0.0, 0) == ""
    assert "loading compiled kernels from its cache" in jit_note(0.02, 0) and "first run" not in jit_note(0.02, 0)
    first = jit_note(4.0, 3, "the timed windows")
    assert "compiled 3 kernel(s) inside the timed windows" in first and "quote a second run" in first


def test_clock_is_reentrant_and_leaving_it_twice_changes_nothing():
    c = JitClock()
    with c:
        with c:
            _fresh_kernel()(np.ones(2))
        _fresh_kernel()(np.ones(2))  # still inside the outer entry: counted
    _fresh_kernel()(np.ones(2))  # left: not counted
    c.__exit__(None, None, None)  # left again: nothing
    _fresh_kernel()(np.ones(2))
    assert c.compiles == 2


def test_the_ramps_bench_takes_the_compiler_out_of_its_run(monkeypatch):
    """``icv-envs bench highway-ramps``: a compilation inside the run's loop
    comes out of its wall time; one before the loop (building the env) is
    not the loop's and is not subtracted."""
    from icv_envs.experiments import bench, compare

    real = compare.run_ramps
    seen = {}

    def run(*a, jit=None, **k):
        _fresh_kernel()(np.ones(2))  # before the loop: not the loop's
        s0 = jit.seconds
        m = real(*a, jit=jit, **k)
        seen["before"] = s0
        return m

    monkeypatch.setattr(compare, "run_ramps", run)
    res = bench.bench_highway_ramps(seconds=2.0, echo=lambda s: None)
    assert seen["before"] == 0.0 and res["jit_compiles"] == 0 and res["wall_seconds"] > 0
    assert res["peak_rss_includes_compiler"] is False
    # a compilation at every step of the loop: counted and reported
    from icv_envs.envs.highway_ramps_v0 import HighwayRampsParallelEnv

    ask = HighwayRampsParallelEnv.expert_actions

    def compiling(self):
        _fresh_kernel()(np.ones(2))
        return ask(self)

    monkeypatch.setattr(HighwayRampsParallelEnv, "expert_actions", compiling)
    out = []
    res = bench.bench_highway_ramps(seconds=2.0, echo=out.append)
    assert res["jit_compiles"] == 10 and res["jit_seconds_excluded"] > 0  # 2 s at 5 Hz
    assert any("compiled 10 kernel(s) inside the run" in line for line in out)
    # the peak memory cannot leave the compiler out: it says so
    assert res["peak_rss_includes_compiler"] is True and "includes numba's compiler" in out[-1]


def test_gc_clock_times_collections_by_generation():
    import gc

    from icv_envs._gc_clock import GcClock

    with GcClock() as c:
        a = []
        a.append(a)  # a cycle
        del a
        gc.collect()
    assert c.collections[2] >= 1 and c.seconds[2] > 0.0 and c.total >= c.seconds[2]
    assert c.as_dict("icv_") == {"icv_gc_seconds": c.total, "icv_gc_full_collections": c.collections[2]}
    n = c.collections[2]
    gc.collect()  # left: not counted
    assert c.collections[2] == n and c._callback not in gc.callbacks


def test_time_icv_formation_reports_the_collector():
    from icv_envs.experiments.sumo_bench import time_icv_formation

    r = time_icv_formation(12, seconds=0.4, warmup=0.2)
    assert 0.0 <= r["gc_ms_per_sim_s"] <= r["ms_per_sim_s"] and r["gc_full_collections"] >= 0
