"""What a device file's header claims, checked before any third-party reader sees the file.

actfast (Rust) and pygt3x trust some header fields: a GENEActiv .bin's "Number of Pages" sizes
actfast's first allocation (a 12.7 kB file claiming 40 000 000 pages made it ask for 2.4 TB and
abort the process), a page's "Measurement Frequency" spaces its samples (0 gives times 2^63 ns
apart), a calibration gain of 0 gives infinite accelerations; ActiGraph's info.txt rate, scale and
dates drive pygt3x's arithmetic (a rate of 0: numpy's division warnings); a .cwa's header packet
length and the rate byte of its first block place and space every sample we hand on.  Each is
read here, cheaply, and checked against the file's size and physical bounds: a file that fails
is one line (InputError) naming the field, its value and the bound.  Bounds, from the devices'
datasheets with a margin: sample rates 1-1000 Hz for GENEActiv and ActiGraph (they sample at
10-100 Hz and 30-100 Hz), 0.195-3200 Hz for Axivity (its accelerometer's rate codes 1-15); GENEActiv gains 1..2^20
(about 25 000 per g on real devices) and offsets within +-2^20; ActiGraph dates as .NET ticks.
docs/real-recordings.md "Damaged headers"; tests/files/test_devheaders.py holds a corpus."""
from __future__ import annotations

import math
import os
import zipfile

from accelcal.errors import InputError
from accelcal.files.binpages import PAGE_HEX, BinPages

RATE_HZ = (1.0, 1000.0)          # GENEActiv, ActiGraph: a sample rate outside is not a device's
BIN_HEADER_MAX = 64 * 1024       # a GENEActiv header is ~2 kB (59 lines)
BIN_LINE_MAX = 1 << 20           # a page's hex line is 3600 characters on real devices
GAIN_MAX = 1 << 20
CWA_HEADER_LEN = 1020            # the 'MD' packet's length field (cwa.h: 1024 bytes in all)
CWA_BLOCK = 512
CWA_MIN_CODE = 1                 # rate code 1 = 0.195 Hz, 15 = 3200 Hz (3200 / 2^(15 - code)): the
                                 # ADXL345's codes; AX3 tools offer 6.25 Hz up, but slow clocks
                                 # (1.5625 Hz, code 4) are real recordings; code 0 is refused
GT3X_INFO_MAX = 64 * 1024
GT3X_MEMBER_MAX = 4 << 30        # a member of the zip, uncompressed (a week at 100 Hz is ~0.3 GB)
DEFLATE_RATIO = 1032              # deflate expands a byte to at most 1032 (258 per 2 bits)
TICKS_MAX = 3155378975999999999  # .NET DateTime.MaxValue.Ticks
SCALE_MAX = 1e5                  # ActiGraph "Acceleration Scale": counts per g (256, 341, 1024...)


def _number(path: str, what: str, text: str, integer: bool = False) -> float:
    s = text.strip()
    try:
        v = int(s) if integer else float(s.replace(",", "."))
    except ValueError:
        raise InputError(f"{path}: header field {what} is {s[:40]!r}, not "
                         f"{'an integer' if integer else 'a number'}") from None
    if not math.isfinite(v):
        raise InputError(f"{path}: header field {what} is {s[:40]!r}, not a finite number")
    return v


def _within(path: str, what: str, v: float, lo: float, hi: float, unit: str = "") -> None:
    if not lo <= v <= hi:
        f = (lambda x: str(x)) if isinstance(v, int) else (lambda x: f"{x:g}")
        raise InputError(f"{path}: header field {what} is {f(v)}{unit}, outside {f(lo)}..{f(hi)}"
                         f"{unit} (a damaged header; the file is not read)")


