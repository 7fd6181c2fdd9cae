"""Samples a researcher already holds, as a recording (issue 51): a numpy array (n, 3) in g with
its rate or times, or a pandas or polars frame with named columns and a time index or column.
They become an ArrayRecording, which hands the same chunks to the same scan and device code as a
file's reader (files/recordings.py), checked the same way (files/checks.py): a frame and the CSV
holding its samples give the same calibration integers (tests/pipeline/test_arrays.py).

Column names (case-insensitive): x, y, z (also acc_x..., ax...); temperature `temp` or
`temperature` (degC); time `t` or `time`, a datetime or seconds, or the frame's index (pandas: a
DatetimeIndex, or a numeric index other than the default 0..n-1); any other numeric column is a
further column (e.g. battery_v), as in a CSV.  Datetimes become seconds since the epoch."""
from __future__ import annotations

from typing import Iterator

import numpy as np

from accelcal.errors import InputError
from accelcal.files.checks import check_values
from accelcal.files.recordings import CHUNK, Chunk, Recording

AXES_NAMES = (("x", "y", "z"), ("acc_x", "acc_y", "acc_z"), ("ax", "ay", "az"),
              ("accel_x", "accel_y", "accel_z"))
TIME_NAMES = ("t", "time", "timestamp", "datetime")
TEMP_NAMES = ("temp", "temperature")
KINDS = ("numpy", "pandas", "polars")


class ArrayRecording(Recording):
    """Samples in memory: t (n,) s, xyz (n, 3) g, temp (n,) degC or None, further columns.
    kind: what they came as ("numpy", "pandas", "polars"), so apply can give the same back;
    `path` is a label for messages and records ("<pandas DataFrame>")."""

    in_memory = True

    def __init__(self, t, xyz, temp=None, cols=None, kind: str = "numpy", original=None,
                 names=("x", "y", "z")):
        super().__init__(f"<{kind} {'array' if kind == 'numpy' else 'DataFrame'}>")
        self.format = f"{kind} {'array' if kind == 'numpy' else 'DataFrame'}"
        self.kind, self.original, self.names = kind, original, names
        self.t = _floats(t, "time", self.path)
        self.xyz = np.ascontiguousarray(_floats(xyz, "x, y, z", self.path))
        self.temp = None if temp is None else _floats(temp, "temperature", self.path)
        self.has_temp = self.temp is not None
        self.cols = {k: _floats(v, k, self.path) for k, v in (cols or {}).items()}
        self.columns = list(self.cols)
        n = len(self.xyz)
        for name, a in [("time", self.t), ("temperature", self.temp), *self.cols.items()]:
            if a is not None and len(a) != n:
                raise InputError(f"{self.path}: {name} has {len(a)} values for {n} samples")
        check_values(self.path, self.t, self.xyz, self.temp, 0, line_offset=0)

    def __str__(self):
        return self.path

    def chunks(self, size: int = CHUNK) -> Iterator[Chunk]:
        for a in range(0, len(self.t), size):
            b = min(len(self.t), a + size)
            yield Chunk(self.t[a:b], self.xyz[a:b], None if self.temp is None else self.temp[a:b],
                        a, {k: v[a:b] for k, v in self.cols.items()})

    def like(self, xyz: np.ndarray):
        """Calibrated samples xyz (n, 3) g as the kind given: an array, or a copy of the frame
        with its x, y, z columns replaced."""
        if self.kind == "numpy":
            return xyz
        if self.kind == "pandas":
            out = self.original.copy()
            for k, n in enumerate(self.names):
                out[n] = xyz[:, k]
            return out
        import polars as pl
        return self.original.with_columns([pl.Series(n, xyz[:, k]) for k, n in enumerate(self.names)])


def _floats(a, what: str, label: str) -> np.ndarray:
    try:
        out = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{label}: {what} values are not numbers") from None
    if not np.isfinite(out).all():
        bad = int(np.argmax(~np.isfinite(out).reshape(len(out), -1).all(axis=1)))
        raise InputError(f"{label}: {what} value at row {bad} is missing, NaN or infinite")
    return out


