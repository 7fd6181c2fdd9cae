"""Files: recordings and points files (DESIGN.md "Files"), saved parameters, and the conversion
between floats in g and the device's fixed-point integers (device/acal/fixed.py)."""
from __future__ import annotations

import csv
import warnings
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acal import fixed


class InputError(Exception):
    """Bad input: the CLI prints the message on one line and exits with status 2."""


RECORDING_HEADERS = (["t", "x", "y", "z"], ["t", "x", "y", "z", "temp"])


@dataclass
class Table:
    """A CSV file read into float columns (and string columns where they are not numeric)."""
    path: str
    columns: dict[str, np.ndarray]
    kind: str  # "recording" or "points"
    text_columns: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def xyz(self) -> np.ndarray:
        return np.column_stack([self.columns["x"], self.columns["y"], self.columns["z"]])

    def __len__(self):
        return len(self.columns["x"])


def read_table(path: str | Path, text_ok: tuple[str, ...] = ("device",)) -> Table:
    """Read a recording (header t,x,y,z[,temp]) or a points file (x,y,z plus optional temp, t,
    device, ...).  Every numeric cell is checked: non-numeric, missing or NaN -> InputError
    naming the line and column.  Actigraphy files (.cwa, .bin, .gt3x) are read whole through
    accelcal.recording as recordings."""
    path = str(path)
    from accelcal.recording import ACTIGRAPHY, read_whole
    if Path(path).suffix.lower() in ACTIGRAPHY:
        t, xyz, temp, _ = read_whole(path)
        cols = {"t": t, "x": xyz[:, 0].copy(), "y": xyz[:, 1].copy(), "z": xyz[:, 2].copy()}
        if temp is not None:
            cols["temp"] = temp
        return Table(path, cols, "recording", {})
    try:
        fh = open(path, newline="")
    except OSError as e:
        raise InputError(f"{path}: cannot open ({e.strerror})") from None
    with fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise InputError(f"{path}: empty file") from None
        for need in ("x", "y", "z"):
            if need not in header:
                raise InputError(f"{path}: header needs columns x,y,z (and t first for a recording); "
                                 f"found {','.join(header)}")
        if len(set(header)) != len(header):
            raise InputError(f"{path}: repeated column in header {','.join(header)}")
        if not any(h in text_ok for h in header):
            # Fast path: numpy's C parser.  Anything it rejects goes through the checks below,
            # which name the line and column.
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # "no data": said below, in one line
                    data = np.loadtxt(fh, delimiter=",", dtype=np.float64, ndmin=2)
            except ValueError:
                data = None
            if data is not None and data.shape[1] == len(header) and len(data) \
                    and np.isfinite(data).all():
                kind = "recording" if header in RECORDING_HEADERS else "points"
                return _checked(Table(path, {h: np.ascontiguousarray(data[:, i])
                                             for i, h in enumerate(header)}, kind, {}))
            fh.seek(0)
            next(reader)
        rows = list(reader)
    kind = "recording" if header in RECORDING_HEADERS else "points"
    ncol = len(header)
    cols: dict[str, list] = {h: [] for h in header}
    for lineno, row in enumerate(rows, start=2):
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if len(row) != ncol:
            raise InputError(f"{path}:{lineno}: expected {ncol} values, found {len(row)}")
        for h, cell in zip(header, row):
            cols[h].append(cell.strip())
    if not cols["x"]:
        raise InputError(f"{path}: no data rows")
    out: dict[str, np.ndarray] = {}
    text: dict[str, np.ndarray] = {}
    for h, cells in cols.items():
        if h in text_ok:
            text[h] = np.array(cells, dtype=object)
            continue
        try:
            arr = np.array(cells, dtype=np.float64)
        except ValueError:
            for i, c in enumerate(cells):
                try:
                    float(c)
                except ValueError:
                    what = "missing value" if c == "" else f"non-numeric value {c!r}"
                    raise InputError(f"{path}:{i + 2}: {what} in column {h}") from None
            raise
        bad = ~np.isfinite(arr)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(f"{path}:{i + 2}: {cells[i]} in column {h} (values must be finite)")
        out[h] = arr
    return _checked(Table(path, out, kind, text))


MAX_ABS_G = 256.0          # no wearable accelerometer reads more: a larger value is not a reading
TEMP_RANGE_C = (-100.0, 200.0)


