"""Real device files (tests/data/real: Axivity AX3 and AX6 .cwa, GENEActiv .bin, from
scikit-digital-health's test data, MIT licence beside them) read onto our recording model, checked
against the values scikit-digital-health's own reader gives for the same files (*_data.npz) and
against the raw bytes of the CWA blocks."""
import json
import re
from pathlib import Path

import numpy as np
import pytest

from accelcal.errors import InputError
from accelcal.files.recordings import is_recording, open_recording, read_whole
from conftest import ROOT, run_cli

REAL = ROOT / "tests" / "data" / "real"
FILES = {"ax3_sample.cwa": ("ax3_data.npz", 200, 8.0), "ax6_sample.cwa": ("ax6_data.npz", 100, 16.0),
         "gnactv_sample.bin": ("gnactv_data.npz", 50, 8.0)}


@pytest.mark.parametrize("name", FILES)
def test_real_file_reads_to_the_reference(name):
    ref_name, rate, full_scale = FILES[name]
    ref = np.load(REAL / ref_name)
    t, xyz, temp, rec = read_whole(REAL / name)
    assert len(t) == len(ref["time"])
    # Acceleration in g: the same values (float32 storage: 1e-6; the resolution is 1/256 g)
    assert np.abs(xyz - ref["accel"]).max() < 1e-4
    # Time: both readers place samples between the blocks' timestamps, by conventions that
    # differ by up to ~1.5 sample periods (AX3: 7 ms median at 200 Hz); never by 20 ms.
    assert np.abs(t - ref["time"]).max() < 0.02
    assert np.abs(np.median(t - ref["time"])) < 0.01
    assert rec.range_g == full_scale
    assert temp is not None and rec.has_temp
    # Both hold the device's per-block temperature reading until the next one
    assert len(np.unique(temp)) == len(np.unique(ref["temperature"]))
    if name.endswith(".bin"):
        assert np.abs(temp - ref["temperature"]).max() < 1e-5
    else:
        # Axivity: we (actfast) convert as the format's documentation says (cwa.h:
        # value * 75 / 256 - 50 degC); scikit-digital-health uses another sensor formula.  The
        # readings are the same, the conversions affine maps of each other.
        a, b = np.polyfit(temp, ref["temperature"], 1)
        assert np.abs(a * temp + b - ref["temperature"]).max() < 1e-6
        assert abs(a - 1.0864) < 1e-3 and abs(b + 0.106) < 1e-2


