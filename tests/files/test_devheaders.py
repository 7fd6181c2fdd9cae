"""Damaged device-file headers (files/devheaders.py): a corpus made from the real sample files
(tests/data/real, licences beside them), every field a reader trusts set to 0, negative, huge,
not a number, or inconsistent with the file's size.  Each case through the CLI's main(argv)
in-process: exit 2, one line naming the file, never a traceback; a few as real processes (no
signal, no library warning lines); and a --jobs batch whose one file kills its reader natively
(actfast's abort on a header claiming 40 000 000 pages, the check switched off in the workers)
finishes the others, the dead one "failed" with its signal named."""
import io
import json
import re
import signal
import subprocess
import sys
import zipfile

import pytest

from conftest import ROOT, run_main

REAL = ROOT / "tests" / "data" / "real"
BIN = (REAL / "gnactv_sample.bin").read_bytes()          # 3 pages, 50 Hz, gains ~25 000
CWA = (REAL / "ax3_sample.cwa").read_bytes()             # header 1024 bytes, 200 Hz blocks
GT3X = REAL / "ggir" / "actigraph_testfile.gt3x"         # info.txt + log.bin, 30 Hz
AGDC = REAL / "pygt3x" / "CPW1C48210013_baseline.agdc"   # read by pygt3x


def _field(data: bytes, key: bytes, value: bytes, count=1) -> bytes:
    out, n = re.subn(re.escape(key) + rb":[^\r\n]*", key + b":" + value, data, count=count)
    assert n, key
    return out


def _put(data: bytes, at: int, value: bytes) -> bytes:
    return data[:at] + value + data[at + len(value):]


def bin_cases():
    # ("4" is no longer here: more pages declared than held, within the configured period, is
    # a truncated file, read to its last whole page: tests/files/test_truncated.py)
    pages = [b"0", b"-1", b"2", b"40000000", b"99999999999999999999", b"x", b""]
    cases = {f"pages {v.decode()!r}": _field(BIN, b"Number of Pages", v) for v in pages}
    for v in (b"0 Hz", b"-5 Hz", b"1e30 Hz", b"nan Hz", b"100000 Hz"):
        cases[f"header rate {v.decode()}"] = _field(BIN, b"Measurement Frequency", v)
    for v in (b"0", b"-5", b"1e30", b"nan", b"0.0001", b"inf"):   # every page's, and the last one's
        body = BIN[BIN.index(b"Recorded Data"):]
        head = BIN[:BIN.index(b"Recorded Data")]
        cases[f"page rate {v.decode()}"] = head + _field(body, b"Measurement Frequency", v, 0)
        last = body.rindex(b"Measurement Frequency:")
        cases[f"last page rate {v.decode()}"] = head + body[:last] + _field(
            body[last:], b"Measurement Frequency", v)
    for key in (b"x gain", b"y gain", b"z gain"):
        for v in (b"0", b"-1", b"99999999999"):
            cases[f"{key.decode()} {v.decode()}"] = _field(BIN, key, v)
    cases["x offset huge"] = _field(BIN, b"x offset", b"99999999")
    cases["no header"] = b"\0" * 1000
    cases["header only"] = BIN[:BIN.index(b"Recorded Data") + 14]
    return cases


def cwa_cases():
    cases = {f"header length {v}": _put(CWA, 2, v.to_bytes(2, "little")) for v in (0, 4, 0xFFFF)}
    for v in (0, 0x40, 0x80):  # rate code 0 (0.1 Hz) at three ranges
        cases[f"header rate byte {v}"] = _put(CWA, 36, bytes([v]))
        cases[f"first block rate byte {v}"] = _put(CWA, 1024 + 24, bytes([v]))
    cases["first block not AX"] = _put(CWA, 1024, b"ZZ")
    cases["header only"] = CWA[:1024]
    cases["header and half a block"] = CWA[:1024 + 100]
    return cases


def _zip(info: str, members=None) -> bytes:
    src = zipfile.ZipFile(GT3X)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for m in members if members is not None else ["log.bin"]:
            z.writestr(m, src.read(m))
        if info is not None:
            z.writestr("info.txt", info)
    return buf.getvalue()


