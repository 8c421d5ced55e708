"""Config validation shared by the environments.

Every check raises ``ValueError`` (or ``TypeError`` for a value of the wrong
kind where the key is still named) with a message naming the key, the value
given and what is allowed; nothing is accepted and then ignored.

The bounds below keep a run within memory and within the validity of the
vehicle model; they are deliberately generous:

* :data:`MAX_DURATION` (one day of simulated time): the arrival schedules of
  the open-road envs and the per-step statistics grow linearly with it;
* :data:`MAX_AGENTS` (possible agents of one env): PettingZoo's
  ``possible_agents``, the space dicts and ``state()`` hold one entry per
  possible agent;
* :data:`MAX_ACCEL` (|a| <= 20 m/s^2, about 2 g): above any tyre-road friction
  limit (dry asphalt mu ~ 1, so ~ 10 m/s^2), so no physical vehicle is excluded;
* render sizes within :data:`MAX_SCREEN` pixels a side.
"""

from __future__ import annotations

import math
import warnings
from numbers import Real

import numpy as np

__all__ = [
    "MAX_DURATION", "MAX_AGENTS", "UNUSED_COMMON", "MAX_ACCEL", "MAX_SCREEN", "num", "section", "check_keys", "flag",
    "accel_range", "speed_range", "is_speed_pair", "check_render", "check_unused", "check_possible_agents", "typed_options",
    "pick_type", "check_reset_options", "real_numbers",
]

MAX_DURATION = 86400.0  # s
MAX_AGENTS = 200_000
#: highway-env keys no env of this package uses, and why (each env adds ``other_vehicles_type``
#: with its own reason): setting them is an error
UNUSED_COMMON = {
    "manual_control": "no manual control; drive the Gymnasium ego through step()",
    "show_trajectories": "not drawn by this env's viewer",
    "neighbour_vehicles_connected_lanes": "observations use the env's own neighbour search",
}
MAX_ACCEL = 20.0  # m/s^2
MAX_SCREEN = 8192  # px


