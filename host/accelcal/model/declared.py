"""Effects a user declares (`--effects FILE`): a small Python file whose EFFECTS list holds one
dict per effect, checked field by field and added to the catalogue, so that diagnose tries it as
a candidate like the built-in ones and calibrate (lsq) and apply fit and apply it.

    EFFECTS = [
        dict(name="ageing2",                 # a new name: letters, digits, _
             regressor="time",               # "temperature", "time", "reading" or
                                             # "column:NAME", a column of the recording
             power=2,                        # the regressor to this power (1..4); default 1
             step=False,                     # time only: a step at a time the fit finds instead
             form="offset",                  # "offset": v + p x;  "gain": v (1 + p x)
             unit="g/day^2", bound=0.001,    # of the parameters (one per axis): |p| <= bound
             explanation="The offset ages faster as the package's stress relaxes ..."),
    ]

The regressor x per axis is (T - T0)^power with T0 the mean temperature, ((t - t0) / 1 day)^power
with t0 the first time, [t >= ts] for a step, the axis's own reading^power, or (C - C0)^power for
a recording column C (battery voltage, say: CSV t,x,y,z[,temp],NAME...; a points file's column)
with C0 its mean over the points fitted.  Such effects are linear in their parameters.  On the board an effect runs as the device kind of its shape
(model/effects.py device_kind): an offset in temperature or time to a power 1..4, a step, a gain
linear in temperature, an offset in the squared reading; the device's bound for that shape then
holds (0.05 g per unit of its normalised regressor for the generic offsets).  Other shapes, and
every effect of a recording column, are fitted and applied on the host
(docs/model-discovery.md "Effects you declare")."""
from __future__ import annotations

import math
import re
import runpy
from pathlib import Path

from accelcal.errors import InputError
from accelcal.model.effects import CATALOGUE, COLUMN_NAME, RESERVED, Effect

MAX_EFFECTS = 64     # one file's effects: each is a candidate fit in diagnose
MAX_FILE_BYTES = 1 << 20
REGRESSORS = {"temperature": "temp", "time": "t", "reading": None}
REQUIRED = ("name", "regressor", "unit", "bound", "explanation")
OPTIONAL = ("power", "step", "form")
# how a regressor reads in a report
REGRESSOR_LABEL = {"temperature": "temperature", "time": "time", "reading": "axis reading"}


def _check(path: str, i: int, d) -> Effect:
    where = f"{path}: EFFECTS[{i}]"
    if not isinstance(d, dict):
        raise InputError(f"{where} must be a dict (name=..., regressor=..., ...), found "
                         f"{type(d).__name__}")
    missing = [k for k in REQUIRED if k not in d]
    if missing:
        raise InputError(f"{where} lacks {', '.join(missing)} (needs {', '.join(REQUIRED)})")
    unknown = sorted(set(d) - set(REQUIRED) - set(OPTIONAL))
    if unknown:
        raise InputError(f"{where}: unknown field {unknown[0]!r} (fields: "
                         f"{', '.join(REQUIRED + OPTIONAL)})")
    name = d["name"]
    if not isinstance(name, str) or not re.fullmatch(r"[a-z][a-z0-9_]{0,23}", name) or name == "base":
        raise InputError(f"{where}: name must be lower-case letters, digits and _ (a model spec "
                         f"part), found {name!r:.40}")
    if name in CATALOGUE and CATALOGUE[name].declared_in != str(path):
        raise InputError(f"{where}: {name!r} is already an effect; choose another name")
    reg = d["regressor"]
    column = None
    if isinstance(reg, str) and reg.startswith("column:"):
        column = reg[len("column:"):]
        if column in RESERVED or not COLUMN_NAME.fullmatch(column):
            raise InputError(f"{where}: regressor 'column:NAME' names a further recording column "
                             f"(lower-case, not t/x/y/z/temp/device), found {reg!r:.40}")
    elif reg not in REGRESSORS:
        raise InputError(f"{where}: regressor must be one of {', '.join(REGRESSORS)} or "
                         f"'column:NAME' (a column of the recording), found {reg!r:.40}")
    power = d.get("power", 1)
    if isinstance(power, bool) or not isinstance(power, int) or not 1 <= power <= 4:
        raise InputError(f"{where}: power must be a whole number 1..4, found {power!r:.40}")
    step = d.get("step", False)
    if not isinstance(step, bool) or (step and reg != "time"):
        raise InputError(f"{where}: step is True or False, and only for the time regressor")
    form = d.get("form", "offset")
    if form not in ("offset", "gain"):
        raise InputError(f"{where}: form must be 'offset' or 'gain', found {form!r:.40}")
    bound = d["bound"]
    if isinstance(bound, bool) or not isinstance(bound, (int, float)) or \
            not math.isfinite(bound) or not 0 < bound <= 1:
        raise InputError(f"{where}: bound must be a number in (0, 1] (the parameters' largest "
                         f"magnitude, in its unit), found {bound!r:.40}")
    for k in ("unit", "explanation"):
        if not isinstance(d[k], str) or not d[k].strip():
            raise InputError(f"{where}: {k} must be text")
    needs, label = ("col", column) if column else (REGRESSORS[reg], REGRESSOR_LABEL[reg])
    return Effect(name, f"{name}_", d["unit"], 1.0, d["unit"], float(bound),
                  (bound / 10, bound / 4), needs, label,
                  d["explanation"].strip(), form=form, power=power, change_point=step,
                  declared_in=str(path), column=column)


def load_effects(path: str) -> list[Effect]:
    """The effects a file declares, checked; InputError (one line) for a file that cannot be
    one: missing, a syntax error, an error running it, no EFFECTS list, a bad field."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{path}: no such effects file (a regular file)")
    if p.stat().st_size > MAX_FILE_BYTES:
        raise InputError(f"{path}: an effects file of more than {MAX_FILE_BYTES >> 10} KiB")
    try:
        ns = runpy.run_path(str(p), run_name="accelcal_effects")
    except SyntaxError as e:
        raise InputError(f"{path}:{e.lineno}: syntax error ({e.msg})") from None
    except BaseException as e:  # noqa: B036 - the user's code: sys.exit(0), SystemExit(3),
        # KeyboardInterrupt or any BaseException subclass it raises ends the command as one
        # line, exit 2, before any output is touched
        raise InputError(f"{path}: running it failed: {type(e).__name__}: "
                         f"{' '.join(str(e).split())[:160]}") from None
    effects = ns.get("EFFECTS")
    if not isinstance(effects, (list, tuple)) or not effects:
        raise InputError(f"{path}: must define EFFECTS, a non-empty list of effect dicts")
    if len(effects) > MAX_EFFECTS:
        raise InputError(f"{path}: declares {len(effects)} effects (at most {MAX_EFFECTS}: "
                         "diagnose tries each as a candidate)")
    out = [_check(path, i, d) for i, d in enumerate(effects)]
    names = [e.name for e in out]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: an effect name is declared twice")
    return out


def register(path: str | None) -> list[str]:
    """Add a file's effects to the catalogue (this process); their names.  The same file again is
    a no-op, so workers and repeated calls may register freely."""
    if not path:
        return []
    names = []
    for e in load_effects(path):
        old = CATALOGUE.get(e.name)
        if old is not None and old.declared_in == e.declared_in:
            names.append(e.name)
            continue
        CATALOGUE[e.name] = e
        names.append(e.name)
    return names
