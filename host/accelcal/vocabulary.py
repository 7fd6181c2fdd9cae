"""One word for one thing (issue 51): every keyword of the public functions (accelcal.__all__),
what it means with its unit, and the command-line option that takes the same value.  A function
whose keyword is not here, or a keyword whose option the command lacks, fails
tests/test_vocabulary.py; `documented` appends each function's keywords, from here, to its
docstring, so help(accelcal.calibrate) shows the units; docs/api.md is generated from both
(tools/api_doc.py)."""
from __future__ import annotations

import inspect

# keyword -> (the command-line option or argument taking the same value, or None; its meaning)
KEYWORDS: dict[str, tuple[str | None, str]] = {
    "path": ("INPUT", "the data: a recording (CSV t,x,y,z[,temp] in s, g, degC; .cwa, .bin, "
             ".gt3x) or points file (x,y,z in g) by its path, or samples in memory: a numpy array "
             "(n, 3) in g with rate or time, or a pandas or polars DataFrame (columns x, y, z in "
             "g, temp in degC; times from a datetime or seconds index, a t/time column, or rate)"),
    "params": ("PARAMS", "the parameters: a file `calibrate --save` wrote (JSON), or a "
               "CalibrationResult that calibrated"),
    "output": ("-o/--output", "the file written (a recording CSV: t s, x y z g, temp degC); "
               "never one of the inputs"),
    "model": ("--model", "the model: base (Farago 2024's 9 parameters), base+EFFECT[+...] "
              "(accelcal.CATALOGUE, e.g. base+temp_offset) or, for calibrate, auto "
              "(base+temp_offset where the data has temperature, else base: its default)"),
    "method": ("--method", "the fit: device (the device's integer fit) or a float method: lsq, "
               "de, linauto, linminvar, campolo, merayo, minvol"),
    "methods": ("--methods", "the methods compared: a list, or a comma-separated string "
                "(None: all)"),
    "profile": ("--profile", "the device pipeline's settings: wear (default, robust for real "
                "wear) or paper (Farago 2024 to the letter)"),
    "runtime": ("--runtime", "where the device code runs: cpython (default), micropython, "
                "micropython32, rp2040 (emulated), circuitpython"),
    "engine": ("--engine", "vector (the device code's numpy twin, bit-exact) or device (every "
               "sample through the device modules); None: vector under cpython"),
    "fallback": ("--fallback", "a parameters file taken when the data does not calibrate"),
    "points": ("--points", "what a float method is fitted on: bins (the points the device's "
               "bins selected) or all (every usable rest point)"),
    "effects": ("--effects", "a Python file declaring effects of your own (it is run: name only "
                "a file you trust)"),
    "effect": ("--effect", "hidden effects to simulate: catalogue names (accelcal.CATALOGUE)"),
    "progress": (None, "a callable told of progress (samples read, an int, or a message, a "
                 "str); None: silent"),
    "rate": ("--rate", "the sample rate, Hz"),
    "temp": (None, "each sample's temperature, degC, an (n,) array (samples given as an array)"),
    "time": (None, "each sample's time, an (n,) array of s or datetimes (seconds since the "
             "epoch), for samples given as an array"),
    "plots": ("--plots", "a folder for the figures (PNG)"),
    "history": ("--history", "a diagnose history (JSON lines) this step is appended to"),
    "report": ("--report", "a folder for report.html"),
    "force": ("--force", "replace an existing output"),
    "cfg": (None, "the device pipeline's settings, an accelcal.Config (None: the profile's)"),
    "train": ("--train", "what compare's float methods are fitted on: selected (the device's "
              "bins' points), all (every training rest point) or thinned (10 per direction)"),
    "split": ("--split", "how rest points split into training and held out: blocks (2-hour "
              "blocks), first-half or second-half (of their time span)"),
    "device": ("--device", "which device of a `calibrate --by` parameters file"),
    "range_g": ("--range", "the device's full scale, g: 2, 4, 8 or 16"),
    "days": ("--days", "the recording's length, days"),
    "seed": ("--seed", "the random seed"),
    "stimulus": ("--stimulus", "also write this stimulus file for the virtual board"),
    "events_within_days": (None, "a step's shock falls within the first this many days"),
    "job": (None, "an accelcal.Job: the settings every file gets (Job.of)"),
    "settings": (None, "accelcal.Config fields over the profile's: seconds (s, --seconds), "
                 "threshold_g (g, --threshold), axis, min_count, max_count, iterations, ..."),
}


def keyword_lines(fn, width: int = 96) -> list[str]:
    """fn's keywords, one paragraph each: name, meaning with its unit, [the CLI option]."""
    import textwrap
    lines = []
    for n in inspect.signature(fn).parameters:
        if n in ("self", "cls"):
            continue
        option, meaning = KEYWORDS.get(n, (None, "?"))
        lines += textwrap.wrap(f"{n}: {meaning}" + (f" [{option}]" if option else ""), width,
                               subsequent_indent="    ")
    return lines


def documented(fn):
    """fn with its keywords' meanings and units (KEYWORDS) appended to its docstring, at the
    docstring's own indentation (so help() shows them in line)."""
    doc = fn.__doc__ or ""
    rest = [ln for ln in doc.splitlines()[1:] if ln.strip()]
    pad = " " * min((len(ln) - len(ln.lstrip()) for ln in rest), default=4)
    fn.__doc__ = doc.rstrip() + f"\n\n{pad}Keywords (accelcal.vocabulary):\n" + \
        "".join(f"{pad}  {ln}\n" for ln in keyword_lines(fn)) + pad
    return fn