def check_values(path: str, t, xyz, temp, first: int, last_t: float | None = None,
                 line_offset: int = 2) -> None:
    """Readings a sensor could have given: |x|, |y|, |z| <= MAX_ABS_G, temperatures within
    TEMP_RANGE_C, time never going back (also across chunks: last_t); InputError naming the
    line (first data line = line_offset) otherwise."""
    big = np.abs(xyz) > MAX_ABS_G
    if big.any():
        row = int(np.argmax(big.any(axis=1)))
        raise InputError(f"{path}:{first + row + line_offset}: {xyz[row][big[row]][0]:g} g is not "
                         f"an acceleration a wearable reads (|value| <= {MAX_ABS_G:g} g)")
    if temp is not None:
        lo, hi = TEMP_RANGE_C
        off = (temp < lo) | (temp > hi)
        if off.any():
            row = int(np.argmax(off))
            raise InputError(f"{path}:{first + row + line_offset}: temperature {temp[row]:g} degC "
                             f"is outside {lo:g}..{hi:g} degC")
    if len(t):
        back = np.diff(t) < 0
        if back.any():
            row = int(np.argmax(back)) + 1
            raise InputError(f"{path}:{first + row + line_offset}: time goes back ({t[row - 1]:g} "
                             f"s, then {t[row]:g} s)")
        if last_t is not None and t[0] < last_t:
            raise InputError(f"{path}:{first + line_offset}: time goes back ({last_t:g} s, then "
                             f"{t[0]:g} s)")


def _checked(table: "Table") -> "Table":
    c = table.columns
    xyz = np.column_stack([c["x"], c["y"], c["z"]])
    check_values(table.path, c.get("t", np.empty(0)), xyz, c.get("temp"), 0)
    return table


def g_to_sample(g: np.ndarray) -> np.ndarray:
    """Floats in g -> device samples (Q10 g ints), rounded, clipped to the +-16 g range."""
    q = np.rint(np.asarray(g, dtype=np.float64) * fixed.SAMPLE_ONE_G)
    return np.clip(q, -fixed.SAMPLE_MAX, fixed.SAMPLE_MAX).astype(np.int64)


def g_to_point(g: np.ndarray) -> np.ndarray:
    """Floats in g -> device points (Q16 g ints), rounded."""
    return np.rint(np.asarray(g, dtype=np.float64) * fixed.POINT_ONE_G).astype(np.int64)


def point_to_g(q) -> np.ndarray:
    return np.asarray(q, dtype=np.float64) / fixed.POINT_ONE_G


def sample_to_g(q) -> np.ndarray:
    return np.asarray(q, dtype=np.float64) / fixed.SAMPLE_ONE_G


def params_to_float(p_int) -> np.ndarray:
    return np.asarray(p_int, dtype=np.float64) / fixed.PARAM_ONE


def params_to_int(p: np.ndarray) -> list[int]:
    return [int(v) for v in np.rint(np.asarray(p, dtype=np.float64) * fixed.PARAM_ONE)]


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
    """Written whole or not at all (accelcal.outputs); the caller checked the path."""
    from accelcal.outputs import write_text
    write_text(path, json.dumps(record, indent=2) + "\n")


def _reject_constant(name):
    raise ValueError(f"{name} is not a number JSON allows")


def load_params(path: str, device: str | None = None) -> tuple[str, list[int], dict]:
    """(model spec, integer parameters, reference) from a saved file; `device` picks one from a
    `calibrate --by` file.  The reference (T0 degC, t0 s) is a composed model's; {} for base.
    Everything is checked: the shape, integer parameters inside the device's calibration bounds
    (a file no fit could have written is refused), a finite reference."""
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
    from accelcal.effects import ModelSpec
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
    from acal import effects as deffects
    from acal import model as dmodel
    kinds = tuple(deffects.parse_model(str(spec)))
    if not dmodel.in_bounds(p_int) or (kinds and not dmodel.effects_within(p_int, kinds, 1)):
        raise InputError(f"{path}: parameters outside the calibration bounds (README \"Fixed-"
                         "point formats\"): no fit writes these")
    return str(spec), p_int, ref


def write_csv(path: str, header: list[str], columns: list[np.ndarray], fmt: list[str]) -> None:
    """Write columns as CSV quickly (numpy formatting, no Python loop per cell)."""
    data = np.column_stack(columns)
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)


def sample_rate(t: np.ndarray, path: str = "") -> int:
    """Sample rate in Hz (int) from the median time step of a recording."""
    if len(t) < 2:
        raise InputError(f"{path}: a recording needs at least 2 samples")
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0))
        raise InputError(f"{path}:{i + 3}: time does not increase (t={t[i + 1]!r} after {t[i]!r})")
    rate = 1.0 / float(np.median(dt))
    r = int(round(rate))
    if r < 1 or not math.isfinite(rate):
        raise InputError(f"{path}: sample rate {rate:.3g} Hz is below 1 Hz")
    return r
