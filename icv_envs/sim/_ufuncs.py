"""NumPy's ``clip`` ufunc, called directly.

``numpy.clip`` is a Python wrapper (``fromnumeric.clip`` -> ``ndarray.clip``
-> ``_methods._clip``) around the ``clip`` ufunc; on the arrays of one step
(20-450 vehicles) the wrapper costs more than the clipping, and a step
clips a few dozen times. :func:`clip` is that same ufunc (same loops, same
results bit for bit), without the wrapper.
"""

from __future__ import annotations

try:
    from numpy._core.umath import clip
except ImportError:  # numpy < 2
    from numpy.core.umath import clip  # type: ignore[no-redef]

__all__ = ["clip"]