def check_bin(path: str) -> BinPages:
    """A GENEActiv .bin: the 59-line text header, then pages of "Recorded Data", 8 field lines
    and a hex line.  Checked: the header's rate, gains and offsets, "Number of Pages" (at least
    the pages that begin in the file, and pages x a page's hex line within twice the file's
    size: actfast reserves that), and every page's "Measurement Frequency" (read line by line,
    BIN_LINE_MAX bytes at a time).  Returns the pages counted: a header declaring more than the
    file holds is a truncated file, read to its last whole page (files/binpages.py)."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        head = fh.read(BIN_HEADER_MAX)
        cut = head.find(b"Recorded Data")
        if not head.startswith(b"Device Identity") or cut < 0:
            raise InputError(f"{path}: not a GENEActiv .bin file (no 'Device Identity' header "
                             f"ending in 'Recorded Data' within {BIN_HEADER_MAX // 1024} KiB)")
        fields = {}
        for raw in head[:cut].decode("latin-1").splitlines():
            key, sep, value = raw.partition(":")
            if sep:
                fields.setdefault(key.strip(), value)
        pages = fields.get("Number of Pages")
        if pages is None:
            raise InputError(f"{path}: GENEActiv header has no 'Number of Pages'")
        declared = _number(path, "'Number of Pages'", pages, integer=True)
        rate = fields.get("Measurement Frequency")
        if rate is not None:
            _within(path, "'Measurement Frequency'", _number(path, "'Measurement Frequency'",
                    rate.replace("Hz", "")), *RATE_HZ, " Hz")
        for axis in "xyz":
            for name, lo, hi in ((f"{axis} gain", 1, GAIN_MAX), (f"{axis} offset", -GAIN_MAX, GAIN_MAX)):
                if name in fields:
                    _within(path, f"'{name}'", _number(path, f"'{name}'", fields[name], True), lo, hi)
        # the pages: count them (whole ones apart), check each one's rate
        fh.seek(cut)
        found, whole, end, n_line, hex_len, first_hex, at_start = 0, 0, cut, 0, 0, 0, True
        while True:
            line = fh.readline(BIN_LINE_MAX)
            ends = line.endswith(b"\n")
            if at_start and line.startswith(b"Recorded Data"):
                found, n_line, hex_len = found + 1, 0, 0
            n_line += at_start
            if n_line == 10:                         # "Recorded Data", 8 fields, the hex line
                hex_len += len(line.strip())
                first_hex = hex_len if found == 1 else first_hex
                if (ends or not line) and hex_len >= PAGE_HEX:   # the page is whole
                    whole, end, n_line = whole + 1, fh.tell(), 11
            elif at_start and ends and line.startswith(b"Measurement Frequency:"):
                what = f"'Measurement Frequency' of page {found}"
                _within(path, what, _number(path, what, line[22:].decode("latin-1")),
                        *RATE_HZ, " Hz")
            if not line:
                break
            at_start = ends
    pages = BinPages(declared, found, whole, cut, end)
    if not 1 <= declared or declared < found or not whole:
        raise InputError(f"{path}: header field 'Number of Pages' is {declared}; the file holds "
                         f"{found} page{'s' * (found != 1)}, {whole} whole (a damaged header; "
                         "the file is not read)")
    if declared > found:   # a truncated file: its reader is given its whole pages (binpages.py)
        most = _period_pages(path, fields)
        if not most:
            raise InputError(f"{path}: header field 'Number of Pages' is {declared}; the file holds "
                             f"{found}, and no 'Measurement Period' tells a truncated file from a "
                             "damaged header (the file is not read)")
        _within(path, "'Number of Pages'", declared, 1, most, " pages")
        return pages
    if declared * first_hex > 2 * size:
        raise InputError(f"{path}: header field 'Number of Pages' ({declared}) x a page's "
                         f"{first_hex} hex characters is more than the file's {size} bytes hold")
    return pages


def _period_pages(path: str, fields: dict) -> int:
    """The pages a GENEActiv's configured recording fills ("Measurement Period" hours at the
    header's rate, 300 samples a page, one more for a partial page): what a truncated file's
    header may declare (GGIR's test file: 216 h at 85.7 Hz, 222 135 pages; it declares 222 048).
    A header without both fields cannot tell a truncated file from a damaged count: 0."""
    if "Measurement Period" not in fields or "Measurement Frequency" not in fields:
        return 0
    hours = _number(path, "'Measurement Period'", fields["Measurement Period"].replace("Hours", ""))
    rate = _number(path, "'Measurement Frequency'", fields["Measurement Frequency"].replace("Hz", ""))
    _within(path, "'Measurement Period'", hours, 0, 24 * 366, " h")
    return int(hours * 3600 * rate) // 300 + 1


def check_cwa(head: bytes, path: str, size: int) -> None:
    """An Axivity .cwa: the 'MD' header packet (its length field 1020: 1024 bytes in all), its
    sample-rate byte, and the first data block ('AX', its rate byte): a rate code 1-15
    (0.195-3200 Hz); `head` is the file's first 1024 + 512 bytes."""
    if len(head) < 4 or head[:2] != b"MD":
        raise InputError(f"{path}: not an Axivity CWA file (no 'MD' header packet)")
    length = int.from_bytes(head[2:4], "little")
    if length != CWA_HEADER_LEN:
        raise InputError(f"{path}: header packet length {length} (an Axivity header packet is "
                         f"{CWA_HEADER_LEN}; a damaged header, the file is not read)")
    if size < 1024 + CWA_BLOCK:
        raise InputError(f"{path}: Axivity CWA file holds no data blocks ({size} bytes)")
    for where, at in (("header packet", 36), ("first data block", 1024 + 24)):
        if where == "first data block" and head[1024:1026] != b"AX":
            raise InputError(f"{path}: the first data block does not begin with 'AX'")
        code = head[at] & 0x0F
        if code < CWA_MIN_CODE:
            raise InputError(f"{path}: {where}'s sample-rate byte 0x{head[at]:02x} is "
                             f"{3200 / 2 ** (15 - code):g} Hz (an Axivity samples at "
                             f"0.195-3200 Hz; a damaged header, the file is not read)")


def check_zip(path: str) -> None:
    """An ActiGraph .gt3x or CentrePoint .agdc: a zip holding info.txt (and log.bin or, in old
    NHANES-format files, activity.bin).  Checked: every member's uncompressed size (at most
    GT3X_MEMBER_MAX, and what its compressed size can expand to), info.txt's Sample Rate (an integer, RATE_HZ), Acceleration Scale (0 <
    scale <= SCALE_MAX), and dates (ticks within 0..TICKS_MAX, the start not after the last
    sample)."""
    try:
        with zipfile.ZipFile(path) as z:
            members = z.infolist()
            big = [m for m in members if m.file_size > GT3X_MEMBER_MAX or
                   m.file_size > DEFLATE_RATIO * m.compress_size + (1 << 20)]
            if big:
                m = big[0]
                raise InputError(f"{path}: zip member {m.filename[:60]!r} claims {m.file_size} "
                                 f"bytes from {m.compress_size} compressed (at most "
                                 f"{GT3X_MEMBER_MAX >> 30} GiB, and {DEFLATE_RATIO} times its "
                                 "compressed size: deflate's limit; a damaged file)")
            try:
                info = z.getinfo("info.txt")
            except KeyError:
                raise InputError(f"{path}: not an ActiGraph file (no info.txt in the zip)") from None
            if info.file_size > GT3X_INFO_MAX:
                raise InputError(f"{path}: info.txt claims {info.file_size} bytes (at most "
                                 f"{GT3X_INFO_MAX // 1024} KiB)")
            with z.open(info) as fh:
                text = fh.read(GT3X_INFO_MAX + 1).decode("utf-8", "replace")
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError) as e:
        raise InputError(f"{path}: not a readable ActiGraph file (a damaged zip: "
                         f"{' '.join(str(e).split())[:120]})") from None
    fields = {}
    for line in text.splitlines():
        key, sep, value = line.partition(":")
        if sep:
            fields.setdefault(key.strip(), value)
    if "Sample Rate" in fields:
        _within(path, "'Sample Rate'", _number(path, "'Sample Rate'", fields["Sample Rate"], True),
                *RATE_HZ, " Hz")
    if "Acceleration Scale" in fields:
        scale = _number(path, "'Acceleration Scale'", fields["Acceleration Scale"])
        if not 0 < scale <= SCALE_MAX:
            raise InputError(f"{path}: header field 'Acceleration Scale' is {scale:g}, outside "
                             f"0 (excluded)..{SCALE_MAX:g} (a damaged header; the file is not read)")
    ticks = {}
    for name in ("Start Date", "Stop Date", "Last Sample Time", "Download Date"):
        if name in fields:
            ticks[name] = _number(path, f"'{name}'", fields[name], integer=True)
            _within(path, f"'{name}'", ticks[name], 0, TICKS_MAX)
    start, last = ticks.get("Start Date", 0), ticks.get("Last Sample Time", 0)
    if start and last and last < start:
        raise InputError(f"{path}: header's 'Last Sample Time' ({last}) is before its 'Start "
                         f"Date' ({start}) (a damaged header; the file is not read)")


def check_device_file(path: str) -> BinPages | None:
    """The header check of a device file by its suffix (.bin, .gt3x, .agdc; a .cwa's is made
    where it is opened, CwaRecording); a .bin's pages as counted."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".bin":
        return check_bin(path)
    elif ext in (".gt3x", ".agdc"):
        check_zip(path)

