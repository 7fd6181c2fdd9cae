"""A corpus of bad inputs over every command that reads a file or an option, run through the
CLI's main(argv) in-process (hundreds of cases in seconds): each must end with exit status 2
and exactly one line on stderr, never a traceback, and never a silent wrong result.  A few run
as real subprocesses to prove the exit code and the absence of a traceback end to end."""
import json
import struct
import subprocess
import sys

import numpy as np
import pytest

from conftest import run_main

BAD_NUMBERS = ["nan", "inf", "-inf", "1e300", "-1", "abc", "", "0x10", "1e400", "10000000000"]


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """Small valid inputs, so that the bad part of each case is the one that is reported."""
    d = tmp_path_factory.mktemp("good")
    rng = np.random.default_rng(5)
    v = rng.normal(size=(300, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    pts = d / "pts.csv"
    pts.write_text("x,y,z\n" + "\n".join(",".join(f"{c:.6f}" for c in r) for r in v) + "\n")
    rec = d / "rec.csv"
    t = np.arange(3000) / 10.0
    rec.write_text("t,x,y,z,temp\n" + "\n".join(
        f"{ti:.1f},0.01,0.02,0.99,25.0" for ti in t) + "\n")
    params = d / "p.json"
    params.write_text(json.dumps({"model": "base", "params_int": {
        n: (1 << 24 if i < 3 else 0) for i, n in enumerate(
            ["kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz"])}}))
    return d, pts, rec, params


def option_cases(good):
    d, pts, rec, params = good
    out = d / "out.csv"
    groups = [
        (["calibrate", pts], ["--seconds", "--threshold", "--min-count", "--max-count", "--differ",
                              "--iterations", "--rates", "--jobs", "--axis", "--select", "--profile",
                              "--points", "--method", "--runtime", "--engine", "--dask"]),
        (["apply", params, rec, "-o", out], ["--range"]),
        (["simulate", "paper", "-o", out], ["--noise-mg", "--scenarios", "--points", "--seed",
                                             "--noise-dist"]),
        (["simulate", "wrist", "-o", out], ["--days", "--rate", "--range", "--seed", "--effect"]),
        (["paper", "table2"], ["--scenarios", "--candidates", "--seed", "--profile"]),
        (["paper", "gietzelt"], ["--passes", "--jitter", "--seed"]),
        (["paper", "farago-table3"], ["--devices", "--days", "--rate", "--seed"]),
        (["acquire", "--port", "/dev/null", "--hours", "1"], ["--rate", "--capture-kb",
                                                               "--recal-hours", "--profile"]),
        (["acquire", "--port", "/dev/null"], ["--hours"]),
        (["deploy", "--port", "/dev/null"], ["--rate", "--capture-kb", "--recal-hours"]),
        (["board", "virtual", "--flash", d / "flash"], ["--days", "--rate", "--bus-faults",
                                                         "--speed", "--seed"]),
        (["compare", rec], ["--train"]),
    ]
    for prefix, options in groups:
        for opt in options:
            for bad in BAD_NUMBERS:
                yield [*prefix, opt, bad]


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    """(argv, what it is) for bad files of every kind a command reads."""
    d = tmp_path_factory.mktemp("badfiles")
    cases = []
    names = ["kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz"]
    ident = {n: (1 << 24 if i < 3 else 0) for i, n in enumerate(names)}

    def params(name, text):
        p = d / name
        p.write_bytes(text if isinstance(text, bytes) else text.encode())
        return p

    rec = d / "rec.csv"
    rec.write_text("t,x,y,z\n" + "".join(f"{i / 10:.1f},0,0,1\n" for i in range(200)))
    bad_params = {
        "list.json": "[1, 2]", "number.json": "3", "null.json": "null", "empty.json": "",
        "obj.json": "{}", "binary.json": bytes(range(256)),
        "truncated.json": json.dumps({"model": "base", "params_int": ident})[:40],
        "inf.json": json.dumps({"model": "base", "params_int": {**ident, "kxx": "Infinity"}}).replace(
            '"Infinity"', "Infinity"),
        "nan.json": json.dumps({"model": "base", "params_int": {**ident, "ox": "NaN"}}).replace(
            '"NaN"', "NaN"),
        "huge.json": json.dumps({"model": "base", "params_int": {**ident, "kxx": 10 ** 300}}),
        "float.json": json.dumps({"model": "base", "params_int": {**ident, "kxx": 1.5}}),
        "string.json": json.dumps({"model": "base", "params_int": {**ident, "kxx": "one"}}),
        "missing.json": json.dumps({"model": "base", "params_int": {"kxx": 1 << 24}}),
        "badmodel.json": json.dumps({"model": "base+nonsense", "params_int": ident}),
        "nullmodel.json": json.dumps({"model": None, "params_int": ident}),
        "intmodel.json": json.dumps({"model": 3, "params_int": ident}),
        "listparams.json": json.dumps({"model": "base", "params_int": [1, 2, 3]}),
        "outside.json": json.dumps({"model": "base", "params_int": {**ident, "kxx": 1 << 26}}),
        "nanref.json": json.dumps({"model": "base+temp_offset", "params_int": {
            **ident, "c_x": 0, "c_y": 0, "c_z": 0}, "reference": {"T0": "NaN", "t0": 0}}).replace(
            '"NaN"', "NaN"),
        "noref.json": json.dumps({"model": "base+temp_offset", "params_int": ident}),
        "bydev.json": json.dumps({"by": "device", "devices": "nope"}),
        "bydev2.json": json.dumps({"by": "device", "devices": [{"device": 1}]}),
    }
    for name, text in bad_params.items():
        p = params(name, text)
        cases.append((["apply", p, rec, "-o", d / f"o_{name}.csv"], name))
        cases.append((["calibrate", rec, "--fallback", p], "fallback " + name))
    bad_hist = {
        "zero.jsonl": '{"model": "base", "input": "r", "heldout_error_mg": 0, "noise_floor_mg": 0.1, '
                      '"missing_effect": null}\n',
        "nullmodel.jsonl": '{"model": null, "input": "r", "heldout_error_mg": 1, "noise_floor_mg": '
                           '0.1, "missing_effect": null}\n',
        "nan.jsonl": '{"model": "base", "input": "r", "heldout_error_mg": NaN, "noise_floor_mg": '
                     '0.1, "missing_effect": null}\n',
        "inf.jsonl": '{"model": "base", "input": "r", "heldout_error_mg": Infinity, '
                     '"noise_floor_mg": 0.1, "missing_effect": null}\n',
        "neg.jsonl": '{"model": "base", "input": "r", "heldout_error_mg": -1, "noise_floor_mg": '
                     '0.1, "missing_effect": null}\n',
        "list.jsonl": "[1, 2]\n", "text.jsonl": "hello\n", "empty.jsonl": "",
        "binary.jsonl": bytes(range(256)), "str.jsonl": '{"model": "base", "heldout_error_mg": '
                                                         '"1", "noise_floor_mg": 0.1}\n',
    }
    for name, text in bad_hist.items():
        p = params(name, text)
        cases.append((["report", p], "history " + name))
        cases.append((["report", p, "--json"], "history json " + name))
    bad_rec = {
        "huge.csv": "t,x,y,z\n" + "".join(f"{i / 10:.1f},1e300,1e300,1e300\n" for i in range(500)),
        "hot.csv": "t,x,y,z,temp\n" + "".join(f"{i / 10:.1f},0,0,1,1e308\n" for i in range(500)),
        "nan.csv": "t,x,y,z\n" + "".join(f"{i / 10:.1f},nan,0,1\n" for i in range(500)),
        "inf.csv": "t,x,y,z\n" + "".join(f"{i / 10:.1f},inf,0,1\n" for i in range(500)),
        "header.csv": "t,x,y,z\n",
        "noheader.csv": "".join(f"{i / 10:.1f},0,0,1\n" for i in range(50)),
        "text.csv": "t,x,y,z\n" + "a,b,c,d\n" * 20,
        "binary.csv": bytes(range(256)) * 10,
        "empty.csv": "",
        "backwards.csv": "t,x,y,z\n" + "".join(f"{(500 - i) / 10:.1f},0,0,1\n" for i in range(500)),
        "nant.csv": "t,x,y,z\n" + "nan,0,0,1\n" * 500,
        # further named columns (battery voltage, ...): checked as the others
        "col_nan.csv": "t,x,y,z,temp,battery_v\n" + "".join(f"{i / 10:.1f},0,0,1,25,nan\n"
                                                            for i in range(500)),
        "col_huge.csv": "t,x,y,z,battery_v\n" + "".join(f"{i / 10:.1f},0,0,1,1e300\n"
                                                      for i in range(500)),
        "col_text.csv": "t,x,y,z,battery_v\n" + "".join(f"{i / 10:.1f},0,0,1,low\n"
                                                      for i in range(500)),
        "col_short.csv": "t,x,y,z,battery_v\n" + "".join(f"{i / 10:.1f},0,0,1\n"
                                                       for i in range(500)),
        "garbage.cwa": bytes(range(256)) * 40,
        "garbage.bin": b"Device Identity\r\nDevice Unique Serial Code:x\r\n" + bytes(300),
        "garbage.gt3x": b"PK\x03\x04" + bytes(200),
        "garbage.agdc": b"PK\x03\x04" + bytes(200),
        "short.cwa": b"MD",
    }
    good_params = params("good.json", json.dumps({"model": "base", "params_int": ident}))
    for name, text in bad_rec.items():
        p = params(name, text)
        cases.append((["calibrate", p], "recording " + name))
        cases.append((["apply", good_params, p, "-o", d / f"a_{name}.csv"], "apply " + name))
        cases.append((["diagnose", p], "diagnose " + name))
        cases.append((["compare", p], "compare " + name))
    bad_pts = {
        "p_nan.csv": "x,y,z\n" + "nan,0,1\n" * 30,
        "p_huge.csv": "x,y,z\n" + "1e300,0,1\n" * 30,
        "p_inf.csv": "x,y,z\n" + "0,inf,1\n" * 30,
        "p_few.csv": "x,y,z\n1,0,0\n0,1,0\n",
        "p_text.csv": "x,y,z\n" + "a,b,c\n" * 30,
        "p_cols.csv": "x,y\n" + "1,0\n" * 30,
    }
    for name, text in bad_pts.items():
        p = params(name, text)
        cases.append((["calibrate", p], "points " + name))
        cases.append((["calibrate", p, "--method", "lsq"], "points lsq " + name))
        cases.append((["calibrate", p, "--by", "device"], "points by " + name))
    return cases


def board_log(records):
    from acal import log
    return b"".join(log.encode(t, p) for t, p in records)


@pytest.fixture(scope="module")
def bad_logs(tmp_path_factory):
    """Pulled-log folders whose records pass their CRC but not their kind's rules."""
    from acal import log
    d = tmp_path_factory.mktemp("badlogs")
    boot = struct.pack(log.FORMATS[log.BOOT], 0, 2, 25, 5, 0, 3, 2, 0, 2, 8, 6553, 20, 600, -128,
                       0, 1)
    cases = {
        "short_rest": [(log.BOOT, boot), (log.REST, b"\x01\x02")],
        "short_cal": [(log.BOOT, boot), (log.CAL, bytes(10))],
        "long_boot": [(log.BOOT, boot + b"xx")],
        "boot_rate0": [(log.BOOT, struct.pack(log.FORMATS[log.BOOT], 0, 2, 0, 5, 0, 3, 2, 0, 2,
                                              8, 6553, 20, 600, -128, 0, 1))],
        "boot_axis9": [(log.BOOT, struct.pack(log.FORMATS[log.BOOT], 0, 2, 25, 5, 0, 9, 2, 0, 2,
                                              8, 6553, 20, 600, -128, 0, 1))],
        "boot_range3": [(log.BOOT, struct.pack(log.FORMATS[log.BOOT], 0, 2, 25, 5, 0, 3, 3, 0, 2,
                                               8, 6553, 20, 600, -128, 0, 1))],
        "rest_subset50": [(log.BOOT, boot), (log.REST, struct.pack(log.FORMATS[log.REST], 10, 0, 0,
                                                                    65536, 25, 50, 0))],
        "unknown_type": [(log.BOOT, boot), (99, b"abc")],
        "no_boot": [(log.REST, struct.pack(log.FORMATS[log.REST], 10, 0, 0, 65536, 25, 1, 0))],
        "cal_status9": [(log.BOOT, boot), (log.CAL, struct.pack(log.FORMATS[log.CAL], 10, 1, 9, 5,
                                                                 18, 1, 1, *([1 << 24] * 9)))],
        "samples_short": [(log.BOOT, boot), (log.SAMPLES, b"\x00\x00\x00\x00\x05\x00")],
    }
    out = []
    for name, recs in cases.items():
        f = d / name
        f.mkdir()
        (f / "log.bin").write_bytes(board_log(recs))
        out.append(f)
    empty = d / "empty_capture"
    empty.mkdir()
    (empty / "log.bin").write_bytes(board_log([(log.BOOT, boot)]))
    (empty / "capture.bin").write_bytes(b"")
    out.append(empty)
    return out


def test_bad_options_end_in_one_line(good, capsys):
    n = 0
    for argv in option_cases(good):
        code, _, err = run_main(capsys, argv)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and "Traceback" not in err, (argv, code, err)
        n += 1
    assert n >= 400


def test_bad_files_end_in_one_line(bad_files, capsys):
    for argv, what in bad_files:
        code, out, err = run_main(capsys, argv)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and "Traceback" not in err, (what, argv, code, err)
        assert "nan" not in out.lower() and "inf" not in out.lower(), (what, out)
    assert len(bad_files) >= 140


def test_bad_board_logs_end_in_one_line(bad_logs, capsys):
    for folder in bad_logs:
        code, _, err = run_main(capsys, ["replay", folder])
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and "Traceback" not in err, (folder.name, code, err)


def test_malformed_board_log_records_are_reported_with_their_offset(bad_logs):
    """What `pull` writes into summary.json: a record whose CRC passes but whose length or fields
    cannot be the app's is dropped and said, with its byte offset, like a torn one; the records
    around it are kept."""
    from accelcal.bridge import boardlog
    for folder in bad_logs:
        s = boardlog.summary(folder)
        said = [d for d in s["dropped"] if "malformed record at offset" in d]
        if folder.name in ("no_boot", "empty_capture"):
            assert not said
            continue
        assert len(said) == 1, (folder.name, s["dropped"])
        if not folder.name.startswith(("long_boot", "boot_")):
            assert s["boots"] == 1   # the good BOOT before it kept


def test_a_few_as_real_processes(good, bad_files):
    """The exit code and the absence of a traceback, end to end."""
    picks = [list(next(iter(option_cases(good))))] + [a for a, _ in bad_files[::40]]
    for argv in picks:
        r = subprocess.run([sys.executable, "-m", "accelcal.cli", *map(str, argv)],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, (argv, r.stderr)
        assert "Traceback" not in r.stderr
