"""The bounds and choices of the options the command line and the Python API share, in one
place: the CLI's parsers take their ranges from here (cli/options.py), and each public function
of the API checks its keywords here first (accelcal.calibrate, diagnose, compare, apply,
simulate_wrist), so a bad argument is the same one line either way: InputError, whose words are
the CLI's ("argument --seconds: 0 is outside [1, 3600]").  The API takes the option's name
(seconds=..., threshold=..., axis="x") or the pipeline setting it makes (threshold_g=, axis=0,
differ_g=, policy=, rates_tenths=): pipeline_settings() turns either into Config overrides."""
from __future__ import annotations

import math

from accelcal.errors import InputError

# option -> (lo, hi): whole numbers within [lo, hi]
INTS = {"seconds": (1, 3600), "min_count": (1, 14), "max_count": (1, 14),
        "iterations": (1, 100000), "jobs": (1, 256), "seed": (0, 2 ** 32 - 1)}
# option -> (lo, hi, lo excluded): finite numbers
FLOATS = {"differ": (0.0, 2.0, False), "threshold": (0.0, 2.0, True), "days": (0.0, 3650.0, True)}
CHOICES = {"profile": ("wear", "paper"), "axis": ("x", "y", "z", "all"),
           "select": ("centre", "first"), "engine": ("vector", "device"),
           "train": ("selected", "thinned", "all"), "points": ("bins", "all"),
           "rate": (10, 25, 50, 100), "range": (2, 4, 8, 16),
           "split": ("blocks", "first-half", "second-half")}
AXES = {"x": 0, "y": 1, "z": 2, "all": 3}     # 3: acal.core.rest.ALL_AXES


def flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def outside_int(v: int, lo: int, hi: int) -> str:
    return f"{v} is outside [{lo}, {hi}]"


def outside_float(v, lo: float, hi: float, lo_open: bool) -> str:
    return f"{v} is outside {'(' if lo_open else '['}{lo:g}, {hi:g}]"


def _bad(name: str, why: str):
    raise InputError(f"argument {flag(name)}: {why}")


def whole(name: str, v, lo: int | None = None, hi: int | None = None) -> int:
    """v as an int option `name` (INTS' bounds unless given); InputError in the CLI's words."""
    if lo is None:
        lo, hi = INTS[name]
    if isinstance(v, bool) or not isinstance(v, int):
        if isinstance(v, float) and math.isfinite(v) and v == int(v):
            v = int(v)
        else:
            _bad(name, f"{v!r} is not a whole number")
    if not lo <= v <= hi:
        _bad(name, outside_int(v, lo, hi))
    return v


def number(name: str, v) -> float:
    """v as a float option `name` within FLOATS' bounds (finite)."""
    lo, hi, lo_open = FLOATS[name]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        _bad(name, f"{v!r} is not a number")
    if not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo):
        _bad(name, outside_float(v, lo, hi, lo_open))
    return float(v)


def choice(name: str, v, choices=None):
    """v as one of the option's choices (argparse's words)."""
    choices = CHOICES[name] if choices is None else tuple(choices)
    if not any(v == c and type(v) is type(c) for c in choices):
        _bad(name, f"invalid choice: {v!r} (choose from {', '.join(map(repr, choices))})")
    return v


def paths(*, required=(), **named) -> None:
    """Each named argument a path (a str or os.PathLike, not empty); None passes (not given)
    unless its name is in required, and so do samples already taken in memory (files/arrays.py
    as_input: an array or frame, not a file)."""
    import os
    for name, v in named.items():
        if (v is None and name not in required) or getattr(v, "in_memory", False):
            continue
        if not isinstance(v, (str, os.PathLike)) or str(v) == "":
            raise InputError(f"{name}={v!r:.60}: not a path (a str or os.PathLike)")


def threshold(v):
    """--threshold: g in (0, 2], or "auto" (None: the profile's)."""
    return v if v is None or v == "auto" else number("threshold", v)


def pipeline_settings(settings: dict) -> dict:
    """The API's pipeline keywords (the CLI's options or Config's fields) as Config overrides,
    each checked as the CLI checks it; an unknown keyword is refused, naming the known ones."""
    out = {}
    for k, v in settings.items():
        if v is None:
            continue
        if k in ("seconds", "min_count", "max_count", "iterations"):
            out[k] = whole(k, v)
        elif k in ("threshold", "threshold_g"):
            out["threshold_g"] = None if threshold(v) == "auto" else threshold(v)
        elif k == "axis":
            out["axis"] = AXES[choice("axis", v)] if not isinstance(v, int) or isinstance(v, bool) \
                else whole("axis", v, 0, 3)
        elif k in ("differ", "differ_g"):
            out["differ_g"] = number("differ", v)
        elif k in ("select", "policy"):
            out["policy"] = choice("select", v)
        elif k in ("rates", "rates_tenths"):
            if not (isinstance(v, (tuple, list)) and len(v) == 3):
                _bad("rates", f"{v!r}: three non-negative multiples of 0.1, e.g. (3, 8, 2) tenths")
            out["rates_tenths"] = tuple(whole("rates", r, 0, 1000) for r in v)
        elif k == "discover":
            if not isinstance(v, bool):
                _bad("discover", f"{v!r:.40}: True or False")
            out[k] = v
        else:
            raise InputError(f"unknown setting {k}={v!r:.40}; the pipeline's are seconds, "
                             "threshold, axis, min_count, max_count, differ, select, "
                             "iterations, rates, discover")
    mn, mx = out.get("min_count"), out.get("max_count")
    if mn is not None and mx is not None and mx < mn:
        raise InputError("--max-count must be >= --min-count")
    return out
