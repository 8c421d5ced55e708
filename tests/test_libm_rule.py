"""The premise of the kernels' transcendental rule (icv_envs/sim/_kernels/__init__.py,
from stop 49): at X86_V3, the level the reference fingerprints are pinned at,
NumPy's float64 transcendental ufuncs give libm's values, which numba's
compiled code calls, so a kernel may take those steps itself without changing
a pinned trajectory. A NumPy whose AVX2 loops stopped calling libm would fail
here (the full measurement: results/bench/stop49/libm_vs_numpy.py)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from pinned_numpy import at_pinned_level


@nb.njit(cache=False)
def _libm(x, y, which):
    out = np.empty(x.size)
    for i in range(x.size):
        v = x[i]
        if which == 0:
            out[i] = math.exp(v)
        elif which == 1:
            out[i] = v ** 3.0
        elif which == 2:
            out[i] = v ** 5.0
        elif which == 3:
            out[i] = math.asinh(v)
        elif which == 4:
            out[i] = math.sinh(v)
        elif which == 5:
            out[i] = math.hypot(v, y[i])
        elif which == 6:
            out[i] = math.atan(v)
        elif which == 7:
            out[i] = math.sin(v)
        elif which == 8:
            out[i] = math.cos(v)
        elif which == 9:
            out[i] = np.cbrt(v)
        elif which == 10:
            out[i] = v ** 4.0
        else:
            out[i] = math.atan2(v, y[i])
    return out


@at_pinned_level  # the premise holds at X86_V3 (tests/pinned_numpy.py); above it NumPy's SIMD kernels differ
def test_numpy_transcendentals_are_libms_at_the_pinned_level():
    rng = np.random.default_rng(49)
    n = 20_000
    y = rng.uniform(-50.0, 50.0, n)
    cases = [  # (NumPy's, the probes: the ranges the step uses)
        (np.exp, rng.uniform(-30.0, 5.0, n)),
        (lambda t: np.power(t, np.array([[3.0]]))[0], rng.uniform(0.0, 60.0, n)),
        (lambda t: np.power(t, 5.0), rng.uniform(0.0, 60.0, n)),
        (np.arcsinh, rng.uniform(-50.0, 50.0, n)),
        (np.sinh, rng.uniform(-5.0, 5.0, n)),
        (lambda x: np.hypot(x, y), rng.uniform(-50.0, 50.0, n)),
        (np.arctan, rng.uniform(-3.0, 3.0, n)),
        (np.sin, rng.uniform(-7.0, 7.0, n)),
        (np.cos, rng.uniform(-7.0, 7.0, n)),
        (np.cbrt, rng.uniform(0.0, 5_000.0, n)),  # the join search's start (from stop 50 inside plan_pass)
        (lambda t: t ** 4.0, rng.uniform(0.0, 2.0, n)),  # the IDM's free term (from stop 50 inside the experts' kernels)
        (lambda x: np.arctan2(x, y), rng.uniform(-50.0, 50.0, n)),  # the turn arcs' and FCFS paths' angles (stop 50)
    ]
    for which, (f, x) in enumerate(cases):
        got, want = _libm(x, y, which), f(x)
        assert got.tobytes() == want.tobytes(), (which, int(np.count_nonzero(got != want)))
