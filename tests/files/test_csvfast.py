"""The CSV reader's C fast path (host/accelcal/files/_csvfast.c, used by files/csvpieces.py
`parse`): a plain piece parses to Arrow's values bit for bit (and to Python's correctly rounded
float() of each field), anything else is left to Arrow, whose answer or error is then the same as
with the fast path switched off (ACCELCAL_CSV_FAST=0); a whole `calibrate --json` record is the
same either way."""
import json

import numpy as np
import pytest

from accelcal.files import csvpieces
from conftest import run_cli

needs_fast = pytest.mark.skipif(csvpieces._csvfast is None,
                                reason="accelcal.files._csvfast not built (no C compiler at install)")
NAMES = ["t", "x", "y", "z", "temp"]
LIMITS = ["rising"] + [(-256.0, 256.0)] * 3 + [(-40.0, 85.0)]


def both(text: bytes, skip: int, names=NAMES, limits=None):
    """parse()'s answer for the piece with the fast path and with Arrow alone."""
    pa, pacsv = csvpieces.arrow()
    view = memoryview(text)     # what parse gets: a view into the mapped file
    return [csvpieces.parse(view, names, skip, pa, pacsv, limits, fast) for fast in (True, False)]


def same(a, b) -> bool:
    """The same answer: columns equal bit for bit (-0.0 is not 0.0), or the same error."""
    if isinstance(a[0], str) or isinstance(b[0], str):
        return repr(a) == repr(b)     # a nan in the error: not equal to itself
    return a[1] == b[1] and len(a[0]) == len(b[0]) and all(
        x.dtype == y.dtype == np.float64 and np.array_equal(x.view(np.int64), y.view(np.int64))
        for x, y in zip(a[0], b[0]))


def field(rng) -> str:
    """-?digits(.digits)? with random digit counts, 1 to 17 in all (some beyond the exact path:
    2^53 or more, then Arrow's), leading and trailing zeros, negative zeros."""
    whole = rng.integers(1, 12)
    frac = rng.integers(0, 18 - whole)
    digits = "".join(rng.choice(list("0123456789"), whole + frac)) if rng.random() < 0.9 \
        else "0" * (whole + frac)
    text = digits[:whole] + ("." + digits[whole:] if frac else "")
    return ("-" if rng.random() < 0.4 else "") + text


def exact(f: str) -> bool:
    return int(f.replace("-", "").replace(".", "")) < 2 ** 53


@needs_fast
@pytest.mark.parametrize("seed", range(6))
def test_plain_pieces_parse_to_arrows_values_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    rows = [[field(rng) for _ in NAMES] for _ in range(4000)]
    taken = [r for r in rows if all(map(exact, r))]
    assert 1000 < len(taken) < len(rows)
    end = "\r\n" if seed % 2 else "\n"
    for skip, last_end in ((0, ""), (1, end), (1, "")):
        head = ("t,x,y,z,temp" + end) if skip else ""
        piece = (head + end.join(",".join(r) for r in taken) + last_end).encode()
        assert csvpieces.plain(memoryview(piece), 5, skip) is not None
        fast, arrow = both(piece, skip)
        assert same(fast, arrow) and len(fast[0][0]) == len(taken)
        # Python's float() is correctly rounded too: an independent reading of each field
        for c, col in enumerate(fast[0]):
            want = np.array([float(r[c]) for r in taken])
            assert np.array_equal(col.view(np.int64), want.view(np.int64))
        # a field beyond the exact path anywhere: the piece is Arrow's, the same answer
        piece = (head + end.join(",".join(r) for r in rows) + last_end).encode()
        assert csvpieces.plain(memoryview(piece), 5, skip) is None
        assert same(*both(piece, skip))


@needs_fast
def test_negative_zero_and_the_exact_paths_edges():
    piece = b"-0.000,-0,0.0,9007199254740991,0.000000000000000001\n" \
            b"1,-9007199254740991,900719925474099.1,0.9007199254740991,123\n"
    fast, arrow = both(piece, 0)
    assert same(fast, arrow) and [np.signbit(fast[0][c][0]) for c in range(3)] == [True, True, False]
    assert csvpieces.plain(memoryview(piece), 5, 0) is not None
    for beyond in (b"9007199254740992", b"0.9007199254740992", b"1.00000000000000000001",
                   b"12345678901234567890"):
        assert csvpieces.plain(memoryview(b"1,2,3,4," + beyond + b"\n"), 5, 0) is None
        fast, arrow = both(b"1,2,3,4," + beyond + b"\n", 0)
        assert same(fast, arrow)


PLAIN = b"t,x,y,z,temp\n0.0100,-0.030,-0.028,0.990,30.00\n0.0200,-0.031,-0.027,0.991,30.00\n"
# every form the fast path leaves to Arrow, put into the second data row
REJECTED = ['"0.0200",-0.031,-0.027,0.991,30.00', "0.0200, -0.031,-0.027,0.991,30.00",
            "0.0200,-0.031 ,-0.027,0.991,30.00", "0.0200,-3.1e-2,-0.027,0.991,30.00",
            "0.0200,+0.031,-0.027,0.991,30.00", "0.0200,.5,-0.027,0.991,30.00",
            "0.0200,1.,-0.027,0.991,30.00", "0.0200,,-0.027,0.991,30.00",
            "0.0200,-0.031,-0.027,0.991", "0.0200,-0.031,-0.027,0.991,30.00,1",
            "0.0200,nan,-0.027,0.991,30.00", "0.0200,inf,-0.027,0.991,30.00",
            "0.0200,-inf,-0.027,0.991,30.00", "0.0200,NaN,-0.027,0.991,30.00",
            "0.0200,-,-0.027,0.991,30.00", "0.0200,--1,-0.027,0.991,30.00",
            "0.0200,0x1,-0.027,0.991,30.00", "0.0200,1_0,-0.027,0.991,30.00",
            "0.0200,-0.031,-0.027,0.991,30.00\r0.0300,-0.031,-0.027,0.991,30.00",
            "0.0200,-0.031,-0.027,0.991,30.00\n\n", "\n0.0200,-0.031,-0.027,0.991,30.00",
            "0.0200;-0.031;-0.027;0.991;30.00", "0.0200,-0.031,-0.027,0.991,30.00\t",
            "0.0200,abc,-0.027,0.991,30.00", "0.0200,-0.031,-0.027,0.991,30.00\r\r",
            " 0.0200,-0.031,-0.027,0.991,30.00", "0.0200,-0.031,-0.027,0.991,30.00 "]


