"""NumPy's ``clip`` ufunc and ``count_nonzero`` called directly, and ``flatnonzero`` of a 1-D array without its wrapper.

Below every layer of the package: the algorithms in ``formation/`` use it,
as the simulator, the policies and the envs do.

``numpy.clip`` is a Python wrapper (``fromnumeric.clip`` -> ``ndarray.clip``
-> ``_methods._clip``) around the ``clip`` ufunc; on the arrays of one step
(20-450 vehicles) the wrapper costs more than the clipping, and a step
clips a few dozen times. :func:`clip` is that same ufunc (same loops, same
results bit for bit), without the wrapper.
"""

from __future__ import annotations

try:
    from numpy._core.umath import clip
    from numpy._core._multiarray_umath import count_nonzero
except ImportError:  # numpy < 2
    from numpy.core.umath import clip  # type: ignore[no-redef]
    from numpy.core._multiarray_umath import count_nonzero  # type: ignore[no-redef]

#: ``count_nonzero`` above is what ``numpy.count_nonzero(a)`` (no ``axis``)
#: calls after its Python wrapper (``numeric.count_nonzero``): the same
#: count, about 0.1 instead of 0.2 us (a step asks five times or more; from
#: stop 51). Arrays only.

__all__ = ["clip", "count_nonzero", "flatnonzero"]


def flatnonzero(a):
    """``numpy.flatnonzero(a)`` of a 1-D array ``a``: the same index array
    (``a.nonzero()[0]``), without ``numpy.flatnonzero``'s ``ravel`` and
    dispatch (about 0.3 instead of 1.1 us; a step of the intersection asks
    about fifteen times, the formation layer about ten)."""
    return a.nonzero()[0]
