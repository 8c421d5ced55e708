"""Do NumPy's float64 transcendental ufuncs round as libm's (which numba's
compiled code calls)? Stop 49. Counts the values that differ, per function,
over 400,000 probes each in the ranges the step uses, in this process's
NumPy dispatch (run it as is, then with the reference fingerprints' cap:
``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL" python ...``)."""
import json
import math
import sys

import numpy as np
from numba import njit

N = 400_000
rng = np.random.default_rng(0)
probes = {
    "exp": rng.uniform(-30.0, 5.0, N),  # reward terms: exp(-(dx/L)^2 ...)
    "power345": rng.uniform(0.0, 60.0, N),  # join profiles: t^3, t^4, t^5
    "cbrt": rng.uniform(0.0, 5000.0, N),  # join search start
    "sin": rng.uniform(-7.0, 7.0, N), "cos": rng.uniform(-7.0, 7.0, N),
    "tan": rng.uniform(-0.7, 0.7, N), "arctan": rng.uniform(-3.0, 3.0, N),
    "arcsinh": rng.uniform(-50.0, 50.0, N), "sinh": rng.uniform(-5.0, 5.0, N),
    "hypot": rng.uniform(-50.0, 50.0, N), "arctan2": rng.uniform(-50.0, 50.0, N),
}
y = rng.uniform(-50.0, 50.0, N)


@njit(cache=False)
def libm(x, y, which):
    out = np.empty((3, x.size))
    for i in range(x.size):
        v = x[i]
        if which == 0:
            out[0, i] = math.exp(v)
        elif which == 1:
            out[0, i] = v ** 3.0
            out[1, i] = v ** 4.0
            out[2, i] = v ** 5.0
        elif which == 2:
            out[0, i] = np.cbrt(v)
        elif which == 3:
            out[0, i] = math.sin(v)
        elif which == 4:
            out[0, i] = math.cos(v)
        elif which == 5:
            out[0, i] = math.tan(v)
        elif which == 6:
            out[0, i] = math.atan(v)
        elif which == 7:
            out[0, i] = math.asinh(v)
        elif which == 8:
            out[0, i] = math.sinh(v)
        elif which == 9:
            out[0, i] = math.hypot(v, y[i])
        else:
            out[0, i] = math.atan2(v, y[i])
    return out


numpy_of = {"exp": np.exp, "power345": lambda t: np.power(t, np.array([[3.0], [4.0], [5.0]])), "cbrt": np.cbrt,
            "sin": np.sin, "cos": np.cos, "tan": np.tan, "arctan": np.arctan, "arcsinh": np.arcsinh, "sinh": np.sinh,
            "hypot": lambda x: np.hypot(x, y), "arctan2": lambda x: np.arctan2(x, y)}
out = {}
for k, (name, x) in enumerate(probes.items()):
    got = libm(x, y, k)
    want = numpy_of[name](x)
    rows = 3 if name == "power345" else 1
    out[name] = int(np.count_nonzero(np.atleast_2d(want)[:rows] != got[:rows]))
feat = [t for t in ("X86_V4", "AVX512_ICL", "AVX512_SKX", "AVX512F", "AVX2")
        if np._core._multiarray_umath.__cpu_features__.get(t)]
print(json.dumps({"numpy": np.__version__, "cpu_features_on": feat,
                  "disabled": __import__("os").environ.get("NPY_DISABLE_CPU_FEATURES", ""),
                  "values_differing": out, "values_compared": {k: (3 * N if k == "power345" else N) for k in out}}))
