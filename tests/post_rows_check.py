"""The check both envs' one-pass ``_post_rows`` tests run (the highway's
``formation_post_rows``, tests/test_kernels.py; the intersection's
``intersection_post_rows``, tests/test_intersection_api.py): every step,
the one-pass result against the separate calls
(``IcvAgentsEnv._post_rows``), bit for bit, and how often the kernel was
reached."""

from __future__ import annotations

import contextlib

import numpy as np


@contextlib.contextmanager
def post_rows_checked(core, module, kernel_name: str, fused):
    """While active, ``core``'s ``_post_rows`` is ``fused`` (the env class's
    one-pass method) checked against the separate calls at every step, and
    ``module.<kernel_name>`` counts its calls. Yields the counts
    ``{"steps", "crashed", "fused"}``."""
    from icv_envs.envs.base import IcvAgentsEnv

    seen = {"steps": 0, "crashed": 0, "fused": 0}
    kernel = getattr(module, kernel_name)

    def counted(*args):
        seen["fused"] += 1
        return kernel(*args)

    def checked(self, rows, crashed_now):
        got = fused(self, rows, crashed_now)
        want = IcvAgentsEnv._post_rows(self, rows, crashed_now)
        assert got[0].tobytes() == np.asarray(want[0], dtype=np.float64).tobytes()
        assert list(got[1]) == list(want[1])
        for k in want[1]:
            assert got[1][k].tobytes() == np.asarray(want[1][k], dtype=np.float64).tobytes()
        assert got[2].dtype == want[2].dtype and got[2].shape == want[2].shape
        assert got[2].tobytes() == want[2].tobytes()
        seen["steps"] += 1
        seen["crashed"] += int(np.sum(crashed_now))
        return got

    setattr(module, kernel_name, counted)
    core._post_rows = checked.__get__(core)
    try:
        yield seen
    finally:
        setattr(module, kernel_name, kernel)
        del core._post_rows
