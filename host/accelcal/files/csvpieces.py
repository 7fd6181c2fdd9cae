"""A recording CSV parsed in pieces on both cores (CsvRecording.chunks): the file is cut at line
ends into pieces of PIECE bytes, each parsed in a worker thread, WORKERS pieces at once, checked
by numpy there and handed on in the file's order.  Each piece is read into one of WORKERS + 1
buffers made once and reused (not mapped: a mapped page past the file's end kills the process
when touched, so a file cut short while a piece was parsed did; read, it is a short read and a
one-line refusal), and parsed there in place.
Arrow's streaming reader parses one block after another on one core: on the 14-day 100 Hz file
(4.5 GB) the parse alone was most of the command's time.

A piece is parsed first by our C fast path (_csvfast.c, the GIL released), which takes only the
plain form a recording has: fields -?digits(.digits)?, the header's number of them on every line,
lines ending in \n or \r\n (the last may have none), values correctly rounded by Clinger's exact
path (all digits an integer below 2^53, at most 22 decimals), so bit for bit Arrow's.  Anything
else in a piece (quotes, spaces, exponents, '+', '.5', '1.', empty fields, blank lines, nan, inf,
another column count, more digits) and the whole piece goes to Arrow's CSV reader (C++, the GIL
released) as before, so every answer and error message is Arrow's or ours as it was.  Where the
module was not built (no C compiler at install: setup.py makes it optional) or with
ACCELCAL_CSV_FAST=0, Arrow parses every piece.  On the 14-day file the fast path parses in ~6 s of
CPU what Arrow parsed in ~20-23 s (docs/real-recordings.md "Real recordings").

What is handed on is what the streaming reader gave: the same rows and values; a bad row is
named by its line in the file (the first bad row of a piece, whatever its column).  The first piece is Arrow's first 1 MB block as the
streaming reader cut it, so the first chunk, on which scan estimates the rate, is the same.
Arrow parses each piece as one block (its columns come to numpy without a copy); the reader's
value checks (files/checks.py) are made in the same threads as two reductions per column, and
only a piece that fails them is looked at value by value, on the main thread, to name the row.
Memory: WORKERS + 1 buffers of PIECE bytes of text (12 MB) and the columns of the pieces in
flight (~5 MB each)."""
from __future__ import annotations

import os
import re
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from accelcal.errors import InputError

try:        # built by `pip install` where a C compiler is (setup.py: optional); else Arrow alone
    from accelcal.files import _csvfast
except ImportError:
    _csvfast = None

BLOCK = 1 << 20       # Arrow's block: a longer line is refused (not a recording's)
PIECE = 4 << 20       # bytes of text per piece after the first (1 MB: ~25 % more CPU in read_csv calls)
WORKERS = 2
LONG_LINE = "a line longer than 1 MB (not a recording's line)"


def arrow():
    """(pyarrow, pyarrow.csv), told once that pandas is not there: its lazy pandas check (on the
    first array it makes or converts) would import pandas where installed, 0.3-1.4 s here, for
    nothing: no pandas object is made from Arrow's here.  pandas, if installed, stays importable
    for whatever imports it itself (pygt3x)."""
    import sys
    import pyarrow as pa
    import pyarrow.csv as pacsv
    if "pandas" not in sys.modules:
        class NoPandas:      # import pandas -> ImportError, remembered by pyarrow
            def find_spec(self, name, path=None, target=None):
                if name == "pandas":
                    raise ModuleNotFoundError("pandas", name="pandas")
        blocker = NoPandas()
        sys.meta_path.insert(0, blocker)
        try:
            pa.array([0.0]).to_numpy()
        finally:
            sys.meta_path.remove(blocker)
    return pa, pacsv


