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
                return Table(path, {h: np.ascontiguousarray(data[:, i]) for i, h in enumerate(header)},
                             kind, {})
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
    return Table(path, out, kind, text)


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
    Path(path).write_text(json.dumps(record, indent=2) + "\n")


def load_params(path: str, device: str | None = None) -> tuple[str, list[int], dict]:
    """(model spec, integer parameters, reference) from a saved file; `device` picks one from a
    `calibrate --by` file.  The reference (T0 degC, t0 s) is a composed model's; {} for base."""
    try:
        rec = json.loads(Path(path).read_text())
    except OSError as e:
        raise InputError(f"{path}: cannot open ({e.strerror})") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not JSON ({e.msg} at line {e.lineno})") from None
    if isinstance(rec, dict) and "devices" in rec:
        by = rec.get("by", "device")
        names = [str(d.get(by)) for d in rec["devices"]]
        if device is None:
            raise InputError(f"{path} holds {len(names)} devices; choose one with --device "
                             f"({', '.join(names[:5])}{', ...' if len(names) > 5 else ''})")
        if device not in names:
            raise InputError(f"{path}: no {by} {device!r}")
        rec = rec["devices"][names.index(device)]
    elif device is not None:
        raise InputError(f"{path} holds one calibration; --device applies to calibrate --by files")
    from accelcal.effects import ModelSpec
    try:
        spec = ModelSpec.parse(str(rec.get("model", "base")))
    except ValueError as e:
        raise InputError(f"{path}: {e}") from None
    names = spec.param_names
    try:
        pi = rec["params_int"]
        p_int = [int(pi[n]) for n in names]
        ref = {k: float(v) for k, v in rec["reference"].items()} if spec.effects else {}
        if spec.effects and not {"T0", "t0"} <= set(ref):
            raise KeyError("reference")
    except (KeyError, TypeError, ValueError, AttributeError):
        extra = " and reference {T0, t0}" if spec.effects else ""
        raise InputError(f"{path}: needs params_int with {', '.join(names)}{extra}") from None
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