@needs_fast
@pytest.mark.parametrize("row", REJECTED)
def test_anything_else_is_arrows(row):
    lines = PLAIN.split(b"\n")
    for last in (b"\n", b""):
        piece = b"\n".join(lines[:2] + [row.encode()]) + last
        assert csvpieces.plain(memoryview(piece), 5, 1) is None
        for limits in (None, LIMITS):
            fast, arrow = both(piece, 1, limits=limits)
            assert same(fast, arrow), (fast, arrow)


@needs_fast
def test_a_quoted_header_and_out_of_limit_values():
    piece = b'"t","x,y",z,w,temp\n1,2,3,4,5\n'    # a quoted header: Arrow skips it as a row
    assert csvpieces.plain(memoryview(piece), 5, 1) is None
    assert same(*both(piece, 1))
    piece = PLAIN + b"0.0300,-0.031,-0.027,0.991,30.00\r"      # a lone CR ends the piece
    assert csvpieces.plain(memoryview(piece), 5, 1) is None
    assert same(*both(piece, 1))
    # plain, but outside the limits: columns handed on unchecked, as Arrow's
    piece = PLAIN + b"0.0100,300.5,-0.027,0.991,30.00\n"
    fast, arrow = both(piece, 1, limits=LIMITS)
    assert csvpieces.plain(memoryview(piece), 5, 1) is not None
    assert same(fast, arrow) and fast[1] is False
    fast, arrow = both(PLAIN, 1, limits=LIMITS)
    assert same(fast, arrow) and fast[1] is True


def test_the_switch(monkeypatch):
    monkeypatch.setenv("ACCELCAL_CSV_FAST", "0")
    assert not csvpieces.fast_path()
    monkeypatch.delenv("ACCELCAL_CSV_FAST")
    assert csvpieces.fast_path() == (csvpieces._csvfast is not None)


@needs_fast
def test_calibrate_record_is_the_same_with_and_without_the_fast_path(tmp_path, monkeypatch):
    wrist = tmp_path / "wrist.csv"
    r = run_cli("simulate", "wrist", "--days", 1.5, "--rate", 10, "--seed", 7, "-o", wrist)
    assert r.returncode == 0, r.stderr
    records = []
    for switch in ("1", "0"):
        monkeypatch.setenv("ACCELCAL_CSV_FAST", switch)
        r = run_cli("calibrate", wrist, "--json")
        assert r.returncode == 0, r.stderr
        records.append(json.loads(r.stdout))
    assert records[0] == records[1] and records[0]["params_int"]


@needs_fast
def test_room_for_the_rows_guessed_short():
    """Room for a piece's rows is guessed from its first 4 kB (csvpieces.plain); long lines
    there and short ones after: the guess is short, the rows are counted and all parsed."""
    long_rows = [f"{i}.{i:012d},0.000000000001,-0.5,0.25,30.125" for i in range(60)]
    short_rows = [f"{i},1,2,3,4" for i in range(60, 5000)]
    piece = "\n".join(["t,x,y,z,temp"] + long_rows + short_rows).encode()
    lines = piece[:4096].count(b"\n")
    assert len(piece) * (lines + 1) // 3700 + 64 < 5000      # the guess, short
    fast, arrow = both(piece, 1)
    assert same(fast, arrow) and len(fast[0][0]) == 5000
    assert csvpieces.plain(memoryview(piece), 5, 1) is not None


@needs_fast
def test_the_modules_answers():
    """_csvfast.parse: rows, None for text that is not plain, -1 for columns with too little
    room (then nothing is said about the text); lines counts '\\n'."""
    fast = csvpieces._csvfast
    text = b"1,2\n3,-4.5\r\n6,7"
    assert fast.lines(text) == 2 and fast.lines(b"") == 0
    cols = [np.zeros(3), np.zeros(3)]
    assert fast.parse(text, False, cols) == 3 and cols[1].tolist() == [2, -4.5, 7]
    assert fast.parse(text, False, [np.zeros(2), np.zeros(2)]) == -1
    assert fast.parse(b"1,2\n3,x\n", False, [np.zeros(3), np.zeros(3)]) is None
    assert fast.parse(b"1,2\n3,x\n", False, [np.zeros(1), np.zeros(1)]) == -1
    with pytest.raises(TypeError):
        fast.parse(text, False, [np.zeros(3, np.float32), np.zeros(3)])
    with pytest.raises(ValueError):     # not contiguous
        fast.parse(text, False, [np.zeros(3), np.zeros(3)[::2]])


def test_fast_path_is_built_where_a_compiler_is():
    """The build is optional (setup.py), so a failed one would only show as the tests above
    skipped and a reader three times slower: where the interpreter's C compiler is on PATH
    (CI's machine has gcc), the module must be there."""
    import shutil
    import sysconfig
    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    if shutil.which(cc) is None:
        pytest.skip(f"no C compiler ({cc}) here: the reader uses Arrow alone")
    assert csvpieces._csvfast is not None, "accelcal.files._csvfast was not built at install"
