"""A real 66.7 Hz GENEActiv recording (issue 50 part 3, "the 66.7 Hz file read"): GENEAcore's
test file `1008667Hz.bin` (GPL >= 2, tests/data/real/geneacore/), a GENEActiv 1.2 on a right
wrist, 293 pages of 300 samples, its page times stamped in whole seconds 4 and 5 s apart, so that
every other page is stamped before the previous page's last sample.  Refused whole before ("time
does not increase"); read here, its overlapping pages counted as counted from its own page times,
every sample within 10 ms of where GENEAread (ActivInsights' reader: every sample from the first
page's time at 66.667 Hz) puts it, its rate as measured and its hours from it."""
import calendar
import json
import re
import time

import numpy as np

from accelcal.files.recordings import open_recording
from conftest import ROOT, run_main

BIN = ROOT / "tests" / "data" / "real" / "geneacore" / "1008667Hz.bin"
PAGE = 300


def page_times():
    """Each page's `Page Time` (s since the epoch), parsed from the file's text here."""
    text = BIN.read_bytes().decode("latin-1")
    stamps = re.findall(r"Page Time:(\d+-\d+-\d+ \d+:\d+:\d+):(\d+)", text)
    return np.array([calendar.timegm(time.strptime(a, "%Y-%m-%d %H:%M:%S")) + int(ms) / 1000
                     for a, ms in stamps])


def test_a_real_66_7_hz_geneactiv_file_is_read_its_overlaps_placed_and_counted(capsys):
    stamps = page_times()
    assert len(stamps) == 293 and set(np.diff(stamps)) == {4.0, 5.0}
    # pages stamped at or before the page before's last sample (300 samples at 66.7 Hz: 4.48 s)
    expected = int(np.sum(stamps[1:] <= stamps[:-1] + (PAGE - 1) / 66.7))
    assert expected == 146
    rec = open_recording(BIN)
    assert rec.overlapping_pages == expected
    t = np.concatenate([c.t for c in rec.chunks()])
    assert len(t) == PAGE * len(stamps) and (np.diff(t) > 0).all()
    geneaaread = stamps[0] + np.arange(len(t)) * 3 / 200   # 66.667 Hz from the first page
    assert np.abs(t - geneaaread).max() < 0.01
    code, out, err = run_main(capsys, ["calibrate", BIN, "--json"])
    assert "time does not increase" not in err
    r = json.loads(out)
    assert r["overlapping_pages"] == expected and r["gaps"] == 0, r
    assert abs(r["rate_hz"] - 200 / 3) < 0.01 and r["rate_hz_device"] == 67, r["rate_hz"]
    assert abs(r["hours"] - len(t) * 3 / 200 / 3600) < 0.001, r["hours"]
    # 22 minutes on one side of the sphere: said, not calibrated
    assert code == 2 and r["status"] == "not_enough_data" and "one hemisphere" in r["reason"]
