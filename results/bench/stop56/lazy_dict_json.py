"""Stop 56, decision 3 (README "Decisions where the issue is silent"): a dict
subclass that fills itself on first read, with every Python-level reader
overridden, is still read as empty by C code that looks at a dict's storage
directly. ``python results/bench/stop56/lazy_dict_json.py`` prints what
``json.dumps`` (its C encoder) and ``dict()`` give for one such mapping."""
import json


class Lazy(dict):
    """Filled with {"a": 1} by the first call of any overridden reader."""

    def _fill(self):
        if not dict.__len__(self):
            dict.update(self, {"a": 1})

    def __iter__(self):
        self._fill()
        return dict.__iter__(self)

    def __len__(self):
        self._fill()
        return dict.__len__(self)

    def keys(self):
        self._fill()
        return dict.keys(self)

    def items(self):
        self._fill()
        return dict.items(self)

    def values(self):
        self._fill()
        return dict.values(self)

    def __getitem__(self, k):
        self._fill()
        return dict.__getitem__(self, k)


print("json.dumps(Lazy())           ->", json.dumps(Lazy()))
print("json.dumps({'x': Lazy()})    ->", json.dumps({"x": Lazy()}))
print("dict(Lazy())                 ->", dict(Lazy()))
