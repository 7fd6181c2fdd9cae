"""Which reader opens a file: the one rule every command uses (calibrate, apply, diagnose, compare,
a batch), by suffix and then by the CSV header's content.  `--help` prints RULE, built from the
tables here; anything the rule does not place is one line, exit 2 - never a guess.

What is read before anything is parsed is bounded: the header line (HEADER_MAX_BYTES), a column
name (NAME_MAX), the number of columns (COLUMNS_MAX); the file must be a regular file (a link to
a device or a FIFO is refused before it is opened for reading)."""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

from accelcal.errors import InputError
from accelcal.files.outputs import check_regular
from accelcal.model.effects import COLUMN_NAME, RESERVED

ACTIGRAPHY = {".cwa": "Axivity CWA", ".bin": "GENEActiv BIN", ".gt3x": "ActiGraph GT3X",
              ".agdc": "ActiGraph CentrePoint AGDC"}
# Spellings of the time and temperature columns a recording's header may use (any case).
TIME_NAMES = ("t", "time", "timestamp", "t_s", "time_s", "seconds")
TEMP_NAMES = ("temp", "temperature", "temp_c")
HEADER_MAX_BYTES = 64 * 1024
NAME_MAX = 64
COLUMNS_MAX = 256

RULE = f"""\
How a file is read (one rule for every command, host/accelcal/files/readers.py):
  {', '.join(ACTIGRAPHY)}: a recording ({', '.join(ACTIGRAPHY.values())}).
  CSV whose header begins with a time column, then x,y,z: a recording (t in s, x/y/z in g).
    The time column: {', '.join(TIME_NAMES)} (any case).  Then optionally temp (or
    {', '.join(TEMP_NAMES[1:])}; degC) and further columns named in lower-case letters,
    digits and _ (not t,x,y,z,temp,device).
  CSV whose header holds x,y,z and does not begin with a time column: a points file (rest
    means; optional temp, t, device and further columns).  Its t, if any, steps by >= 1 s.
  Anything else is refused (exit 2).  A header line is at most {HEADER_MAX_BYTES // 1024} KiB,
  a column name at most {NAME_MAX} characters, {COLUMNS_MAX} columns at most."""


@dataclass
class Layout:
    """What a file is: kind "recording" or "points"; for a CSV its header as written (raw) and
    with the rule's names (header: t, temp for their spellings), and a recording's further
    columns."""
    kind: str
    fmt: str
    raw: list[str]
    header: list[str]
    further: list[str]


def read_header(path) -> list[str]:
    """The CSV header's cells, stripped, read within HEADER_MAX_BYTES ([] for an empty file)."""
    check_regular(path)
    try:
        with open(path, "rb") as fh:
            line = fh.readline(HEADER_MAX_BYTES + 1)
    except OSError as e:
        raise InputError(f"{path}: cannot open ({e.strerror})") from None
    if len(line) > HEADER_MAX_BYTES:
        raise InputError(f"{path}: no header line within its first {HEADER_MAX_BYTES // 1024} KiB "
                         "(not a CSV file of ours)")
    if b"\0" in line:
        raise InputError(f"{path}: not a CSV text file (NUL bytes; nor {'/'.join(ACTIGRAPHY)})")
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a CSV text file (not UTF-8; nor {'/'.join(ACTIGRAPHY)})"
                         ) from None
    try:
        return [h.strip() for h in next(csv.reader([text]), [])]
    except csv.Error as e:
        raise InputError(f"{path}: header is not CSV ({e})") from None


def _canonical(cell: str) -> str:
    low = cell.lower()
    if low in TIME_NAMES:
        return "t"
    if low in TEMP_NAMES:
        return "temp"
    return low if low in ("x", "y", "z") else cell


def classify(header: list[str], path="") -> Layout:
    """The rule (RULE) on a CSV header; InputError naming what does not fit."""
    found = ",".join(header)[:120]
    if len(header) > COLUMNS_MAX:
        raise InputError(f"{path}: {len(header)} columns (at most {COLUMNS_MAX})")
    long = [h for h in header if len(h) > NAME_MAX]
    if long:
        raise InputError(f"{path}: a column name of {len(long[0])} characters (at most "
                         f"{NAME_MAX})")
    canon = [_canonical(h) for h in header]
    if canon[:1] == ["t"]:
        if canon[1:4] != ["x", "y", "z"]:
            raise InputError(f"{path}: a header that begins with a time column is a recording's: "
                             f"then x,y,z (found {found})")
        n = 5 if canon[4:5] == ["temp"] else 4
        further = header[n:]
        for h in further:
            if h in RESERVED or _canonical(h) in ("t", "temp") or not COLUMN_NAME.fullmatch(h):
                raise InputError(f"{path}: recording column {h!r:.40}: further columns are named in "
                                 "lower-case letters, digits and _ (at most 24), not t,x,y,z,temp,"
                                 "device (see --help)")
        if len(set(further)) != len(further):
            raise InputError(f"{path}: repeated column in header {found}")
        return Layout("recording", "CSV", header, canon[:n] + further, further)
    if not {"x", "y", "z"} <= set(canon):
        raise InputError(f"{path}: header needs columns x,y,z (a points file), or a time column "
                         f"then x,y,z (a recording); found {found or 'no header'}")
    if len(set(canon)) != len(canon):
        raise InputError(f"{path}: repeated column in header {found}")
    return Layout("points", "CSV", header, canon, [])


def recording_columns(header: list[str]) -> list[str] | None:
    """The further columns of a recording's CSV header, in order; None when the header is not
    a recording's."""
    try:
        lay = classify(header)
    except InputError:
        return None
    return lay.further if lay.kind == "recording" else None


def layout(path) -> Layout:
    """What the file at path is, by RULE; InputError (one line) when it is none of them."""
    path = str(path)
    suffix = Path(path).suffix.lower()
    if suffix in ACTIGRAPHY:
        check_regular(path)
        return Layout("recording", ACTIGRAPHY[suffix], [], [], [])
    header = read_header(path)
    if not header or header == [""]:
        raise InputError(f"{path}: empty file")
    return classify(header, path)


def is_recording(path) -> bool:
    """A recording (streamed) rather than a points file, by RULE; samples in memory
    (files/arrays.py ArrayRecording) are one."""
    if in_memory(path):
        return True
    return layout(path).kind == "recording"


def in_memory(source) -> bool:
    """Samples given as an array or frame (files/arrays.py), not a file."""
    return getattr(source, "in_memory", False)


def path_of(source) -> str | None:
    """The file a source reads (for the output checks: never write over it); None for samples
    in memory."""
    return None if source is None or in_memory(source) else str(source)
