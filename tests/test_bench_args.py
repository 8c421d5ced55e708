"""Bad arguments to the benches' Python functions (stop 55): each raises
``ValueError`` naming the argument and what is allowed, before anything
runs. Before, a string or None reached a comparison (``TypeError``), ``chunks=0``
divided by zero, a NaN reached ``int()``, a float seed reached Gymnasium's
seeding, and a negative window was reported as the env's
``config['duration']`` or ``config['road_length']``, values the caller never
gave. :func:`icv_envs._args.check_float` is the one check they share."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from icv_envs._args import check_float
from icv_envs.experiments import bench, intersection_bench, sumo_bench
from icv_envs.experiments import intersection_compare
from icv_envs.experiments.compare import run_ramps, validate_grid
from icv_envs.experiments.run import run_highway_formation

BAD_SECONDS = ["x", None, float("nan"), float("inf"), -1.0, 0, True, [1.0]]


@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6)),
       st.floats(-100, 100), st.booleans())
def test_check_float_accepts_exactly_the_finite_numbers_in_range(v, lo, strict):
    ok = math.isfinite(v) and (v > lo if strict else v >= lo)
    if ok:
        assert check_float("x", v, lo, strict=strict) == float(v)
    else:
        with pytest.raises(ValueError, match=r"^x = .*; allowed: a finite number >"):
            check_float("x", v, lo, strict=strict)


def test_check_float_upper_bound_types_and_unit():
    assert check_float("vgr", np.float32(0.5), 0, hi=1.0) == 0.5
    assert check_float("n", np.int64(3), 0) == 3.0
    for v in (1.5, "0.5", True, np.bool_(True), complex(1, 0), np.array([0.5])):
        with pytest.raises(ValueError, match=r"allowed: a finite number > 0 and <= 1 vehicles/s per ramp"):
            check_float("vgr", v, 0, hi=1.0, unit="vehicles/s per ramp")


@pytest.mark.parametrize("v", BAD_SECONDS)
@pytest.mark.parametrize("call", [
    lambda v: intersection_bench.bench_intersection(seconds=v),
    lambda v: sumo_bench.ramps_vs_sumo(seconds=v),
    lambda v: sumo_bench.scaling(seconds=v),
    lambda v: sumo_bench.time_icv_formation(10, seconds=v),
    lambda v: sumo_bench.time_sumo(10, seconds=v),
    lambda v: bench.time_icv(10, seconds=v),
    lambda v: bench.time_highway_v0(10, seconds=v),
    lambda v: bench.bench_highway_formation(sizes=[10], seconds=v),
    lambda v: bench.bench_highway_ramps(seconds=v),
    lambda v: validate_grid(["formation"], [0.2], 1, v),
    lambda v: intersection_compare.validate_grid(["fcfs"], [1500.0], 1, v),
    lambda v: run_highway_formation(seconds=v),
], ids=["intersection", "ramps_vs_sumo", "scaling", "time_icv_formation", "time_sumo", "time_icv",
        "time_highway_v0", "bench_highway_formation", "bench_highway_ramps", "compare", "intersection_compare", "run"])
def test_bad_seconds_are_named(call, v):
    with pytest.raises(ValueError, match=r"^seconds = .*; allowed: a finite number > 0"):
        call(v)


@pytest.mark.parametrize("call, match", [
    (lambda: intersection_bench.bench_intersection(seconds=1, warmup=None), r"^warmup = None; allowed: a finite number >= 0"),
    (lambda: intersection_bench.bench_intersection(seconds=1, warmup=0, seeds=1.0), r"^seeds = 1.0; allowed: an integer >= 1"),
    (lambda: sumo_bench.ramps_vs_sumo(measure="10"), r"^measure = '10'; allowed: a finite number > 0"),
    (lambda: sumo_bench.ramps_vs_sumo(chunks=0), r"^chunks = 0; allowed: an integer >= 1"),
    (lambda: sumo_bench.ramps_vs_sumo(seed=1.5), r"^seed = 1.5; allowed: an integer >= 0"),
    (lambda: sumo_bench.ramps_vs_sumo(sumo_warmup=float("nan")), r"^sumo_warmup = nan; allowed: a finite number >= 0"),
    (lambda: sumo_bench.ramps_vs_sumo(vgr=2.0), r"^vgr = 2.0; allowed: a finite number > 0 and <= 1 vehicles/s"),
    (lambda: bench.bench_highway_ramps(vgr="a"), r"^vgr = 'a'; allowed: a finite number > 0 and <= 1"),
    (lambda: sumo_bench.time_icv_formation(0), r"^n = 0; allowed: an integer >= 1"),
    (lambda: sumo_bench.time_sumo(10, warmup=-1), r"^warmup = -1; allowed: a finite number >= 0"),
    (lambda: bench.time_icv(10.5), r"^n = 10.5; allowed: an integer >= 1"),
    (lambda: bench.bench_highway_formation(sizes=[10, 0]), r"^sizes = \[10, 0\]; allowed: a non-empty list of vehicle counts >= 1 \(bad: \[0\]\)$"),
    (lambda: bench.bench_highway_formation(sizes=[]), r"^sizes = \[\]; allowed: a non-empty list"),
    (lambda: bench.bench_highway_formation(sizes=800), r"^sizes = 800; allowed: a non-empty list"),
    (lambda: sumo_bench.scaling(sizes=800), r"^sizes = 800; allowed: a non-empty list of vehicle counts >= 1$"),
    (lambda: bench.bench_highway_formation(sizes=[10], stock_seconds=0), r"^stock_seconds = 0; allowed"),
])
def test_bad_bench_arguments_are_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@pytest.mark.parametrize("v", ["x", None, True, float("nan"), -1.0, 0, 2.0, [0.3]])
def test_run_ramps_vgr_is_checked(v):
    """``run_ramps`` (``icv-envs bench highway-ramps``, the sweeps' runs)
    converted ``vgr`` with ``float()`` before the env saw it (stop 56): a
    string or None raised float()'s own error, and ``True`` ran at 1.0."""
    with pytest.raises(ValueError, match=r"^vgr = .*; allowed: a finite number > 0 and <= 1 vehicles/s per ramp"):
        run_ramps("formation", v, 0, 1.0)


@pytest.mark.parametrize("call", [
    lambda v: intersection_compare.run_intersection("multi-vp", v, 0, 1.0),
    lambda v: intersection_bench.bench_intersection(seconds=1.0, throughput=v, warmup=0, seeds=1),
], ids=["run_intersection", "bench_intersection"])
@pytest.mark.parametrize("v", ["x", None, True, float("inf"), -5, 0, 20001.0])
def test_intersection_throughput_is_checked(call, v):
    """The intersection's runs converted ``throughput`` with ``float()``
    (stop 56): ``True`` ran at 1 vehicle/h."""
    with pytest.raises(ValueError, match=r"^throughput = .*; allowed: a finite number > 0 and <= 20000 vehicles/h"):
        call(v)


@pytest.mark.parametrize("call", [
    lambda v: intersection_compare.run_intersection("multi-vp", 1000.0, 0, v),
    lambda v: run_ramps("formation", 0.2, 0, v),
], ids=["run_intersection", "run_ramps"])
@pytest.mark.parametrize("v", BAD_SECONDS)
def test_single_runs_name_bad_seconds(call, v):
    """One run's ``seconds`` was reported as the env's ``config['duration']``
    or raised float()'s own error (stop 56)."""
    with pytest.raises(ValueError, match=r"^seconds = .*; allowed: a finite number > 0"):
        call(v)