def _claim(data: bytes, name: str, size: int) -> bytes:
    """The zip with member `name`'s uncompressed size set to `size` in its central directory
    entry (and its local header): what a damaged or crafted file claims."""
    b = bytearray(data)
    for sig, at in ((b"PK\x01\x02", 24), (b"PK\x03\x04", 22)):
        i = b.find(sig)
        while i >= 0:
            n = 46 if sig == b"PK\x01\x02" else 30
            ln = int.from_bytes(b[i + (28 if n == 46 else 26):][:2], "little")
            if bytes(b[i + n:i + n + ln]) == name.encode():
                b[i + at:i + at + 4] = min(size, 0xFFFFFFFF).to_bytes(4, "little")
            i = b.find(sig, i + 4)
    return bytes(b)


def gt3x_cases():
    info = zipfile.ZipFile(GT3X).read("info.txt").decode()
    cases = {}
    for key, values in (("Sample Rate", ["0", "-1", "100000", "1e30", "x", "30.5"]),
                        ("Acceleration Scale", ["0", "-1", "1e30", "nan", "inf"]),
                        ("Start Date", ["-1", "99999999999999999999", "637340351120000001"]),
                        ("Last Sample Time", ["-1", "637340333300000000", "x"])):
        for v in values:
            cases[f"{key} {v}"] = _zip(re.sub(rf"{key}: [^\r\n]*", f"{key}: {v}", info))
    cases["no info.txt"] = _zip(None)
    for claim in (200 << 20, 1 << 30, 0xFFFFFFFF):    # log.bin's uncompressed size, as claimed
        cases[f"log.bin claims {claim} bytes"] = _claim(_zip(info), "log.bin", claim)
    cases["not a zip"] = b"PK\x03\x04" + b"\0" * 100
    cases["zip cut short"] = GT3X.read_bytes()[:5000]
    return cases


CORPUS = [(f"bin {k}", ".bin", v) for k, v in bin_cases().items()] + \
    [(f"cwa {k}", ".cwa", v) for k, v in cwa_cases().items()] + \
    [(f"gt3x {k}", ".gt3x", v) for k, v in gt3x_cases().items()]


