"""Truncated device files (issue 50): read to their last whole page or block, never refused
whole and never silent.  GGIR's (and GGIRread's) GENEActiv_testfile.bin (Apache-2.0,
tests/data/real/ggir/) declares 222 048 pages and holds 17, the 17th cut mid-way: GGIRread
reads the pages that are there (its own test expects page 1's 300th z at -0.808364 g, 21.5 degC,
its 300th sample 3488 ms after the first), so do we, keeping the 16 whole pages, dropping the
cut one, both counted in the record with one warning line.  Files cut by the test itself: a
.bin at every kind of place (inside a page's field lines, its hex line, at a page's end), a .cwa
inside its last block (read to its last whole block), a .gt3x anywhere (its zip's directory and
info.txt come after log.bin: refused, one line).  A header damaged otherwise is still refused
(tests/files/test_devheaders.py)."""
import json
import re

import numpy as np
import pytest

from accelcal.files.recordings import open_recording
from conftest import ROOT, run_main

REAL = ROOT / "tests" / "data" / "real"
GGIR_BIN = REAL / "ggir" / "GENEActiv_testfile.bin"
PAGE = 300


def whole(path):
    rec = open_recording(path)
    ch = list(rec.chunks())
    return rec, np.concatenate([c.t for c in ch]), np.concatenate([c.xyz for c in ch])


def test_ggirs_truncated_geneactiv_file_reads_its_whole_pages():
    data = GGIR_BIN.read_bytes()
    assert b"Number of Pages:222048" in data and data.count(b"Recorded Data") == 17
    rec, t, xyz = whole(GGIR_BIN)
    assert len(t) == 16 * PAGE and (np.diff(t) > 0).all()
    assert (rec.pages_missing, rec.pages_cut) == (222048 - 17, 1)
    assert [w for w in rec.warnings if "truncated" in w] == [
        "a truncated file: the header declares 222048 pages, the file holds 16 whole pages "
        "and 1 cut mid-way (dropped); 222031 declared pages missing"]
    # GGIRread's own expectations for page 1 (tests/testthat/test_readGENEActiv.R)
    assert abs(xyz[PAGE - 1, 2] - -0.808364) < 1e-5
    assert int((t[PAGE - 1] - t[0]) * 1000) == 3488
    temp = np.concatenate([c.temp for c in rec.chunks()])
    assert temp[0] == 21.5
    # each page at its own Page Time (s since the epoch, as written: local clock)
    stamps = re.findall(rb"Page Time:(\S+ \S+):(\d+)", data)[:16]
    import calendar
    import time
    first = [calendar.timegm(time.strptime(a.decode(), "%Y-%m-%d %H:%M:%S")) + int(ms) / 1000
             for a, ms in stamps]
    assert np.abs(t[::PAGE] - first).max() < 1e-3


def test_calibrate_says_so_in_the_record_and_one_line(capsys):
    code, out, err = run_main(capsys, ["calibrate", GGIR_BIN, "--json"])
    r = json.loads(out)
    assert (r["pages_missing"], r["pages_cut"]) == (222031, 1), r
    assert abs(r["hours"] - 16 * PAGE / 85.7 / 3600) < 2e-4, r["hours"]
    assert r["status"] == "not_enough_data" and code == 2     # 56 s of wrist: said, not calibrated
    code, out, err = run_main(capsys, ["calibrate", GGIR_BIN])
    lines = [ln for ln in out.splitlines() if "truncated" in ln]
    assert len(lines) == 1 and lines[0].startswith("warning: a truncated file"), out


