"""Run a bit-exact oracle test with NumPy's SIMD dispatch capped at AVX2.

Some tests compare compiled kernels with the NumPy code they replaced, bit
for bit, over whole runs (``tests/test_intersection_frames.py``,
``tests/test_box_steering.py``). The kernels call libm's ``sin``, ``cos``,
``arctan2`` ..., as NumPy's float64 loops do up to ``X86_V3`` (AVX2); on an
AVX-512 machine NumPy takes some of them from its SIMD library, which can
round the last bit differently, and a run that branches on such a bit then
diverges (``icv_envs/sim/_kernels/__init__.py`` states the rule). Such a
test, decorated with :func:`at_pinned_level`, runs itself again in a
pytest subprocess whose NumPy dispatch is capped at ``X86_V3``
(:func:`trajectory_hash.pinned_environment`, as the trajectory
fingerprints are computed), so the comparison stays exact on every x86-64
machine with AVX2; on a machine with nothing above that level it runs in
place.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

from trajectory_hash import _active_targets_above, pinned_environment

_ROOT = Path(__file__).resolve().parents[1]
_MARK = "ICV_ENVS_PINNED_TEST"  # set in the subprocess: never re-launch from it


def at_pinned_level(test):
    """Decorator: run ``test`` in a subprocess pinned at ``X86_V3`` when this
    process runs NumPy kernels above it (module docstring)."""

    @functools.wraps(test)
    def run(*args, **kwargs):
        env = pinned_environment() if _active_targets_above() and not os.environ.get(_MARK) else None
        if env is None:
            return test(*args, **kwargs)
        env[_MARK] = "1"
        nodeid = os.environ["PYTEST_CURRENT_TEST"].rsplit(" (", 1)[0]
        out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", nodeid],
                             env=env, cwd=_ROOT, capture_output=True, text=True, check=False)
        assert out.returncode == 0, f"{nodeid} failed in the X86_V3-pinned subprocess:\n{out.stdout[-8000:]}{out.stderr[-2000:]}"

    return run
