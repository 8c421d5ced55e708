"""Whether an object's hooks are still its class's own: the guard of the
one-call paths (``HighwayRows._post_rows``, the highway env's,
``FormationExpert.compute``), which stand for several overridable methods
and are taken only while none of them is replaced, on a subclass, on the
class itself (a monkeypatch) or on the instance.

Below every layer of the package, as :mod:`icv_envs._ufuncs`: the envs and
the policies use it.
"""

from __future__ import annotations

import operator

__all__ = ["hook_table", "own_hooks"]


def hook_table(cls: type, *names: str) -> tuple:
    """``(names, cls's functions of those names, a getter of the names'
    values on a class)``, made once where ``cls`` is defined (the getter
    reads all of them in one C call)."""
    get = operator.attrgetter(*names)
    return names, get(cls), get


def own_hooks(obj, table: tuple) -> bool:
    """Whether every hook of ``table`` (:func:`hook_table`) is, on ``obj``'s
    class, the function it was made with (functions compare by identity),
    and none is set on ``obj`` itself."""
    names, funcs, get = table
    return get(type(obj)) == funcs and obj.__dict__.keys().isdisjoint(names)
