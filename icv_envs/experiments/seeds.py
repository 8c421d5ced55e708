"""Seed lists for the sweeps: ``--seeds 3`` or ``--seeds 5,7,10-12``.

One parser for every ``compare`` command.  Rules:

* a bare integer ``N`` (``3``, or the int 3) is a COUNT: seeds ``0 .. N-1``
  (what ``--seeds 3`` always meant);
* anything with a comma or a dash is a LIST of seeds and inclusive ranges:
  ``5,7,10-12`` = ``[5, 7, 10, 11, 12]``; a single seed ``s`` is written
  ``s,`` or ``s-s``;
* a list or tuple of integers is taken as the seed list itself.

Seeds are integers >= 0, returned sorted without duplicates (a repeated seed
would only repeat a run: the runs are deterministic).
"""

from __future__ import annotations

import numbers

__all__ = ["parse_seeds", "MAX_SEEDS"]

#: a sanity bound on the number of seeds of one sweep
MAX_SEEDS = 100_000


def _int(tok: str, text) -> int:
    tok = tok.strip()
    if not tok.isdigit():
        raise ValueError(f"--seeds {text!r}: {tok!r} is not a seed; allowed: a count N (seeds 0..N-1) or a "
                         f"comma-separated list of seeds >= 0 and ranges a-b, e.g. '5,7,10-12'")
    return int(tok)


def parse_seeds(value) -> list[int]:
    """Seeds from a count, a list/range string or a list (module docstring).

    Raises:
        ValueError: naming the bad value and what is allowed.
    """
    if isinstance(value, bool):
        raise ValueError(f"--seeds {value!r} is invalid; allowed: a count N >= 1 or a list like '5,7,10-12'")
    if isinstance(value, numbers.Integral):
        n = int(value)
        if not 1 <= n <= MAX_SEEDS:
            raise ValueError(f"--seeds {value!r}: a count must be in 1..{MAX_SEEDS} (runs use seeds 0..N-1)")
        return list(range(n))
    if isinstance(value, (list, tuple)):
        out = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 0:
                raise ValueError(f"--seeds {value!r}: {v!r} is not a seed; allowed: integers >= 0")
            out.append(int(v))
        if not out:
            raise ValueError("--seeds is an empty list; allowed: at least one seed")
        return sorted(set(out))
    if not isinstance(value, str):
        raise ValueError(f"--seeds {value!r} is invalid; allowed: a count N >= 1 or a list like '5,7,10-12'")
    text = value.strip()
    if not text:
        raise ValueError("--seeds is empty; allowed: a count N >= 1 or a list like '5,7,10-12'")
    if "," not in text and "-" not in text:
        return parse_seeds(_int(text, value))
    out = set()
    for part in text.split(","):
        if not part.strip():
            continue
        if "-" in part:
            a, sep, b = part.partition("-")
            lo, hi = _int(a, value), _int(b, value)
            if hi < lo:
                raise ValueError(f"--seeds {value!r}: range {part.strip()!r} is empty (a-b needs a <= b)")
            if hi - lo + 1 + len(out) > MAX_SEEDS:
                raise ValueError(f"--seeds {value!r}: more than {MAX_SEEDS} seeds")
            out.update(range(lo, hi + 1))
        else:
            out.add(_int(part, value))
    if not out:
        raise ValueError(f"--seeds {value!r} holds no seed; allowed: e.g. '5,7,10-12'")
    return sorted(out)
