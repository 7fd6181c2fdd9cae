"""CSV tables: recordings (t,x,y,z[,temp]) and points files (x,y,z plus optional temp, t, device,
...), read whole with every cell checked (docs/method-and-formats.md "Files")."""
from __future__ import annotations

import csv
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from accelcal.errors import InputError
from accelcal.files.checks import check_units, check_values
from accelcal.files.readers import ACTIGRAPHY, layout
from accelcal.files.recordings import read_whole

# A points file is read whole: beyond this it is not rest means (a 14-day recording gives ~10 MB)
POINTS_MAX_BYTES = 32 << 20
MIN_POINT_STEP_S = 1.0     # the shortest rest segment (--seconds >= 1)


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
    accelcal.files.recordings as recordings."""
    path = str(path)
    if Path(path).suffix.lower() in ACTIGRAPHY:
        t, xyz, temp, _ = read_whole(path)
        cols = {"t": t, "x": xyz[:, 0].copy(), "y": xyz[:, 1].copy(), "z": xyz[:, 2].copy()}
        if temp is not None:
            cols["temp"] = temp
        return Table(path, cols, "recording", {})
    lay = layout(path)     # the one rule: the kind, the header's names (files/readers.py)
    header = lay.header
    kind = lay.kind
    size = Path(path).stat().st_size
    if kind == "points" and size > POINTS_MAX_BYTES:
        raise InputError(f"{path}: a points file of {size >> 20} MB (at most "
                         f"{POINTS_MAX_BYTES >> 20} MB; a recording's header begins with its time "
                         "column)")
    try:
        fh = open(path, newline="")
    except OSError as e:
        raise InputError(f"{path}: cannot open ({e.strerror})") from None
    with fh:
        reader = csv.reader(fh)
        fh.readline()     # the header, read above within its bound
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
                return _checked(Table(path, {h: np.ascontiguousarray(data[:, i])
                                             for i, h in enumerate(header)}, kind, {}))
            fh.seek(0)
            fh.readline()
        try:
            rows = list(reader)
        except csv.Error as e:   # a cell past the csv module's limit, a NUL
            raise InputError(f"{path}:{reader.line_num}: not CSV ({e})") from None
        except UnicodeDecodeError:
            raise InputError(f"{path}: not a CSV text file (not UTF-8)") from None
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


def _checked(table: "Table") -> "Table":
    c = table.columns
    xyz = np.column_stack([c["x"], c["y"], c["z"]])
    check_values(table.path, c.get("t", np.empty(0)), xyz, c.get("temp"), 0)
    if table.kind == "points":
        check_units(table.path, xyz)   # rest means in m/s^2 or counts: the fix, in one line
    if table.kind == "points" and "t" in c and len(c["t"]) > 2:
        step = median(np.diff(c["t"]))
        if step < MIN_POINT_STEP_S:   # rest means lie a segment (>= 1 s) apart: samples do not
            raise InputError(f"{table.path}: a points file whose t steps by {step:.3g} s holds "
                             f"samples, not rest means; a recording's header begins with its "
                             f"time column (t,x,y,z...)")
    return table


def write_csv(path: str, header: list[str], columns: list[np.ndarray], fmt: list[str]) -> None:
    """Write columns as CSV quickly (numpy formatting, no Python loop per cell)."""
    data = np.column_stack(columns)
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)


def median(v: np.ndarray) -> float:
    """np.median(v) of a non-empty array without NaN, to the bit (the middle value, or the mean
    of the two middle ones), without np.median's check for masked arrays, which imports numpy.ma
    (0.05-0.2 s of a command's start here)."""
    n = len(v)
    half = n // 2
    if n % 2:
        return float(np.partition(v, half)[half])
    part = np.partition(v, [half - 1, half])
    return float((part[half - 1] + part[half]) / 2)


def sample_rate(t: np.ndarray, path: str = "") -> int:
    """Sample rate in Hz (int) from the median time step of a recording."""
    if len(t) < 2:
        raise InputError(f"{path}: a recording needs at least 2 samples")
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0))
        raise InputError(f"{path}:{i + 3}: time does not increase (t={t[i + 1]!r} after {t[i]!r})")
    rate = 1.0 / median(dt)
    r = int(round(rate))
    if r < 1 or not math.isfinite(rate):
        raise InputError(f"{path}: sample rate {rate:.3g} Hz is below 1 Hz")
    return r