def seconds_of(values, label: str) -> np.ndarray:
    """Times as seconds: datetimes since the epoch (numpy datetime64, pandas or polars
    datetimes, timezone-aware ones in UTC), or numbers taken as seconds."""
    a = np.asarray(values)
    if a.dtype.kind == "O" and len(a) and hasattr(a[0], "timestamp"):   # aware datetimes
        a = np.array([v.timestamp() for v in a])
    if a.dtype.kind == "M":
        return a.astype("datetime64[ns]").astype(np.int64) / 1e9
    if a.dtype.kind == "m":
        return a.astype("timedelta64[ns]").astype(np.int64) / 1e9
    return _floats(a, "time", label)


def as_input(data, rate: float | None = None, temp=None, time=None):
    """A path (str or os.PathLike: returned as a str) or samples in memory (an ArrayRecording):
    a numpy array (n, 3) in g with rate (Hz) or time ((n,) s or datetimes), and temp ((n,)
    degC) if any; a pandas or polars frame with columns x, y, z (and temp, t/time; the module's
    names), its times from its index or time column, or from rate."""
    import os
    if isinstance(data, ArrayRecording):   # already made
        return data
    if isinstance(data, (str, os.PathLike)):
        if rate is not None or temp is not None or time is not None:
            raise InputError("rate, temp and time go with samples given as an array or frame; "
                             f"{data} is a file, whose own columns hold them")
        return str(data)
    mod = type(data).__module__.split(".")[0]
    if mod == "pandas" and hasattr(data, "columns"):
        return _frame(data, "pandas", rate, temp, time)
    if mod == "polars" and hasattr(data, "columns"):
        return _frame(data, "polars", rate, temp, time)
    if isinstance(data, np.ndarray) or mod == "numpy":
        xyz = np.asarray(data)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise InputError(f"samples as an array are (n, 3): x, y, z in g; got shape {xyz.shape}")
        return ArrayRecording(_times(len(xyz), rate, time, "<numpy array>"), xyz, temp)
    raise InputError(f"data: a file path, a numpy array (n, 3), or a pandas or polars DataFrame; "
                     f"got {type(data).__name__}")


def _times(n: int, rate, time, label: str) -> np.ndarray:
    if time is not None:
        if rate is not None:
            raise InputError(f"{label}: give rate or time, not both")
        return seconds_of(time, label)
    if rate is None:
        raise InputError(f"{label}: samples need their times: rate= (Hz) or time= (s or "
                         "datetimes), or a time column or index")
    if not (isinstance(rate, (int, float)) and np.isfinite(rate) and 0 < rate <= 100000):
        raise InputError(f"{label}: rate {rate!r} must be a sample rate in (0, 100000] Hz")
    return np.arange(n) / float(rate)


def _frame(df, kind: str, rate, temp, time) -> ArrayRecording:
    label = f"<{kind} DataFrame>"
    by_lower = {str(c).lower(): c for c in df.columns}
    names = next((tuple(by_lower[a] for a in trio) for trio in AXES_NAMES
                  if all(a in by_lower for a in trio)), None)
    if names is None:
        raise InputError(f"{label}: no x, y, z columns (found {', '.join(map(str, df.columns))[:200]})")
    col = lambda c: df[c].to_numpy()   # noqa: E731
    tcol = next((by_lower[k] for k in TIME_NAMES if k in by_lower), None)
    if time is None and tcol is not None:
        time = col(tcol)
    elif time is None and rate is None and kind == "pandas":
        idx = df.index
        if type(idx).__name__ != "RangeIndex" and idx.dtype.kind in "Mmfiu" or \
                str(idx.dtype).startswith("datetime64"):
            time = idx.to_numpy() if not getattr(idx, "tz", None) else idx.tz_convert("UTC").asi8 / 1e9
    t = _times(len(df), rate, time, label)
    kcol = next((by_lower[k] for k in TEMP_NAMES if k in by_lower), None)
    if temp is None and kcol is not None:
        temp = col(kcol)
    skip = set(names) | {tcol, kcol}
    cols = {str(c): col(c) for c in df.columns
            if c not in skip and np.asarray(col(c)).dtype.kind in "fiu"}
    xyz = np.column_stack([col(c) for c in names])
    return ArrayRecording(t, xyz, temp, cols, kind, df, names)
