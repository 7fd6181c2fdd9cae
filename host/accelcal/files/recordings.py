"""Recordings of any size and format, read in chunks onto our recording model (docs/method-and-formats.md "Files"):
time t in s, x/y/z in g, temperature in degC where the device records it.

* CSV (header t,x,y,z[,temp][,NAME...]) streams through Apache Arrow's CSV reader: a C++ engine,
  pieces of the file parsed on both cores at once (files/csvpieces.py), so memory stays constant
  whatever the file's length.
* Axivity .cwa (AX3, AX6), GENEActiv .bin and ActiGraph .gt3x go through `actfast`, a maintained
  reader of all three.  It reads a whole file at once (about 20 bytes a sample: a 14-day 100 Hz
  file would need ~2.4 GB), so a .cwa, made of self-contained 512-byte blocks, goes to it in
  pieces of a few MB (CwaRecording): constant memory.  .bin and .gt3x are read whole.  Time: seconds since the epoch (the file's
  clock); temperature: the device's once-per-block reading, held until the next (as the devices'
  own exporters do).  The axes are taken as they are: gyroscopes, light, buttons are dropped.

Gaps: a step in t longer than 1.5 sample periods and longer than GAP_S starts a new contiguous
run.  Real devices' timestamps jitter at block boundaries (an AX3 at 200 Hz: steps of 5 to 15 ms),
which must not cut every rest segment; a second missing inside a 5 s segment moves its mean by
nothing that matters.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Iterator

import numpy as np

from accelcal.errors import InputError
from accelcal.files.checks import MAX_ABS_G, TEMP_RANGE_C, check_values
from accelcal.files.csvpieces import parsed
from accelcal.files.devheaders import check_cwa, check_device_file
from accelcal.files.readers import ACTIGRAPHY, is_recording, layout, recording_columns  # noqa: F401

# Which file is a recording, and its header's names: files/readers.py (the one rule).
COLUMN_MAX = 1e9     # |value| of an extra column: beyond it a float fit loses its digits
GAP_S = 1.0
CHUNK = 1 << 20                      # samples per chunk handed on
GT3X_EXTRA = ("install the optional ActiGraph reader: pip install 'accelcal[gt3x]' (pygt3x)")
STANDARD_RANGES_G = (2, 4, 8, 16)


class Chunk:
    """Consecutive samples: t (n,) s; xyz (n, 3) g float64; temp (n,) degC or None; first: the
    stream index of the first sample; cols: the recording's further columns by name, (n,) each.

    axes: x, y, z as the reader has them (three (n,) columns, or an (n, 3) array of the reader's
    dtype: float32 from actfast), from which xyz is made the first time it is asked for: the
    scan converts the axes to the device's samples directly (accelcal.bridge.twin.planar_of),
    and most chunks never need the float64 copy.  planar: those samples, when a read-ahead
    thread has made them already (pipeline/scan.py), else None."""

    __slots__ = ("t", "axes", "temp", "first", "cols", "planar", "_xyz")

    def __init__(self, t: np.ndarray, xyz: np.ndarray | None, temp: np.ndarray | None, first: int,
                 cols: dict | None = None, axes=None):
        self.t, self.temp, self.first = t, temp, first
        self.cols = {} if cols is None else cols
        self.axes = xyz if axes is None else axes
        self._xyz = xyz if xyz is not None and xyz.dtype == np.float64 else None
        self.planar = None

    @property
    def xyz(self) -> np.ndarray:
        if self._xyz is None:
            a = self.axes
            self._xyz = np.column_stack(a) if isinstance(a, tuple) else a.astype(np.float64)
        return self._xyz


def gap_limit(rate_hz: float) -> float:
    """A gap: a step in time over 1 s and over 2.5 sample periods (at rates under 2.5 Hz a
    block's timestamps place samples up to a period off: an AX3 at 1.5625 Hz steps 0.44-1.08 s
    where a block's whole-second timestamp falls between two samples)."""
    return max(2.5 / rate_hz, GAP_S)


class Recording:
    """A recording opened for reading in chunks.  `format` names it; `range_g` is the full scale
    the file declares (None: not declared); `meta` the reader's metadata (JSON-ready)."""

    format = "?"

    def __init__(self, path: str):
        self.path = str(path)
        self.range_g: float | None = None
        self.meta: dict = {}
        self.has_temp = False
        self.columns: list[str] = []    # further named columns (CSV only), Chunk.cols
        self.warnings: list[str] = []   # what the reader said of the file (kept in the report)
        self.overlapping_pages: int | None = None   # a paged format's (GENEActiv), resolved
        self.pages_missing = self.pages_cut = 0      # a truncated file's (binpages.py)

    def chunks(self, size: int = CHUNK) -> Iterator[Chunk]:
        raise NotImplementedError


def open_recording(path: str | Path) -> Recording:
    """The reader for a file, by the rule of files/readers.py: .cwa/.bin/.gt3x are actigraphy
    files, a CSV is a recording by its header (a points file or anything else: InputError).
    A Recording already open (samples in memory: files/arrays.py) is itself."""
    if isinstance(path, Recording):
        return path
    path = str(path)
    lay = layout(path)
    ext = Path(path).suffix.lower()
    if ext == ".cwa":
        return CwaRecording(path)
    if ext in ACTIGRAPHY:
        return ActigraphyRecording(path)
    return CsvRecording(path, lay)


class CsvRecording(Recording):
    format = "CSV"

    def __init__(self, path: str, lay=None):
        super().__init__(path)
        lay = lay or layout(path)
        if lay.kind != "recording":
            raise InputError(f"{path}: a points file, not a recording: a recording's header begins "
                             f"with its time column, then x,y,z (found {','.join(lay.raw)[:120]})")
        self.header = lay.header     # the rule's names (t, temp) for the file's spellings
        self.has_temp = "temp" in self.header
        self.columns = lay.further

    def chunks(self, size: int = CHUNK) -> Iterator[Chunk]:
        """One chunk per piece of the file parsed on both cores (files/csvpieces.py: the first
        is Arrow's first 1 MB block, then 4 MB of text each): memory stays constant; `size`
        is not used."""
        first = 0
        self._last_t = None
        # what check_values and the further columns' bound allow, checked in the parsing threads
        limits = ["rising"] + [(-MAX_ABS_G, MAX_ABS_G)] * 3 + \
            ([TEMP_RANGE_C] if self.has_temp else []) + [(-COLUMN_MAX, COLUMN_MAX)] * len(self.columns)
        for cols, checked in parsed(self.path, self.header, limits):
            yield self._chunk(cols, first, checked)
            first += len(cols[0])
        if first == 0:
            raise InputError(f"{self.path}: no data rows")

    def _chunk(self, cols: list, first: int, checked: bool) -> Chunk:
        # the rows' columns, each parsed and finite (csvpieces.parse); checked: within the
        # limits check_values and COLUMN_MAX set (csvpieces.parse), so only time across pieces
        # is left; else the value checks find and name the row
        axes = tuple(cols[1:4])
        extra = dict(zip(self.columns, cols[len(self.header) - len(self.columns):]))
        if checked:
            if self._last_t is not None and cols[0][0] < self._last_t:
                check_values(self.path, cols[0][:1], np.column_stack([a[:1] for a in axes]), None,
                             first, self._last_t)
            self._last_t = float(cols[0][-1])
            return Chunk(cols[0], None, cols[4] if self.has_temp else None, first, extra, axes)
        xyz = np.column_stack(axes)
        check_values(self.path, cols[0], xyz, cols[4] if self.has_temp else None, first,
                     self._last_t)
        for name, v in extra.items():
            big = np.abs(v) > COLUMN_MAX
            if big.any():
                row = first + int(np.argmax(big))
                raise InputError(f"{self.path}:{row + 2}: {v[row - first]:g} in column {name} "
                                 f"(|value| <= {COLUMN_MAX:g})")
        self._last_t = float(cols[0][-1])
        return Chunk(cols[0], xyz, cols[4] if self.has_temp else None, first, extra)


def _actfast(path: str, fmt: str) -> dict:
    import actfast
    try:
        return actfast.read(path)
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as e:  # actfast's own errors, and a Rust panic (a BaseException)
        raise InputError(f"{path}: not a readable {fmt} file "
                         f"({' '.join(str(e).split())[:200]})") from None


def _read_bin(path: str, fmt: str, pages) -> dict:
    """A GENEActiv .bin's whole pages, by actfast (a truncated file's through a scratch copy
    that declares them, files/binpages.py), a page cut mid-way dropped."""
    if not pages.short:
        return _actfast(path, fmt)
    from accelcal.files.binpages import whole_pages
    with whole_pages(path, pages) as tmp:
        return _actfast(tmp, fmt)


def _group(timeseries: dict, key: str) -> dict | None:
    # The timeseries group that holds `key`: actfast names groups by rate for GENEActiv and
    # Axivity (high_frequency, low_frequency) and by sensor for ActiGraph (acceleration, ...).
    for g in timeseries.values():
        if isinstance(g, dict) and key in g and len(g[key]):
            return g
    return None


def _columns(data: dict, paged: bool = False):
    """actfast's dict -> (t s, xyz (n, 3) g float32, temp degC held per reading or None).
    paged: a GENEActiv file, whose overlapping page times are resolved first (files/pagetimes.py;
    the count in data["overlapping_pages"])."""
    ts = data.get("timeseries", {})
    hf = _group(ts, "acceleration")
    if hf is None:
        return None
    t = hf["datetime"].astype(np.float64) / 1e9
    if paged:
        from accelcal.files.pagetimes import resolve_overlaps
        data["overlapping_pages"] = resolve_overlaps(t)
    lf = _group(ts, "temperature")
    temp = None
    if lf is not None:
        tl = lf["datetime"].astype(np.float64) / 1e9
        temp = lf["temperature"].astype(np.float64)[held_index(tl, t)]
    return t, hf["acceleration"], temp


def held_index(tl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """For each time in t, the index of the last reading at tl at or before it (0 before the
    first): np.searchsorted(tl, t, "right") - 1, clipped at 0.  Both in order (as a file's
    clock runs): each reading's index repeated over the samples it holds for, a binary search
    per reading rather than per sample (a quarter of a .cwa's read time) and one pass over t."""
    n = len(t)
    if n and len(tl) and (np.diff(t) >= 0).all() and (np.diff(tl) >= 0).all():
        starts = np.searchsorted(t, tl, side="left")   # the first sample at or after each reading
        held = np.diff(np.r_[starts, n])                # samples each reading holds for
        held[0] += starts[0]                            # and the first, those before it
        return np.repeat(np.arange(len(tl)), held)
    return np.clip(np.searchsorted(tl, t, side="right") - 1, 0, None)


def _pygt3x_read(path: str):
    """An ActiGraph file through pygt3x, if installed (the optional extra `accelcal[gt3x]`):
    ((t s, xyz (n, 3) g float32, temp degC held per reading or None), metadata, its log
    messages) or None when
    pygt3x is not installed.  pygt3x reads what actfast does not: GT9X Link files (no samples
    from actfast), old NHANES-format .gt3x (activity.bin, no log.bin) and CentrePoint .agdc (the
    same zip of log.bin and info.txt as a .gt3x; pygt3x's README).  Idle-sleep rows (the
    device stopped sampling while still and the reader repeats a sample) are left out: a gap,
    never rest.  Temperature: the accelerometer chip's own (ADXL) reading, held until the
    next; the board's (MCU) is kept out, it warms with the electronics, not the sensor."""
    try:
        from pygt3x.reader import FileReader
    except ImportError:
        return None
    import logging
    said: list[str] = []     # what pygt3x logs of the file: the record's reader warnings

    class Said(logging.Handler):
        def emit(self, record):
            said.append(record.getMessage())
    log = logging.getLogger("pygt3x")
    handler, propagate = Said(), log.propagate
    log.addHandler(handler)
    log.propagate = False
    import warnings
    try:
        with FileReader(path) as r, warnings.catch_warnings():
            warnings.simplefilter("ignore")   # pandas' deprecations inside pygt3x, not ours
            df = r.to_pandas()
            info = {k: v for k, v in vars(r.info).items() if isinstance(v, (int, float, str))}
            temp_df = r.temperature_to_pandas() if "log.bin" in r.zipfile.namelist() else None
    except Exception as e:   # pygt3x's own errors for files it cannot read
        raise InputError(f"{path}: not a readable ActiGraph file ({' '.join(str(e).split())[:200]})"
                         ) from None
    finally:
        log.removeHandler(handler)
        log.propagate = propagate
    if "IdleSleepMode" in df:
        df = df[~df["IdleSleepMode"].astype(bool)]
    t = df.index.values.astype(np.float64)
    temp = None
    if temp_df is not None and len(temp_df) and "TemperatureADXL" in temp_df:
        tl = temp_df.index.values.astype(np.float64)
        held = np.clip(np.searchsorted(tl, t, side="right") - 1, 0, None)
        temp = temp_df["TemperatureADXL"].values.astype(np.float64)[held]
    return (t, df[["X", "Y", "Z"]].values.astype(np.float32), temp), {"info": info}, said


class ActigraphyRecording(Recording):
    """GENEActiv .bin, ActiGraph .gt3x: read whole by actfast, handed on in chunks."""

    def __init__(self, path: str):
        super().__init__(path)
        ext = Path(path).suffix.lower()
        self.format = ACTIGRAPHY[ext]
        pages = check_device_file(path)     # what the readers trust, before they see the file
        data, cols = {}, None
        why = "CentrePoint .agdc files are read by pygt3x"
        if ext != ".agdc":    # actfast does not know CentrePoint files: pygt3x reads them
            try:
                data = _read_bin(path, self.format, pages) if pages else _actfast(path, self.format)
            except InputError as e:
                if ext != ".gt3x":
                    raise
                why = str(e).removeprefix(f"{path}: ")   # an old NHANES-format .gt3x, say
            self.format = data.get("format", self.format)
            cols = _columns(data, ext == ".bin") if data else None
            if data and cols is None:
                why = "actfast reads no samples from this ActiGraph file (a GT9X Link?)"
        if cols is None and ext in (".gt3x", ".agdc"):
            read = _pygt3x_read(path)
            if read is None:
                raise InputError(f"{path}: {why}; {GT3X_EXTRA}")
            cols, data["metadata"], data["warnings"] = read
            self.reader = "pygt3x"
        if cols is None or not len(cols[0]):
            raise InputError(f"{path}: {self.format} file holds no acceleration samples")
        self.t, self.xyz, self.temp = cols
        _check_samples(path, self.t, self.xyz, self.temp, 0)
        self.has_temp = self.temp is not None
        self.meta = data.get("metadata", {})
        self.warnings = [" ".join(str(w).split()) for w in data.get("warnings", [])]
        self.range_g = _declared_range(self.meta)
        if ext == ".bin":   # pages whose times overlapped, placed as the maker's readers place them
            self.overlapping_pages = data.get("overlapping_pages", 0)
            if pages and pages.short:     # a truncated file (files/binpages.py)
                self.pages_missing, self.pages_cut = pages.missing, pages.cut
                self.warnings.append(pages.warning())

    def chunks(self, size: int = CHUNK) -> Iterator[Chunk]:
        n = len(self.t)
        for a in range(0, n, size):
            b = min(n, a + size)
            yield Chunk(self.t[a:b], None, None if self.temp is None else self.temp[a:b], a,
                        axes=self.xyz[a:b])


class CwaRecording(Recording):
    """Axivity .cwa, streamed: the file is a header packet ('MD', its length in bytes 2-3) and
    512-byte data blocks, each with its own timestamp, temperature and samples.  actfast reads a
    piece made of the header and a run of blocks to exactly what it reads for those blocks in
    the whole file (tests/files/test_formats.py), so pieces of BLOCKS blocks go through a scratch file
    one at a time: constant memory for any length (a 14-day 100 Hz file is ~1 M blocks)."""

    BLOCKS = 8192      # 4 MB of file, ~1 M samples of an AX3 (120 per packed block)
    BLOCK = 512

    def __init__(self, path: str):
        super().__init__(path)
        self.format = "Axivity CWA"
        with open(path, "rb") as fh:
            head = fh.read(1024 + self.BLOCK)
        size = Path(path).stat().st_size
        check_cwa(head, path, size)     # the header packet and the first block's rate
        self.header_len = int.from_bytes(head[2:4], "little") + 4
        self.n_blocks = max(0, (size - self.header_len) // self.BLOCK)
        if self.n_blocks and (size - self.header_len) % self.BLOCK:   # a last block cut: dropped
            self.pages_cut = 1
            self.warnings.append(f"a truncated file: {self.n_blocks} whole data blocks and 1 "
                                 "cut mid-way (dropped)")
        if self.n_blocks == 0:
            raise InputError(f"{path}: {self.format} file holds no data blocks")
        first = self._piece(0, 1)
        self.format = first.get("format", self.format)
        self.meta = first.get("metadata", {})
        self.range_g = _declared_range(self.meta)
        cols = _columns(first)
        self.has_temp = cols is not None and cols[2] is not None

    def _piece(self, a: int, b: int) -> dict:
        import tempfile
        with open(self.path, "rb") as fh:
            header = fh.read(self.header_len)
            fh.seek(self.header_len + a * self.BLOCK)
            blocks = fh.read((b - a) * self.BLOCK)
        scratch = "/dev/shm" if Path("/dev/shm").is_dir() else None
        with tempfile.NamedTemporaryFile(suffix=".cwa", dir=scratch) as tmp:
            tmp.write(header + blocks)
            tmp.flush()
            return _actfast(tmp.name, f"{self.format} (blocks {a}-{b - 1} of {self.path})")

    def chunks(self, size: int = CHUNK) -> Iterator[Chunk]:
        first = 0
        held = [float("nan")]   # the last temperature reading, for a piece without one
        for a in range(0, self.n_blocks, self.BLOCKS):
            data = self._piece(a, min(self.n_blocks, a + self.BLOCKS))
            self.warnings += [" ".join(str(w).split()) for w in data.get("warnings", [])]
            cols = _columns(data)
            if cols is None:
                continue
            t, xyz, temp = cols
            _check_samples(self.path, t, xyz, temp, first)
            if self.has_temp and temp is None:   # a piece without a reading: hold the last
                temp = np.full(len(t), held[0])
            yield Chunk(t, None, temp if self.has_temp else None, first, axes=xyz)
            if self.has_temp:
                held[0] = float(temp[-1])
            first += len(t)
        if first == 0:
            raise InputError(f"{self.path}: {self.format} file holds no acceleration samples")


def _check_samples(path: str, t, xyz, temp, first: int) -> None:
    """What a device reader gave, as check_values bounds a CSV's: finite times, accelerations
    within MAX_ABS_G, temperatures within TEMP_RANGE_C; InputError naming the sample."""
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(xyz) <= MAX_ABS_G).all(axis=1) | ~np.isfinite(t)
        if temp is not None:
            bad |= ~((temp >= TEMP_RANGE_C[0]) & (temp <= TEMP_RANGE_C[1]))
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{path}: sample {first + i}: t {t[i]:g} s, x/y/z {xyz[i][0]:g} "
                         f"{xyz[i][1]:g} {xyz[i][2]:g} g, temperature "
                         f"{'-' if temp is None else f'{temp[i]:g}'} degC: not what a device "
                         f"reads (|g| <= {MAX_ABS_G:g}, {TEMP_RANGE_C[0]:g}..{TEMP_RANGE_C[1]:g} "
                         "degC; a damaged file)")


def _declared_range(meta: dict) -> float | None:
    """The full scale a file's header declares: Axivity's accelerometer_range_g, GENEActiv's
    "Accelerometer Range" ("-8 to 8"), ActiGraph's info.txt "Acceleration Max" ("8.0", as
    actfast gives it; acceleration_max as pygt3x does; 0 in files that leave it out)."""
    for sec in meta.values():
        if not isinstance(sec, dict):
            continue
        for k, v in sec.items():
            if k in ("accelerometer_range_g", "Accelerometer Range", "Acceleration Max",
                     "acceleration_max"):
                try:
                    g = float(str(v).split()[-1])
                except (ValueError, IndexError):
                    return None
                # a range no accelerometer has (nan, 0, 1e300) is not declared: None
                return g if math.isfinite(g) and 0 < g <= 400 else None
    return None


def read_whole(path: str | Path):
    """(t, xyz, temp or None, recording) of a whole recording, for what needs it in memory."""
    rec = open_recording(path)
    parts = list(rec.chunks())
    t = np.concatenate([c.t for c in parts])
    xyz = np.concatenate([c.xyz for c in parts])
    temp = np.concatenate([c.temp for c in parts]) if rec.has_temp else None
    return t, xyz, temp, rec


def sensor_of(path: str | Path) -> str | None:
    """The accelerometer a file's figures may be worded for: the LIS3DH of accelcal's boards
    and simulator for a recording CSV; a device file's format name (whose sensor is not the
    LIS3DH); None for anything else (a points file; samples in memory, their sensor unknown)."""
    if isinstance(path, Recording):
        return None
    try:
        lay = layout(path)
    except InputError:
        return None
    if lay.kind != "recording":
        return None
    return ACTIGRAPHY.get(Path(path).suffix.lower(), "LIS3DH")