@pytest.mark.parametrize("name", ["ax3_sample.cwa", "ax6_sample.cwa"])
def test_cwa_temperature_is_the_blocks_raw_reading(name):
    """Independent of any reader: the 10-bit temperature at byte 20 of each 512-byte 'AX' data
    block, converted per cwa.h, is what each sample of the block carries."""
    raw = np.fromfile(REAL / name, np.uint8)
    blocks = raw[: len(raw) // 512 * 512].reshape(-1, 512)
    data = blocks[(blocks[:, 0] == ord("A")) & (blocks[:, 1] == ord("X"))]
    reading = ((data[:, 20].astype(np.uint16) | (data[:, 21].astype(np.uint16) << 8)) & 0x3FF) * 75 / 256 - 50
    _, _, temp, _ = read_whole(REAL / name)
    steps = np.r_[0, np.flatnonzero(np.diff(temp)) + 1]
    # every held value is a block's reading, in order
    held = temp[steps]
    j = 0
    for v in held:
        while j < len(reading) and abs(reading[j] - v) > 1e-4:
            j += 1
        assert j < len(reading), f"{v} is no block's reading"


def test_real_files_calibrate_report_not_enough_data(tmp_path):
    """Minutes of data: every file goes through the pipeline and says why it cannot calibrate."""
    for name, (ref_name, rate, _) in FILES.items():
        r = run_cli("calibrate", REAL / name, "--json")
        assert r.returncode == 2, r.stderr
        rec = json.loads(r.stdout)
        assert rec["status"] == "not_enough_data" and "bins did not fill" in rec["reason"]
        # the rate as the file's clock measures it (the reference reader's times: the AX3's
        # 197.24 Hz), the device's segments at the nearest whole rate
        t = np.load(REAL / ref_name)["time"]
        assert abs(rec["rate_hz"] - (len(t) - 1) / (t[-1] - t[0])) < 0.002 * rate, rec["rate_hz"]
        assert rec["rate_hz_device"] == rate and rec["format"] != "CSV"
        assert rec["temp_range_c"][0] < rec["temp_range_c"][1]
        assert 0 < rec["hours"] < 0.1
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_recording_kinds_and_corrupt_files(tmp_path):
    assert is_recording(REAL / "ax3_sample.cwa")
    pts = tmp_path / "p.csv"
    pts.write_text("x,y,z\n1,0,0\n")
    assert not is_recording(pts)
    bad = tmp_path / "broken.cwa"
    bad.write_bytes(b"MD" + bytes(1022) + b"garbage" * 200)
    with pytest.raises(InputError, match="broken.cwa"):
        read_whole(bad)
    half = tmp_path / "half.cwa"
    half.write_bytes((REAL / "ax3_sample.cwa").read_bytes()[:1024 + 700])
    r = run_cli("calibrate", half)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.startswith("accelcal")


def test_csv_streams_in_blocks_with_row_numbers_in_errors(tmp_path):
    f = tmp_path / "r.csv"
    n = 400_000   # many Arrow blocks (1 MB of text is ~40 000 such rows)
    t = np.arange(n) / 100
    body = "\n".join(f"{v:.2f},0.01,0.02,0.99" for v in t)
    f.write_text("t,x,y,z\n" + body + "\n")
    rec = open_recording(f)
    chunks = list(rec.chunks())
    assert sum(len(c.t) for c in chunks) == n and [c.first for c in chunks][0] == 0
    assert all(np.array_equal(c.t, t[c.first:c.first + len(c.t)]) for c in chunks)
    lines = f.read_text().splitlines()
    lines[300_001] = "3000.00,0.01,,0.99"
    _refused(f, lines, r"r.csv:300002: missing value in column y")
    lines[300_001] = "3000.00,0.01,nan,0.99"
    _refused(f, lines, r"r.csv:300002: nan in column y")


def _refused(f, lines, match):
    """The recording written as these lines is refused in one line matching match."""
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=match):
        list(open_recording(f).chunks())


def test_csv_pieces_parsed_at_once_give_the_streaming_readers_rows(tmp_path, monkeypatch):
    """The CSV in pieces parsed two at a time (files/csvpieces.py) gives the rows Arrow's
    streaming reader gives, its first block as the first chunk (scan's rate comes from it),
    quoted values too; a bad row in a later piece is named by its line in the file, the first bad row of a piece
    first whatever its column; a short row is named without the piece's own row count."""
    import pyarrow.csv as pacsv

    from accelcal.files import csvpieces
    monkeypatch.setattr(csvpieces, "PIECE", 200_000)
    f = tmp_path / "r.csv"
    n = 120_000      # ~3 MB: a first 1 MB block, then ~12 pieces
    t = np.round(np.arange(n) / 100 + np.sin(np.arange(n)) * 1e-3, 4)
    lines = ["t,x,y,z,temp"] + [f"{v:.4f},0.01,{v % 1:.3f},0.99,30.5" for v in t]
    f.write_text("\n".join(lines) + "\n")
    stream = list(pacsv.open_csv(f, read_options=pacsv.ReadOptions(block_size=1 << 20)))
    chunks = list(open_recording(f).chunks())
    assert 10 < len(chunks) < len(stream) * 5 and len(chunks[0].t) == stream[0].num_rows
    assert [c.first for c in chunks] == list(np.cumsum([0] + [len(c.t) for c in chunks[:-1]]))
    for name, got in (("t", [c.t for c in chunks]), ("y", [c.xyz[:, 1] for c in chunks]),
                      ("temp", [c.temp for c in chunks])):
        assert np.array_equal(np.concatenate(got), np.concatenate([b[name].to_numpy() for b in stream]))
    quoted = list(lines)     # a piece with quoted values: parsed again with quoting
    quoted[50_001] = '"' + lines[50_001].replace(",", '","') + '"'
    f.write_text("\n".join(quoted) + "\n")
    assert np.array_equal(np.concatenate([c.t for c in open_recording(f).chunks()]), t)
    bad = list(lines)
    bad[100_001] = "1000.0000,0.01,0.5,inf,30.5"
    bad[100_002] = "1000.0100,nan,0.5,0.99,30.5"
    bad[100_003] = "1000.0200,0.01,,0.99,30.5"
    _refused(f, bad, r"r.csv:100002: inf in column z")
    bad[100_001] = "1000.0000,0.01,0.5"
    _refused(f, bad, r"r.csv: CSV parse error: Expected 5 columns, got 3: 1000")