def cut(path: str, fh, n: int, first: int, size: int, buffers: list):
    """The file's first n bytes (fh: the file opened unbuffered) in pieces ending at a line end
    (the last may not), each read into the next of `buffers` in turn and given as a view of it:
    the first piece within `first` bytes, then within `size` bytes each.  A buffer is read into
    again len(buffers) pieces later: the caller is done with a piece by then.  No line longer
    than BLOCK (Arrow's streaming reader refused one; the pieces are parsed as one block each)."""
    start, want, k = 0, first, 0
    while start < n:
        stop = min(n, start + want)
        buf = buffers[k % len(buffers)]
        _read(path, fh, buf, start, stop)
        end = buf.rfind(b"\n", 0, stop - start) + 1
        if end == 0:           # no line end in a whole piece (Arrow: "straddling")
            raise InputError(f"{path}: {LONG_LINE}")
        _short_lines(path, buf, 0, end)
        yield memoryview(buf)[:end]
        start, want, k = start + end, size, k + 1
        if stop == n and start < n:     # the last line, without its line end
            buf = buffers[k % len(buffers)]
            _read(path, fh, buf, start, n)
            _short_lines(path, buf, 0, n - start)
            yield memoryview(buf)[:n - start]
            return


def _read(path: str, fh, buf: bytearray, start: int, stop: int) -> None:
    """buf[:stop - start] = the file's bytes start:stop; InputError when the file now ends
    before stop (cut short since it was opened, or while it is read): a short read."""
    view = memoryview(buf)[:stop - start]
    fh.seek(start)
    got = 0
    while got < len(view):
        more = fh.readinto(view[got:])
        if not more:
            size = min(os.fstat(fh.fileno()).st_size, start + got)
            raise InputError(f"{path}: the file got shorter while it was read ({size} bytes now, "
                             f"{stop} before): read a copy, or wait until it is written")
        got += more


def _short_lines(path: str, buf, start: int, end: int) -> None:
    """InputError when a line of buf[start:end] (its last may be cut short) is longer than BLOCK:
    from each line's start, the last line end within BLOCK bytes, in hops of about BLOCK."""
    while end - start > BLOCK:
        nl = buf.rfind(b"\n", start, start + BLOCK)
        if nl < 0:
            raise InputError(f"{path}: {LONG_LINE}")
        start = nl + 1


def fast_path() -> bool:
    """Whether pieces go to the C parser first: built, and not switched off by
    ACCELCAL_CSV_FAST=0 (to compare with Arrow alone)."""
    return _csvfast is not None and os.environ.get("ACCELCAL_CSV_FAST", "1") != "0"


def plain(buf, columns: int, skip: int):
    """The piece's columns parsed by the C fast path (_csvfast.c: plain numbers only, correctly
    rounded as Arrow's), or None when the piece is anything else (Arrow's then)."""
    # Room for the rows guessed from the first 4 kB's lines (counting them all first read the
    # piece twice: ~15 % of the parse), counted exactly when short.  One block for all columns:
    # 4.5 MB for a 4 MB piece, which numpy asks the kernel to back with huge pages (>= 4 MB),
    # a fifth of the page-fault time of five separate arrays.
    lines = bytes(buf[:4096]).count(b"\n")
    room = len(buf) * (lines + 1) // 3700 + 64 if lines > 8 else _csvfast.lines(buf) + 1
    for _ in range(2):
        block = np.empty((columns, room))
        rows = _csvfast.parse(buf, skip, list(block))
        if rows != -1:
            return None if rows is None else list(block[:, :rows])
        room = _csvfast.lines(buf) + 1