@pytest.mark.parametrize("where", ["field line", "hex line", "page end", "no newline"])
def test_a_bin_cut_by_the_test_keeps_its_whole_pages(tmp_path, where):
    """The file cut inside page 9 (its 5th field line, or its hex line), at page 9's end, or with
    its last hex line's newline cut off: the pages before are read exactly as from the whole."""
    data = GGIR_BIN.read_bytes()
    starts = [m.start() for m in re.finditer(rb"Recorded Data", data)]
    p9 = data[starts[8]:starts[9]]
    hex_at = starts[8] + p9.rindex(b"\n", 0, len(p9) - 2) + 1
    cut, kept, cut_pages = {"field line": (starts[8] + p9.index(b"Battery") + 3, 8, 1),
                            "hex line": (hex_at + 1000, 8, 1),
                            "page end": (starts[9], 9, 0),
                            "no newline": (starts[9] - 2, 9, 0)}[where]
    path = tmp_path / "cut.bin"
    path.write_bytes(data[:cut])
    assert data[cut - 2:cut] != b"\r\n" or where == "page end"
    rec, t, xyz = whole(path)
    _, t0, xyz0 = whole(GGIR_BIN)
    assert len(t) == kept * PAGE and (rec.pages_missing, rec.pages_cut) == (222048 - 9, cut_pages)
    assert np.array_equal(t, t0[:len(t)]) and np.array_equal(xyz, xyz0[:len(t)])


def test_a_bin_whose_last_page_is_cut_but_its_count_right(tmp_path):
    """scikit-digital-health's 3-page gnactv_sample.bin cut inside its last hex line: 2 pages
    read, the cut one counted, nothing declared missing."""
    data = (REAL / "gnactv_sample.bin").read_bytes()
    path = tmp_path / "cut.bin"
    path.write_bytes(data[:len(data) - 500])
    rec, t, xyz = whole(path)
    _, t0, xyz0 = whole(REAL / "gnactv_sample.bin")
    assert len(t) == 2 * PAGE and (rec.pages_missing, rec.pages_cut) == (0, 1)
    assert np.array_equal(xyz, xyz0[:2 * PAGE])


def test_a_count_beyond_the_configured_period_is_still_a_damaged_header(tmp_path, capsys):
    """gnactv_sample.bin is configured for 360 h at 50 Hz (216 001 pages): a header declaring
    more than that is damaged, not truncated."""
    data = (REAL / "gnactv_sample.bin").read_bytes()
    for pages, ok in ((216001, True), (216002, False)):
        path = tmp_path / f"p{pages}.bin"
        path.write_bytes(data.replace(b"Number of Pages:3", b"Number of Pages:%d" % pages))
        code, out, err = run_main(capsys, ["calibrate", path])
        if ok:
            assert "warning: a truncated file" in out and "215998 declared pages missing" in out
        else:
            assert code == 2 and len(err.splitlines()) == 1 and "outside 1..216001 pages" in err


def test_a_cwa_cut_inside_its_last_block(tmp_path, capsys):
    data = (REAL / "ax3_sample.cwa").read_bytes()
    path = tmp_path / "cut.cwa"
    path.write_bytes(data[:len(data) - 300])
    rec, t, xyz = whole(path)
    _, t0, xyz0 = whole(REAL / "ax3_sample.cwa")
    assert rec.pages_cut == 1 and rec.n_blocks == (len(data) - 1024) // 512 - 1
    assert 0 < len(t0) - len(t) <= 120 and np.array_equal(xyz, xyz0[:len(t)])
    code, out, err = run_main(capsys, ["calibrate", path, "--json"])
    assert json.loads(out)["pages_cut"] == 1


@pytest.mark.parametrize("keep", [0.3, 0.99])
def test_a_gt3x_cut_anywhere_is_refused_in_one_line(tmp_path, capsys, keep):
    data = (REAL / "ggir" / "actigraph_testfile.gt3x").read_bytes()
    path = tmp_path / "cut.gt3x"
    path.write_bytes(data[:int(len(data) * keep)])
    code, out, err = run_main(capsys, ["calibrate", path])
    assert code == 2 and len(err.splitlines()) == 1 and "damaged zip" in err, err


def test_a_count_past_the_file_without_a_configured_period_is_refused(tmp_path, capsys):
    """Without 'Measurement Period' nothing bounds what a truncated file may declare: refused."""
    data = (REAL / "gnactv_sample.bin").read_bytes()
    path = tmp_path / "noperiod.bin"
    path.write_bytes(re.sub(rb"Measurement Period:[^\r\n]*\r?\n", b"", data.replace(
        b"Number of Pages:3", b"Number of Pages:4")))
    code, out, err = run_main(capsys, ["calibrate", path])
    assert code == 2 and len(err.splitlines()) == 1 and "no 'Measurement Period'" in err, err