@pytest.mark.parametrize("name", ["ax3_sample.cwa", "ax6_sample.cwa"])
def test_cwa_streams_in_pieces_to_exactly_the_whole_read(name, monkeypatch):
    """A .cwa goes to actfast a few blocks at a time (constant memory): the pieces give the
    same samples, times and temperatures as actfast on the whole file, and the same calibration
    record."""
    import actfast

    from accelcal.files.recordings import CwaRecording
    whole = actfast.read(str(REAL / name))["timeseries"]
    rec = CwaRecording(str(REAL / name))
    rec.BLOCKS = 37   # pieces that split the file unevenly
    chunks = list(rec.chunks())
    assert len(chunks) > 5
    t = np.concatenate([c.t for c in chunks])
    assert np.array_equal(t, whole["high_frequency"]["datetime"] / 1e9)
    assert np.array_equal(np.concatenate([c.xyz for c in chunks]), whole["high_frequency"]["acceleration"])
    assert [c.first for c in chunks] == list(np.cumsum([0] + [len(c.t) for c in chunks[:-1]]))
    tl = whole["low_frequency"]["datetime"] / 1e9
    held = whole["low_frequency"]["temperature"][np.clip(np.searchsorted(tl, t, "right") - 1, 0, None)]
    assert np.array_equal(np.concatenate([c.temp for c in chunks]), held)
    one = json.loads(run_cli("calibrate", REAL / name, "--model", "base", "--json").stdout)
    monkeypatch.setattr(CwaRecording, "BLOCKS", 37)
    from accelcal.bridge import runtime
    from accelcal.pipeline.calibrate import calibrate_recording
    cfg = runtime.Config.for_profile("wear")
    pieces = calibrate_recording(str(REAL / name), cfg, "device", "cpython")
    assert {k: v for k, v in pieces.items() if k != "file"} == {k: v for k, v in one.items() if k != "file"}


GT3X = REAL / "ggir" / "actigraph_testfile.gt3x"   # GGIR's test file (Apache-2.0, beside it)


def test_gt3x_reads_to_the_independent_reader():
    """An ActiGraph wGT3X-BT file reads to the samples pygt3x gives for it (its rows outside
    idle sleep, stored beside the file): the same times and values; the idle-sleep stretches
    (the device stopped sampling while still: 35 400 of pygt3x's 53 040 rows repeat a sample)
    are gaps in ours, never rest."""
    ref = np.load(GT3X.with_name("actigraph_testfile_pygt3x.npz"))
    t, xyz, temp, rec = read_whole(GT3X)
    assert len(t) == len(ref["time"]) == 17640 and int(ref["idle_rows"]) == 35400
    assert np.abs(t - ref["time"]).max() < 1e-6
    assert np.array_equal(xyz.astype(np.float32), ref["accel"])
    gaps = np.diff(t) > 1.0
    assert gaps.sum() >= 1 and (t[-1] - t[0]) > 0.45 * 3600   # a 0.49 h span, 0.16 h of samples
    assert temp is None and not rec.has_temp


