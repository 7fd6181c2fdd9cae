"""Saved parameters: the JSON `calibrate --save` writes and `apply` reads, checked whole where it
enters (shape, integer Q24 parameters inside the device's calibration bounds, a finite reference)."""
from __future__ import annotations

import json
import math
from pathlib import Path

from acal.core import fixed
from acal.core import model as dmodel
from accelcal.errors import InputError
from accelcal.files.outputs import check_regular, write_text
from accelcal.fixedpoint import params_to_float
from accelcal.model.effects import ModelSpec, column_ref


PARAMS_MAX_BYTES = 16 << 20   # a calibrate --by file of thousands of devices is ~ 2 MB


# A composed model's integers (pipeline/calibrate.py Fit, a composed --fallback)
COMPOSED_SCALE = ("Q24 per normalised regressor (device/acal/core/effects.py); decoded in g, "
                  "1/degC, g/day, 1/g")


def params_record(p_int, model="base", method="device", **extra) -> dict:
    """The saved-parameters JSON: model spec, integer parameters and their scale, decoded values."""
    names = fixed.PARAM_NAMES
    return {
        "model": model,
        "method": method,
        "scale": f"Q{fixed.PARAM_Q} (value = int / 2**{fixed.PARAM_Q}; offsets in g)",
        "params_int": {n: int(v) for n, v in zip(names, p_int)},
        "params": {n: float(v) for n, v in zip(names, params_to_float(p_int))},
        **extra,
    }


def save_params(path: str, record: dict) -> None:
    """Written whole or not at all (accelcal.files.outputs); the caller checked the path."""
    write_text(path, json.dumps(record, indent=2) + "\n")


def _reject_constant(name):
    raise ValueError(f"{name} is not a number JSON allows")


def _effects_within(spec: ModelSpec, p_int) -> bool:
    """Every effect parameter inside its bound: the device's test where the device has the
    effect, the catalogue's bound in the same Q24 units where only the host does."""
    if not spec.host_only:
        kinds = spec.kinds
        return not kinds or dmodel.effects_within(p_int, kinds, 1)
    for k, e in enumerate(spec.parts):
        b = e.to_int([e.bound])[0]
        if any(abs(v) > b for v in p_int[9 + 3 * k: 12 + 3 * k]):
            return False
    return True


def load_params(path: str, device: str | None = None) -> tuple[str, list[int], dict]:
    """(model spec, integer parameters, reference) from a saved file; `device` picks one from a
    `calibrate --by` file.  The reference (T0 degC, t0 s) is a composed model's; {} for base.
    Everything is checked: the shape, integer parameters inside the device's calibration bounds
    (a file no fit could have written is refused), a finite reference."""
    check_regular(path)
    if Path(path).stat().st_size > PARAMS_MAX_BYTES:
        raise InputError(f"{path}: not a parameters file (larger than "
                         f"{PARAMS_MAX_BYTES >> 20} MB)")
    try:
        text = Path(path).read_bytes().decode("utf-8")
        rec = json.loads(text, parse_constant=_reject_constant)
    except OSError as e:
        raise InputError(f"{path}: cannot open ({e.strerror})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a parameters file (not UTF-8 text)") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not JSON ({e.msg} at line {e.lineno})") from None
    except ValueError as e:
        raise InputError(f"{path}: {e}") from None
    except RecursionError:
        raise InputError(f"{path}: not a parameters file (JSON nested too deeply)") from None
    if not isinstance(rec, dict):
        raise InputError(f"{path}: a parameters file is a JSON object (from calibrate --save); "
                         f"found {type(rec).__name__}")
    if "devices" in rec:
        by = rec.get("by", "device")
        devs = rec["devices"]
        if not isinstance(by, str) or not isinstance(devs, list) or \
                not all(isinstance(d, dict) for d in devs):
            raise InputError(f"{path}: 'devices' must be a list of calibrations (from "
                             "calibrate --by ... --save)")
        names = [str(d.get(by)) for d in devs]
        if device is None:
            raise InputError(f"{path} holds {len(names)} devices; choose one with --device "
                             f"({', '.join(names[:5])}{', ...' if len(names) > 5 else ''})")
        if device not in names:
            raise InputError(f"{path}: no {by} {device!r}")
        rec = devs[names.index(device)]
    elif device is not None:
        raise InputError(f"{path} holds one calibration; --device applies to calibrate --by files")
    model = rec.get("model", "base")
    if not isinstance(model, str):
        raise InputError(f"{path}: 'model' must be a model name such as base or base+drift")
    try:
        spec = ModelSpec.parse(model)
    except ValueError as e:
        raise InputError(f"{path}: {e}") from None
    names = spec.param_names
    extra = " and reference {T0, t0}" if spec.effects else ""
    pi = rec.get("params_int")
    if not isinstance(pi, dict) or not all(n in pi for n in names):
        raise InputError(f"{path}: needs params_int with {', '.join(names)}{extra}")
    for n in names:
        v = pi[n]
        if isinstance(v, bool) or not isinstance(v, int):
            raise InputError(f"{path}: params_int.{n} must be an integer (Q24), found {v!r:.40}")
    p_int = [pi[n] for n in names]
    ref = {}
    if spec.effects:
        r = rec.get("reference")
        if not isinstance(r, dict) or not {"T0", "t0"} <= set(r) or not all(
                isinstance(r[k], (int, float)) and not isinstance(r[k], bool)
                and math.isfinite(r[k]) for k in ("T0", "t0")):
            raise InputError(f"{path}: needs params_int with {', '.join(names)}{extra} "
                             "(finite numbers)")
        ref = {"T0": float(r["T0"]), "t0": float(r["t0"])}
        if not -100 <= ref["T0"] <= 200:
            raise InputError(f"{path}: reference.T0 {ref['T0']:g} degC is not a temperature a "
                             "sensor works at")
        if spec.change_point:
            ts = r.get("ts")
            if isinstance(ts, bool) or not isinstance(ts, (int, float)) or not math.isfinite(ts):
                raise InputError(f"{path}: model {spec} needs reference.ts, the step's time in s "
                                 "(finite)")
            ref["ts"] = float(ts)
        for c in spec.columns:   # a column effect's reference: the column's mean
            k = column_ref(c)
            v = r.get(k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"{path}: model {spec} needs reference.{k}, the mean of column "
                                 f"{c} it was fitted at (finite)")
            ref[k] = float(v)
    if not dmodel.in_bounds(p_int) or not _effects_within(spec, p_int):
        raise InputError(f"{path}: parameters outside the calibration bounds (docs/method-and-formats.md \"Fixed-"
                         "point formats\"): no fit writes these")
    return str(spec), p_int, ref