@pytest.mark.parametrize("name,ext,data", CORPUS, ids=[c[0] for c in CORPUS])
def test_damaged_header_is_one_line_exit_2(name, ext, data, tmp_path, capsys):
    path = tmp_path / f"damaged{ext}"
    path.write_bytes(data)
    code, out, err = run_main(capsys, ["calibrate", path])
    assert code == 2, (name, out, err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("accelcal: error: ") and str(path) in lines[0], err


def test_the_untouched_files_still_read(capsys):
    """The checks refuse none of the real files: each reads to its samples."""
    from accelcal.files.recordings import read_whole
    for p in (REAL / "gnactv_sample.bin", REAL / "ax3_sample.cwa", REAL / "ax6_sample.cwa", GT3X,
              REAL / "pygt3x" / "neo.gt3x", AGDC):
        t, xyz, temp, rec = read_whole(p)
        assert len(t) >= 900, p


def test_real_processes_never_a_signal_never_a_warning_line(tmp_path):
    """End to end: the 12.7 kB .bin claiming 40 000 000 pages (actfast aborted, exit 134 with a
    Rust backtrace, before the check) and a CentrePoint .agdc with Sample Rate 0 (pygt3x's path:
    numpy printed 4 warning lines before the refusal): exit 2, one line on stderr."""
    big = tmp_path / "pages.bin"
    big.write_bytes(_field(BIN, b"Number of Pages", b"40000000"))
    src = zipfile.ZipFile(AGDC)
    agdc = tmp_path / "rate0.agdc"
    with zipfile.ZipFile(agdc, "w") as z:
        for m in src.infolist():
            data = src.read(m)
            if m.filename == "info.txt":
                data = re.sub(rb"Sample Rate: [^\r\n]*", b"Sample Rate: 0", data)
            z.writestr(m.filename, data)
    for p, words in ((big, "Number of Pages"), (agdc, "Sample Rate")):
        r = subprocess.run([sys.executable, "-m", "accelcal.cli", "calibrate", str(p)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and len(r.stderr.splitlines()) == 1, (r.returncode, r.stderr)
        assert words in r.stderr


SITECUSTOMIZE = """
import accelcal.files.devheaders as d
d.check_bin = lambda path: None      # the test's: let actfast meet the damaged header
"""


def test_batch_survives_a_reader_that_dies(tmp_path):
    """A --jobs 2 batch whose one file kills its worker natively (the header check switched off
    in this process tree by a sitecustomize, so actfast aborts on 40 000 000 pages): the other
    files get their records, the dead one is "failed" naming SIGABRT, and the batch exits 0."""
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(SITECUSTOMIZE)
    dead = tmp_path / "dead.bin"
    dead.write_bytes(_field(BIN, b"Number of Pages", b"40000000"))
    good = [REAL / "ax6_sample.cwa", REAL / "gnactv_sample.bin", REAL / "ax3_sample.cwa"]
    import os
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(hook), str(ROOT / "host"), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-m", "accelcal.cli", "calibrate", str(good[0]), str(dead),
                        *map(str, good[1:]), "--jobs", "2", "--json", "--quiet"],
                       capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    recs = {rec["file"].rsplit("/", 1)[-1]: rec for rec in
            (json.loads(ln) for ln in r.stdout.splitlines() if ln.startswith("{"))}
    assert set(recs) == {"ax6_sample.cwa", "dead.bin", "gnactv_sample.bin", "ax3_sample.cwa"}, r.stdout
    assert recs["dead.bin"]["status"] == "failed"
    assert signal.Signals.SIGABRT.name in recs["dead.bin"]["reason"], recs["dead.bin"]
    for g in good:
        assert recs[g.name]["status"] != "failed", recs[g.name]


def test_library_warnings_never_reach_the_terminal(tmp_path):
    """With the header check switched off (a sitecustomize, as above), pygt3x meets Sample Rate
    0 and numpy warns ("divide by zero", 4 lines with Python's -W default): the command line
    still says one line, exit 2; the warnings show only when -W asks for them."""
    import os
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(
        "import accelcal.files.recordings as r\nr.check_device_file = lambda path: None\n")
    src = zipfile.ZipFile(AGDC)
    agdc = tmp_path / "rate0.agdc"
    with zipfile.ZipFile(agdc, "w") as z:
        for m in src.infolist():
            data = src.read(m)
            if m.filename == "info.txt":
                data = re.sub(rb"Sample Rate: [^\r\n]*", b"Sample Rate: 0", data)
            z.writestr(m.filename, data)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(hook), str(ROOT / "host"), os.environ.get("PYTHONPATH", "")]))
    env.pop("PYTHONWARNINGS", None)
    runs = {w: subprocess.run([sys.executable, *w, "-m", "accelcal.cli", "calibrate", str(agdc)],
                              capture_output=True, text=True, timeout=120, env=env)
            for w in ((), ("-W", "default"))}
    quiet, loud = runs[()], runs[("-W", "default")]
    assert quiet.returncode == 2 and len(quiet.stderr.splitlines()) == 1, quiet.stderr
    assert "RuntimeWarning" in loud.stderr      # the warnings were there to be dropped


@pytest.mark.slow
def test_the_whole_corpus_as_real_processes(tmp_path):
    """Every case above as a real process (the in-process run cannot see a signal): exit 2, one
    line on stderr, never a signal (a negative return code), never a traceback."""
    bad = []
    for name, ext, data in CORPUS:
        path = tmp_path / f"damaged{ext}"
        path.write_bytes(data)
        r = subprocess.run([sys.executable, "-m", "accelcal.cli", "calibrate", str(path)],
                           capture_output=True, text=True, timeout=120)
        if r.returncode != 2 or len(r.stderr.splitlines()) != 1 or "Traceback" in r.stderr:
            bad.append((name, r.returncode, r.stderr[-300:]))
    assert not bad, bad


def test_a_long_first_page_counts_whole(tmp_path, capsys):
    """actfast reserves pages x the first page's samples: a first hex line longer than a read
    (1 MiB) counts whole, so 40 pages after a 3 MB first line are refused (they would reserve
    ~40 x 3 MB / 12 samples of 20 bytes: 200 MB from a 3 MB file)."""
    head = BIN[:BIN.index(b"Recorded Data")]
    page = BIN[BIN.index(b"Recorded Data"):BIN.index(b"Recorded Data", BIN.index(b"Recorded Data") + 1)]
    hexline = page.rstrip(b"\r\n").rsplit(b"\n", 1)[1].strip()
    first = page.replace(hexline, hexline * (3_000_000 // len(hexline)))
    small = page.replace(hexline, hexline[:12])
    path = tmp_path / "long.bin"
    path.write_bytes(_field(head, b"Number of Pages", b"40") + first + small * 39)
    code, _, err = run_main(capsys, ["calibrate", path])
    assert code == 2 and "hex characters is more than the file's" in err, err