def test_gt3x_idle_sleep_is_not_rest(tmp_path):
    """calibrate on the .gt3x: the idle-sleep stretches (hours of one repeated sample in other
    readers) give no rest segment; only the sampled minutes do."""
    r = run_cli("calibrate", GT3X, "--json", "--method", "lsq", "--points", "all")
    rec = json.loads(r.stdout.splitlines()[0]) if r.stdout.strip() else None
    assert rec is not None, r.stderr
    assert rec["format"].lower().startswith("actigraph") and rec["gaps"] >= 1
    # 0.16 h of samples: at most that many 5 s segments, whatever the idle hours
    assert rec["still_windows"] <= 0.17 * 3600 / 5


@pytest.mark.parametrize("name", ["ax3_sample.cwa", "gnactv_sample.bin",
                                  "ggir/actigraph_testfile.gt3x"])
def test_calibrate_diagnose_and_compare_find_the_same_rest_segments(name):
    """One file, one set of rest segments: calibrate's still windows (the device's rest test,
    imputed, clipped and non-wear segments left out) are the ones diagnose and compare read."""
    from accelcal.pipeline.restpoints import rest_points
    r = run_cli("calibrate", REAL / name, "--json")
    rec = json.loads(r.stdout.splitlines()[0])
    try:
        n = len(rest_points(str(REAL / name)))
    except InputError:
        n = 0
    assert n == rec["still_windows"], (name, n, rec["still_windows"])


def test_the_same_rest_segments_on_a_day_with_non_wear(tmp_path):
    """A simulated day with the device off the wrist: calibrate leaves the non-wear segments out
    of its still windows, and diagnose's rest points are exactly those (before, it counted the
    off-wrist ones too)."""
    from accelcal.pipeline.restpoints import rest_points
    f = tmp_path / "day.csv"
    assert run_cli("simulate", "wrist", "--days", "1", "--rate", "10", "-o", f).returncode == 0
    rec = json.loads(run_cli("calibrate", f, "--json").stdout.splitlines()[0])
    assert rec["excluded"]["nonwear"] > 0
    assert len(rest_points(str(f))) == rec["still_windows"]


PYGT3X = REAL / "pygt3x"   # pygt3x's test files (GPL-3.0, beside them) and ActiLife's exports


def actilife_csv(path: Path) -> np.ndarray:
    """An ActiLife raw CSV export (10 header lines, then X,Y,Z in g): the vendor's own reading."""
    return np.loadtxt(path, delimiter=",", skiprows=11)


def test_gt3x_declares_its_range():
    """A .gt3x declares its full scale in info.txt (Acceleration Max 8.0): apply takes it."""
    from accelcal.pipeline.apply import apply_range
    rec = open_recording(GT3X)
    assert rec.range_g == 8.0 and apply_range(rec.range_g, None) == 8


def test_agdc_reads_to_actilife():
    """An ActiGraph CentrePoint .agdc reads to what ActiLife exports for it (the vendor's CSV):
    the same samples in g; a second .agdc with the accelerometer chip's temperature reads it as
    ActiGraph's export gives it, held until the next reading, and declares +-8 g."""
    pytest.importorskip("pygt3x")
    assert is_recording(PYGT3X / "WRIST_rawLSB_032Hz_test.agdc")
    t, xyz, temp, rec = read_whole(PYGT3X / "WRIST_rawLSB_032Hz_test.agdc")
    ref = actilife_csv(PYGT3X / "WRIST_rawCalibrated_032Hz.csv")
    assert rec.format == "ActiGraph CentrePoint AGDC" and len(t) == len(ref) == 1920
    assert np.abs(xyz - ref).max() < 1e-6
    assert np.allclose(np.diff(t), 1 / 32)
    t, xyz, temp, rec = read_whole(PYGT3X / "CPW1C48210013_baseline.agdc")
    ref = np.loadtxt(PYGT3X / "CPW1C48210013_baseline_temperature_ADXL_calibrated.csv",
                     delimiter=",", skiprows=1)
    assert rec.has_temp and rec.range_g == 8.0 and len(ref) > 3000
    at = np.searchsorted(t, ref[:, 0])       # the first sample at each reading's time
    inside = at < len(t)
    assert inside.sum() > 3000 and np.abs(temp[at[inside]] - ref[inside, 1]).max() < 1e-4
    assert np.array_equal(np.unique(temp), np.unique(temp[at[inside]]))   # held, never blended