def parse(buf: bytes, names: list[str], skip: int, pa, pacsv, limits=None, fast=False):
    """One piece's columns as float64 arrays and whether they passed `limits` ((lo, hi) per
    column: every value within, so finite; "rising": finite and never going back), or the error
    it holds: ("bad", row, column, None for a missing value or the value that is not finite),
    the row counted from the piece's first; or ("arrow", message).  Columns that fail the limits
    are looked at again value by value (finite here; the reader's own checks name the row).
    fast: a plain piece is parsed by the C fast path (its values all finite and present)."""
    cols = plain(buf, len(names), skip) if fast else None
    if cols is not None:
        return cols, limits is not None and all(_within(v, lim) for v, lim in zip(cols, limits))
    # Without quoting first (a tenth faster): a piece with a quote or an odd row fails to
    # convert or to split and is parsed again as CSV, which then gives the answer.  One block
    # per piece: its columns come whole (no copy to numpy), ~10 % less CPU than 1 MB blocks.
    table = None
    for quoting in (False, True):
        try:
            table = pacsv.read_csv(
                pa.py_buffer(buf),
                read_options=pacsv.ReadOptions(block_size=len(buf) + 1, use_threads=False,
                                               column_names=names, skip_rows=skip),
                parse_options=pacsv.ParseOptions(**({} if quoting else {"quote_char": False})),
                convert_options=pacsv.ConvertOptions(column_types={h: pa.float64() for h in names},
                                                     null_values=[""]))
            break
        except pa.ArrowInvalid as e:
            if quoting:
                return ("arrow", str(e))
    cols = []
    for c in table.columns:
        if c.null_count:
            break
        cols.append(c.chunk(0).to_numpy() if c.num_chunks == 1 else c.to_numpy())
    else:
        if limits is not None and all(_within(v, lim) for v, lim in zip(cols, limits)):
            return cols, True
    cols, bad = [], []
    for i, c in enumerate(table.columns):
        if c.null_count:
            nulls = np.concatenate([k.is_null().to_numpy(zero_copy_only=False) for k in c.chunks])
            bad.append((int(np.argmax(nulls)), i, None))
            continue
        v = c.to_numpy()
        finite = np.isfinite(v)
        if not finite.all():
            row = int(np.argmax(~finite))
            bad.append((row, i, float(v[row])))
        cols.append(v)
    if bad:     # the first bad row, its first bad column: what a row by row reader meets first
        return ("bad",) + min(bad)
    return cols, False


def _within(v: np.ndarray, limit) -> bool:
    # two reductions, no temporaries: a nan makes min/max nan and the comparison false
    if not len(v):
        return True
    if limit == "rising":
        return bool(-np.inf < v[0] and v[-1] < np.inf and (v[1:] >= v[:-1]).all())
    lo, hi = limit
    return bool(lo <= v.min() and v.max() <= hi)


def parsed(path: str, names: list[str], limits=None):
    """The data rows of a CSV file (its first line the header) in order, as (list of columns
    (float64), whether they passed limits: see parse), parsed WORKERS pieces at a time;
    InputError for the first bad row, by its line number."""
    pa, pacsv = arrow()     # once, here: it tells pyarrow that pandas is not there
    fast = fast_path()
    with open(path, "rb", buffering=0) as fh, ThreadPoolExecutor(WORKERS) as pool:
        n = os.fstat(fh.fileno()).st_size
        # read, not mapped (module doc); one buffer per piece in flight (WORKERS parsed, one
        # read), made once: their pages are touched once, not each piece's
        buffers = [bytearray(max(BLOCK, PIECE)) for _ in range(WORKERS + 1)] if n else []
        pending = []       # the pieces' parses, in the file's order
        first = 0
        pieces = cut(path, fh, n, BLOCK, PIECE, buffers)
        try:
            for k, buf in enumerate(pieces):
                pending.append(pool.submit(parse, buf, names, 1 if k == 0 else 0,
                                           pa, pacsv, limits, fast))
                if len(pending) <= WORKERS:
                    continue
                # done with its buffer before cut reads into it again (WORKERS + 1 pieces on)
                first = yield from _handed(path, names, pending.pop(0).result(), first)
            while pending:
                first = yield from _handed(path, names, pending.pop(0).result(), first)
        finally:
            for f in pending:
                f.cancel()


def _handed(path, names, got, first):
    if isinstance(got[0], str):
        if got[0] == "arrow":   # a row longer than Arrow's block: no recording's line is
            said = LONG_LINE if "straddl" in got[1] else \
                " ".join(re.sub(r"Row #\d+: ", "", got[1]).split())[:300]   # the piece's row
            raise InputError(f"{path}: {said}")
        _, row, col, value = got
        where = f"{path}:{first + row + 2}"
        if value is None:
            raise InputError(f"{where}: missing value in column {names[col]}")
        raise InputError(f"{where}: {value} in column {names[col]} (values must be finite)")
    cols, _ = got
    if len(cols[0]):
        yield got
    return first + len(cols[0])
