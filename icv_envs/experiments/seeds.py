"""The ``--seeds`` argument of the sweep commands."""

from __future__ import annotations

__all__ = ["parse_seeds"]


def parse_seeds(text) -> list[int]:
    """Seeds from a count or a list of seeds and ranges.

    * ``"5"`` (a bare count, also the int ``5``): seeds ``0..4``;
    * ``"5,7,10-12"``: seeds 5, 7, 10, 11, 12 (ranges inclusive), in the
      order given; a list with one element must be written with a comma
      (``"7,"``) or as a range (``"7-7"``) to mean "seed 7" rather than
      "seven seeds".

    Seeds are integers >= 0; a seed listed twice is an error (it would run
    the same trajectory twice and weight it double in the means)."""
    if isinstance(text, (list, tuple)):
        bad = [s for s in text if isinstance(s, bool) or not isinstance(s, int) or s < 0]
        if bad or not text or len(set(text)) != len(text):
            raise ValueError(f"seeds = {text!r}; allowed: a non-empty list of distinct integers >= 0, or a count")
        return list(text)
    if isinstance(text, bool):
        raise ValueError(f"seeds = {text!r}; allowed: a count N >= 1 or a list/range like '5,7,10-12'")
    if isinstance(text, int):
        text = str(text)
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"seeds = {text!r}; allowed: a count N >= 1 or a list/range like '5,7,10-12'")
    s = text.strip()
    if s.isdigit():
        n = int(s)
        if n < 1:
            raise ValueError(f"seeds = {text!r}: a count must be >= 1 (runs use seeds 0..N-1)")
        return list(range(n))
    out: list[int] = []
    for part in s.split(","):
        part = part.strip()
        if not part:
            continue
        lo, sep, hi = part.partition("-")
        if not (lo.strip().isdigit() and (not sep or hi.strip().isdigit())):
            raise ValueError(f"seeds = {text!r}: {part!r} is not a seed or a range a-b of seeds >= 0; "
                             f"allowed: a count N or a list like '5,7,10-12'")
        a = int(lo)
        b = int(hi) if sep else a
        if b < a:
            raise ValueError(f"seeds = {text!r}: range {part!r} is empty (its end is below its start)")
        out.extend(range(a, b + 1))
    if not out:
        raise ValueError(f"seeds = {text!r}: no seeds; allowed: a count N or a list like '5,7,10-12'")
    dup = sorted({x for x in out if out.count(x) > 1})
    if dup:
        raise ValueError(f"seeds = {text!r}: seeds {dup} are listed more than once")
    return out