def test_old_nhanes_gt3x_falls_back_to_pygt3x():
    """actfast cannot read an old NHANES-format GT3X+ file (activity.bin, no log.bin); pygt3x
    can, and the samples are ActiLife's export of the same file."""
    pytest.importorskip("pygt3x")
    import actfast
    with pytest.raises(Exception):
        actfast.read(str(PYGT3X / "neo.gt3x"))
    t, xyz, temp, rec = read_whole(PYGT3X / "neo.gt3x")
    ref = actilife_csv(PYGT3X / "neo.csv")
    assert len(t) == len(ref) == 18004 and np.all(np.diff(t) > 0)
    assert np.abs(xyz - ref).max() < 1e-6 and temp is None


def test_actigraph_files_without_pygt3x_name_the_extra(monkeypatch):
    """Without pygt3x, an ActiGraph file only it reads is one line naming the optional extra."""
    import builtins
    real_import = builtins.__import__

    def no_pygt3x(name, *a, **k):
        if name.startswith("pygt3x"):
            raise ImportError(name)
        return real_import(name, *a, **k)
    monkeypatch.setattr(builtins, "__import__", no_pygt3x)
    for name in ("neo.gt3x", "CPW1C48210013_baseline.agdc"):
        with pytest.raises(InputError) as e:
            open_recording(PYGT3X / name)
        assert "accelcal[gt3x]" in str(e.value) and "\n" not in str(e.value)


def test_csv_value_checks_name_the_row_in_any_piece(tmp_path, monkeypatch):
    """The value checks (files/checks.py, a further column's bound) are made in the parsing
    threads when a piece passes them all; a piece that does not is looked at value by value:
    the same one-line refusal, the row's line in the file, in the first piece or a later one,
    time going back inside a piece or across two; a line longer than 1 MB is refused."""
    from accelcal.files import csvpieces
    monkeypatch.setattr(csvpieces, "PIECE", 100_000)
    f = tmp_path / "v.csv"
    n = 60_000
    lines = ["t,x,y,z,temp,supply_mv"] + [f"{i / 100:.2f},0.01,-0.5,0.99,30.5,3900" for i in range(n)]
    f.write_text("\n".join(lines))      # the last line without its line end: read too
    chunks = list(open_recording(f).chunks())
    assert sum(len(c.t) for c in chunks) == n and chunks[-1].t[-1] == (n - 1) / 100
    for row in (10, 45_000):        # the first piece (Arrow's first 1 MB block) and a later one
        line = row + 2
        for cells, match in (
                ("0.01,300,0.99,30.5,3900", rf"v.csv:{line}: 300 g is not an acceleration"),
                ("0.01,-256.5,0.99,30.5,3900", rf"v.csv:{line}: -256.5 g is not an acceleration"),
                ("0.01,0.5,0.99,200.5,3900", rf"v.csv:{line}: temperature 200.5 degC is outside"),
                ("0.01,0.5,0.99,30.5,2e9", rf"v.csv:{line}: 2e\+09 in column supply_mv"),
                ("0.01,0.5,-inf,30.5,3900", rf"v.csv:{line}: -inf in column z"),
                ("0.01,0.5,0.99,nan,3900", rf"v.csv:{line}: nan in column temp")):
            bad = list(lines)
            bad[row + 1] = f"{row / 100:.2f},{cells}"
            _refused(f, bad, match)
        bad = list(lines)
        bad[row + 1] = "0.00,0.01,-0.5,0.99,30.5,3900"
        _refused(f, bad, rf"v.csv:{line}: time goes back \({(row - 1) / 100:g} s, then 0 s\)")
    # time going back across two pieces: at the first row of each piece after the first
    f.write_text("\n".join(lines) + "\n")
    starts = np.cumsum([0] + [len(c.t) for c in open_recording(f).chunks()])[1:-1]
    row = int(starts[3])
    bad = list(lines)
    bad[row + 1] = "1.00,0.01,-0.5,0.99,30.5,3900"
    _refused(f, bad, rf"v.csv:{row + 2}: time goes back \({(row - 1) / 100:g} s, then 1 s\)")
    bad = list(lines)
    bad[30_000] = "300.00,0.01,-0.5,0.99,30.5," + "9" * (1 << 20)
    _refused(f, bad, r"v.csv: a line longer than 1 MB")


