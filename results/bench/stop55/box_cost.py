"""Stop 55: what numba charges for each array a kernel returns (boxing: a new ndarray, its MemInfo base, and numba's
_numba_unpickle of the array type), against a kernel that returns nothing. python box_cost.py"""
import numba as nb, numpy as np, timeit
@nb.njit
def none(a):
    a[0] = 1.0
@nb.njit
def one(a):
    return np.empty(3)
@nb.njit
def four(a):
    return np.empty(3), np.empty(3), np.empty(3), np.empty(3)
@nb.njit
def fourpacked(a):
    return np.empty((4, 3))
@nb.njit
def view(a):
    return a[:2]
x = np.zeros(10)
for f in (none, one, four, fourpacked, view): f(x)
n = 200000
for f in (none, one, four, fourpacked, view):
    print(f.__name__, round(timeit.timeit(lambda: f(x), number=n) / n * 1e9), "ns")
