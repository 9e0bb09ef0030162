"""Value checks for preset JSON (pure Python): one place for every preset key's type and range.

Each check takes the value and the key it came from (a dotted path such as
``style.lane_width``) and returns the value — integers as ``int``, nothing truncated (2.9 is
not an integer) — or raises ``ValueError`` naming the key and the allowed range, e.g.
``style.lane_width must be a number in [0.5, 20], got 30``. A bool is never a number.
Bounds are inclusive unless ``lo_open``. Callers turn the ValueError into an
:class:`~fogsim.errors.InputError` naming the preset file (:mod:`fogsim.render.preset`).

They live in the core (``fogsim.presets``) so that both the renderer's preset loader and the
scene's lighting check (:func:`fogsim.scene.lights.check_lighting`) use them.
"""
from __future__ import annotations

import math


def is_number(v) -> bool:
    """An int or float, not a bool (finiteness is not checked)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _bounds(v, key: str, what: str, lo=None, hi=None, lo_open: bool = False):
    low_bad = lo is not None and (v <= lo if lo_open else v < lo)
    if low_bad or (hi is not None and v > hi):
        fmt = lambda x: str(x) if isinstance(x, int) else f"{x:g}"  # noqa: E731
        if lo is not None and hi is not None:
            rng = f"in {'(' if lo_open else '['}{fmt(lo)}, {fmt(hi)}]"
        elif lo is not None:
            rng = f"{'>' if lo_open else '≥'} {fmt(lo)}"
        else:
            rng = f"≤ {fmt(hi)}"
        raise ValueError(f"{key} must be {what} {rng}, got {v!r}")
    return v


def integer(v, key: str, lo=None, hi=None) -> int:
    """A whole number in [lo, hi] (a float such as 3.0 is accepted, 2.9 refused), as int."""
    if not is_number(v) or not math.isfinite(v) or v != int(v):
        raise ValueError(f"{key} must be an integer, got {v!r}")
    return _bounds(int(v), key, "an integer", lo, hi)


def number(v, key: str, lo=None, hi=None, lo_open: bool = False):
    """A finite number in [lo, hi] ((lo, hi] with ``lo_open``)."""
    if not is_number(v) or not math.isfinite(v):
        raise ValueError(f"{key} must be a finite number, got {v!r}")
    return _bounds(v, key, "a number", lo, hi, lo_open)


def prob(v, key: str):
    """A number in [0, 1]."""
    return number(v, key, 0, 1)


def pair(v, key: str, check=number, **bounds) -> list:
    """A ``[low, high]`` pair with low ≤ high, each checked by ``check`` with ``bounds``."""
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise ValueError(f"{key} must be a [low, high] pair, got {v!r}")
    lo, hi = (check(x, f"{key}[{i}]", **bounds) for i, x in enumerate(v))
    if lo > hi:
        raise ValueError(f"{key} must be [low, high] with low ≤ high, got {v!r}")
    return [lo, hi]


def string(v, key: str) -> str:
    if not isinstance(v, str):
        raise ValueError(f"{key} must be a string, got {v!r}")
    return v


def boolean(v, key: str) -> bool:
    """JSON true or false (not 0 / 1)."""
    if not isinstance(v, bool):
        raise ValueError(f"{key} must be true or false, got {v!r}")
    return v


def choice(v, key: str, choices) -> str:
    if v not in choices:
        raise ValueError(f"{key} must be one of {', '.join(choices)}, got {v!r}")
    return v


def json_object(d, key: str, required: dict, optional: dict) -> dict:
    """Check a JSON object key by key: ``required``/``optional`` map a key to its check
    ``check(value, "key.sub")``. Unknown keys are refused (the allowed ones listed); the keys
    present are checked before missing required ones are reported. Returns the checked values."""
    if not isinstance(d, dict):
        raise ValueError(f"{key} must be a JSON object, got {d!r}")
    unknown = set(d) - set(required) - set(optional)
    if unknown:
        raise ValueError(f"unknown {key} keys {sorted(unknown)} (allowed: {sorted({*required, *optional})})")
    checks = {**required, **optional}
    checked = {k: checks[k](v, f"{key}.{k}") for k, v in d.items()}
    missing = [k for k in required if k not in d]
    if missing:
        raise ValueError(f"{key} lacks {', '.join(repr(k) for k in missing)}")
    return checked