def test_csv_cut_short_while_read_is_refused_not_a_crash(tmp_path, monkeypatch):
    """A CSV file that got shorter since it was opened (pieces already read) is refused at the
    next piece's read, a short read (files/csvpieces.py `_read`), with the sizes."""
    from accelcal.files import csvpieces
    monkeypatch.setattr(csvpieces, "PIECE", 1 << 16)
    f = tmp_path / "growing.csv"
    n = 100_000
    rows = "\n".join(f"{i / 100:.2f},0.001,-0.002,1.003" for i in range(n))
    f.write_text("t,x,y,z\n" + rows + "\n")
    size = f.stat().st_size
    assert size > 2 * csvpieces.BLOCK
    chunks = open_recording(f).chunks()
    next(chunks)                     # the first piece (1 MB) and two of 64 kB are cut by now
    with open(f, "r+b") as fh:
        fh.truncate(csvpieces.BLOCK + 8 * (1 << 16))
    with pytest.raises(InputError, match=r"got shorter while it was read \(1572864 bytes now, "):
        for _ in chunks:
            pass


# Run in its own process: the file is cut short, to below the piece, by the parsing thread just
# before it parses its second piece (the first of 64 kB); the read-ahead then meets the new end.
CUT_WHILE_PARSED = """
import sys
from accelcal.cli import main
from accelcal.files import csvpieces
csvpieces.PIECE = 1 << 16
parse, calls = csvpieces.parse, []
def cut_then_parse(buf, *rest):
    calls.append(len(buf))
    if len(calls) == 2:
        with open(sys.argv[1], "r+b") as fh:
            fh.truncate(csvpieces.BLOCK // 2)
    return parse(buf, *rest)
csvpieces.parse = cut_then_parse
sys.exit(main(["calibrate", sys.argv[1]]))
"""


@pytest.mark.parametrize("fast", ["1", "0"])
def test_csv_cut_short_while_a_piece_is_parsed_exits_2_not_killed(tmp_path, fast):
    """A CSV cut short while one of its pieces is being parsed: read into a buffer (not mapped,
    where touching the piece's pages, gone with the file's end, killed the process by SIGBUS),
    the parse ends and the next read is short: exit 2 and one line, in a real process, through
    the C fast path and through Arrow (ACCELCAL_CSV_FAST=0)."""
    import os
    import subprocess
    import sys

    from accelcal.files import csvpieces
    f = tmp_path / "cut.csv"
    n = 100_000      # ~2.7 MB: a first 1 MB piece, then ~27 of 64 kB
    f.write_text("t,x,y,z\n" + "\n".join(f"{i / 100:.2f},0.001,-0.002,1.003" for i in range(n))
                 + "\n")
    assert f.stat().st_size > csvpieces.BLOCK + 8 * (1 << 16)
    r = subprocess.run([sys.executable, "-c", CUT_WHILE_PARSED, str(f)], capture_output=True,
                       text=True, env={**os.environ, "ACCELCAL_CSV_FAST": fast}, timeout=120)
    assert f.stat().st_size == csvpieces.BLOCK // 2          # it was cut while read
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])   # -7 would be SIGBUS
    assert r.stdout == "" and "Traceback" not in r.stderr
    assert re.fullmatch(rf"accelcal: error: {re.escape(str(f))}: the file got shorter while it "
                        rf"was read \({csvpieces.BLOCK // 2} bytes now, \d+ before\): read a copy, "
                        r"or wait until it is written\n", r.stderr), r.stderr
