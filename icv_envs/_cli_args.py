"""The value parsers of ``icv-envs``' options (argparse ``type=``
callables) and its help formatter: each parser turns one option's text into
its value or raises ``argparse.ArgumentTypeError`` naming the option, the
value and what is allowed (split out of :mod:`icv_envs.cli` at stop 44)."""

from __future__ import annotations

import argparse

__all__ = ["_HelpFormatter", "_choice", "_floats", "_names", "_positive_float", "_positive_int", "_seed_list",
           "_sizes", "_nonneg_int"]


def _positive_float(name, allow_zero: bool = False):
    """A parser of a finite number > 0 (``allow_zero``: >= 0) for option ``name``."""
    bound = ">= 0" if allow_zero else "> 0"

    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number {bound}, got {text!r}") from None
        if not (v >= 0 if allow_zero else v > 0) or v != v or v == float("inf"):
            raise argparse.ArgumentTypeError(f"{name} must be a finite number {bound}, got {text!r}")
        return v

    return parse


def _min_int(name, lo: int):
    """A parser of an integer >= ``lo`` for option ``name``."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            v = None
        if v is None or v < lo:
            raise argparse.ArgumentTypeError(f"{name} must be an integer >= {lo}, got {text!r}")
        return v

    return parse


def _positive_int(name):
    return _min_int(name, 1)


def _nonneg_int(name):
    """An integer >= 0 (a seed: gymnasium refuses a negative one, deep inside a run, with its own error type)."""
    return _min_int(name, 0)


def _floats(name):
    def parse(text):
        try:
            vals = [float(v) for v in text.split(",") if v.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be comma-separated numbers, got {text!r}") from None
        if not vals:
            raise argparse.ArgumentTypeError(f"{name} is empty")
        return vals

    return parse


def _seed_list(text):
    from icv_envs.experiments.seeds import parse_seeds

    try:
        return parse_seeds(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _names(text):
    """Comma-separated names; an empty list is an error (it fell back to the
    defaults until stop 45), and so is a repeated name."""
    vals = [v.strip() for v in text.split(",") if v.strip()]
    if not vals:
        raise argparse.ArgumentTypeError(f"the list is empty, got {text!r}")
    if len(set(vals)) != len(vals):
        raise argparse.ArgumentTypeError(f"the list repeats a name, got {text!r}")
    return vals


def _sizes(text):
    try:
        vals = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--sizes must be comma-separated integers, got {text!r}") from None
    if not vals or any(v < 1 for v in vals):
        raise argparse.ArgumentTypeError(f"--sizes must be integers >= 1, got {text!r}")
    return vals


def _choice(name, allowed):
    def parse(text):
        if text not in allowed:
            raise argparse.ArgumentTypeError(f"unknown {name} {text!r}; allowed: {', '.join(allowed)}")
        return text

    return parse


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends ``(default: X)`` only where there is a default worth showing."""

    def _get_help_string(self, action):
        text = action.help or ""
        # (``0 in (None, False)`` is True in Python: test identity, so a default 0 is shown)
        if action.default is None or action.default is False or "default" in text \
                or action.default is argparse.SUPPRESS:
            return text
        return super()._get_help_string(action)