def _is_real(v) -> bool:
    return isinstance(v, (Real, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def num(config: dict, key: str, lo=None, hi=None, *, lo_open=False, integer=False, allowed: str = "",
        where: str = "") -> float:
    """``config[key]`` as a finite number within ``[lo, hi]`` (``(lo, hi]`` with
    ``lo_open``); ``integer`` also requires an integral value."""
    v = config[key]
    ok = _is_real(v)
    if ok:
        try:
            ok = math.isfinite(v)
        except OverflowError:  # an int too large for a float
            ok = False
    if ok and integer:
        ok = float(v) == int(v)
    if ok and lo is not None:
        ok = v > lo if lo_open else v >= lo
    if ok and hi is not None:
        ok = v <= hi
    if not ok:
        raise ValueError(f"config{where}[{key!r}] = {v!r} is invalid; allowed: {allowed}")
    return int(v) if integer else float(v)


def section(config: dict, name: str, *, optional: bool = False, where: str = "") -> dict | None:
    """``config[name]`` must be a dict (or None when ``optional``)."""
    v = config[name]
    if v is None and optional:
        return None
    if not isinstance(v, dict):
        allowed = "None or a dict" if optional else "a dict"
        raise ValueError(f"config{where}[{name!r}] = {v!r} ({type(v).__name__}) is invalid; allowed: {allowed}")
    return v


def check_keys(d: dict, name: str, allowed, required=()) -> None:
    """No keys beyond ``allowed`` and every key of ``required`` in section ``name``."""
    unknown = sorted(map(str, set(d) - set(allowed)))
    if unknown:
        raise ValueError(f"unknown {name} keys {unknown}; allowed: {sorted(allowed)}")
    missing = sorted(set(required) - set(d))
    if missing:
        raise ValueError(f"{name} needs the keys {missing}; got {d!r}")


def real_numbers(v):
    """``v`` as a float64 array when it is a real number or a (nested, not
    ragged) list / tuple / array of real numbers, else None: a bool or a
    string is not a number here (``np.asarray`` turns ``"5"`` and ``True``
    into 5.0 and 1.0; a config of them was accepted, misread, until stop 45)."""
    if isinstance(v, (bool, np.bool_, str, bytes)):
        return None
    if isinstance(v, np.ndarray):
        return v.astype(np.float64) if v.dtype.kind in "fiu" else None
    if isinstance(v, Real):
        return np.asarray(float(v))
    if isinstance(v, (list, tuple)):
        parts = [real_numbers(x) for x in v]
        if any(p is None for p in parts):
            return None
        try:
            return np.asarray(parts, dtype=np.float64)
        except ValueError:  # (ragged)
            return None
    return None


def check_reset_options(options) -> None:
    """``reset(options=...)``: None or a dict; the env reads its ``"config"``
    (merged into the env's config, as highway-env's reset takes it; checked
    where it is applied). A non-dict is an error. Any other key is ignored
    with a warning naming it, not refused: PettingZoo's own API test
    (``parallel_api_test``) resets with ``options={"options": 1}`` and
    requires the env to accept it (decided at stop 45; until then other keys
    were ignored silently, so a typo such as ``"confg"`` reset with the old
    config without a word)."""
    if options is None:
        return
    if not isinstance(options, dict):
        raise ValueError(f"reset options = {options!r}; allowed: None or a dict {{'config': {{...}}}}")
    unknown = sorted(map(str, set(options) - {"config"}))
    if unknown:
        warnings.warn(f"reset option(s) {unknown} are not used by this env and are ignored; it reads only "
                      f"'config'", UserWarning, stacklevel=4)


def flag(config: dict, key: str, optional: bool = False) -> None:
    v = config[key]
    if optional and v is None:
        return
    if not isinstance(v, (bool, np.bool_)):
        raise ValueError(f"config[{key!r}] = {v!r} is invalid; allowed: True or False" + (" or None" if optional else ""))


def info_keys(config: dict, allowed: tuple) -> None:
    """``config["info_keys"]``: None (every per-step info key the env
    reports) or a list or tuple of distinct names from ``allowed``; the
    expert's label has its own switch, ``expert_in_info``."""
    v = config["info_keys"]
    if v is None:
        return
    if not isinstance(v, (list, tuple)) or not all(isinstance(k, str) for k in v):
        raise ValueError(f"config['info_keys'] = {v!r} is invalid; allowed: None (all) or a list of names from "
                         f"{list(allowed)}")
    if "expert_action" in v:
        raise ValueError("config['info_keys'] lists 'expert_action'; the expert's label is switched by "
                         "config['expert_in_info'] (True or False); allowed names in info_keys: " + str(list(allowed)))
    bad = [k for k in v if k not in allowed]
    if bad:
        raise ValueError(f"config['info_keys'] = {list(v)!r}: unknown names {bad}; allowed: {list(allowed)}")
    if len(set(v)) != len(v):
        raise ValueError(f"config['info_keys'] = {list(v)!r} names a key twice; allowed: distinct names from "
                         f"{list(allowed)}")


def is_speed_pair(sr, v_top: float) -> bool:
    """``[lo, hi]`` of finite reals with ``0 <= lo < hi <= v_top``."""
    ok = isinstance(sr, (list, tuple)) and len(sr) == 2 and all(_is_real(v) for v in sr)
    return ok and all(math.isfinite(v) for v in sr) and 0 <= sr[0] < sr[1] <= v_top


def speed_range(config: dict) -> tuple[float, float]:
    sr = config["speed_range"]
    if not is_speed_pair(sr, 100.0):
        raise ValueError(f"config['speed_range'] = {sr!r} is invalid; allowed: [v_min, v_max] with "
                         f"0 <= v_min < v_max <= 100 m/s")
    return float(sr[0]), float(sr[1])


def accel_range(config: dict) -> tuple[float, float]:
    ar = config["acceleration_range"]
    ok = isinstance(ar, (list, tuple)) and len(ar) == 2 and all(_is_real(v) for v in ar)
    ok = ok and all(math.isfinite(v) for v in ar) and -MAX_ACCEL <= ar[0] < 0 < ar[1] <= MAX_ACCEL
    if not ok:
        raise ValueError(f"config['acceleration_range'] = {ar!r} is invalid; allowed: [a_min, a_max] finite with "
                         f"-{MAX_ACCEL:g} <= a_min < 0 < a_max <= {MAX_ACCEL:g} m/s^2")
    return float(ar[0]), float(ar[1])


def check_render(config: dict, flags=()) -> None:
    """Render settings (highway-env's keys) checked before pygame sees them."""
    for key in ("screen_width", "screen_height"):
        num(config, key, 16, MAX_SCREEN, integer=True, allowed=f"an integer number of pixels in [16, {MAX_SCREEN}]")
    num(config, "scaling", 0.0, 1e4, lo_open=True, allowed="a number of pixels per metre in (0, 10000]")
    cp = config["centering_position"]
    if not (isinstance(cp, (list, tuple)) and len(cp) == 2 and all(_is_real(v) and 0.0 <= v <= 1.0 for v in cp)):
        raise ValueError(f"config['centering_position'] = {cp!r} is invalid; allowed: [x, y], fractions of the "
                         f"screen in [0, 1]")
    for key in ("real_time_rendering", "render_agent", *flags):
        flag(config, key)
    flag(config, "offscreen_rendering", optional=True)


def check_unused(config: dict, defaults: dict, keys, env_name: str, why: dict | None = None) -> None:
    """Keys this env inherits but does not use must keep their default:
    an option accepted and then ignored is an error."""
    why = why or {}
    for key in keys:
        if key in config and not _same(config[key], defaults[key]):
            hint = why.get(key, "")
            raise ValueError(f"config[{key!r}] = {config[key]!r} is not used by {env_name}"
                             + (f" ({hint})" if hint else "") + f"; leave it at its default {defaults[key]!r}")


def _same(a, b) -> bool:
    try:
        return bool(a == b) and type(a) is type(b) or (a is None and b is None) or (
            _is_real(a) and _is_real(b) and a == b)
    except Exception:  # noqa: BLE001 - arrays and other odd objects are simply "not the default"
        return False


def check_possible_agents(n: int, what: str) -> int:
    if n > MAX_AGENTS:
        raise ValueError(f"{what} gives {n} possible agents; allowed: at most {MAX_AGENTS} (MAX_AGENTS of "
                         f"icv_envs.envs._config: every possible agent holds a slot in the spaces and in state())")
    return n


def pick_type(kind: str, config, types: dict, default: str):
    """The class of a highway-env style ``{"type": ..., **options}`` section
    ``config[kind]`` (``kind`` = ``"action"`` / ``"observation"``)."""
    if not isinstance(config, dict):
        raise ValueError(f"config[{kind!r}] = {config!r}; allowed: a dict {{'type': one of {list(types)}, ...}}")
    t = config.get("type", default)
    if t not in types:
        raise ValueError(f"unknown {kind} type {t!r}; allowed: {list(types)}")
    return types[t]


def typed_options(kind: str, name: str, defaults: dict, config: dict) -> dict:
    """``defaults`` updated with ``config`` (without ``type``); an option the
    type ``name`` does not have is an error naming it and the allowed ones."""
    unknown = set(config) - set(defaults) - {"type"}
    if unknown:
        raise ValueError(f"{kind} option(s) {sorted(unknown)} do not apply to type {name!r}; "
                         f"allowed: {sorted(defaults) or 'none'}")
    return {**defaults, **{k: v for k, v in config.items() if k != "type"}}
