"""Real timing (issue 50 part 3): a rate is kept as the file's clock measures it (a float; the
device's segments at the nearest whole rate) and the hours follow it; a GENEActiv .bin whose page
times overlap (a 66.7 Hz recording: 300 samples are 4.498 s, page times written in whole seconds)
is read, its overlapping pages placed as the maker's readers place them (files/pagetimes.py) and
counted in the quality record.  The files are made here byte by byte per the formats: the .bin
per GENEActiv's page layout (as the real sample in tests/data/real/gnactv_sample.bin), the .cwa
by accelcal.simulate.cwa (cwa.h)."""
import calendar
import json
import time

import numpy as np

from accelcal.files.pagetimes import resolve_overlaps
from accelcal.files.recordings import open_recording
from conftest import run_main

PAGE = 300
START = calendar.timegm((2026, 1, 5, 8, 0, 0))


def _stamp(s: float) -> str:
    whole = int(np.floor(s))
    return time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(whole)) + f":{int(round((s - whole) * 1000)):03d}"


def write_bin(path, page_times, xyz_g, temp_c, freq="66.7", gain=25600, offset=0):
    """A GENEActiv .bin: the text header (its sections as the device writes them) and one page
    of 300 samples per page time (s since the epoch), each sample 12 hex digits: x, y, z as
    12-bit two's complement raw = (g * gain + offset) / 100, then light and button."""
    head = ["Device Identity", "Device Unique Serial Code:000001", "Device Type:GENEActiv",
            "Device Model:1.1", "Device Firmware Version:Ver4.08a date14Jul14",
            "Calibration Date:2026-01-01 00:00:00:000", "", "Device Capabilities",
            "Accelerometer Range:-8 to 8", "Accelerometer Resolution:0.0039",
            "Accelerometer Units:g", "Light Meter Range:0 to 5000", "Light Meter Resolution:5",
            "Light Meter Units:lux", "Temperature Sensor Range:0 to 70",
            "Temperature Sensor Resolution:0.1", "Temperature Sensor Units:deg. C", "",
            "Configuration Info", f"Measurement Frequency:{freq} Hz", "Measurement Period:168 Hours",
            f"Start Time:{_stamp(page_times[0])}", "Time Zone:GMT +00:00", "", "Trial Info",
            "Study Centre:test", "Study Code:1", "Investigator ID:", "Exercise Type:",
            "Config Operator ID:", f"Config Time:{_stamp(page_times[0] - 60)}", "Config Notes:",
            "Extract Operator ID:", f"Extract Time:{_stamp(page_times[-1] + 60)}",
            "Extract Notes:", "", "Subject Info", "Device Location Code:left wrist",
            "Subject Code:1", "Date of Birth:1900-1-1", "Sex:", "Height:", "Weight:",
            "Handedness Code:", "Subject Notes:", "", "Calibration Data",
            f"x gain:{gain}", f"x offset:{offset}", f"y gain:{gain}", f"y offset:{offset}",
            f"z gain:{gain}", f"z offset:{offset}", "Volts:300", "Lux:800", "", "Memory Status",
            f"Number of Pages:{len(page_times)}", ""]
    raw = np.round((np.asarray(xyz_g) * gain + offset) / 100).astype(np.int64) & 0xFFF
    lines = list(head)
    for k, pt in enumerate(page_times):
        r = raw[k * PAGE:(k + 1) * PAGE]
        hexes = "".join(f"{x:03X}{y:03X}{z:03X}000" for x, y, z in r)
        lines += ["Recorded Data", "Device Unique Serial Code:000001", f"Sequence Number:{k}",
                  f"Page Time:{_stamp(pt)}", "Unassigned:", f"Temperature:{temp_c[k]:.1f}",
                  "Battery voltage:4.10", "Device Status:Recording", f"Measurement Frequency:{freq}",
                  hexes]
    path.write_bytes(("\n".join(lines) + "\n").encode())
    return path


def postures(n, rate, seed=0, hold_s=60):
    """n samples (g) holding random orientations hold_s seconds each, with 2 mg of noise."""
    rng = np.random.default_rng(seed)
    k = -(-n // int(hold_s * rate))
    d = rng.normal(size=(k, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.repeat(d, int(hold_s * rate), axis=0)[:n] + rng.normal(0, 0.002, (n, 3))


def test_a_66_7_hz_bin_with_overlapping_page_times_is_read(tmp_path, capsys):
    """600 pages of a 66.667 Hz clock (4.5 s a page) stamped in whole seconds: every other page
    is stamped before the previous page's last sample.  Refused whole before ("time does not
    increase"); now read, the overlapping pages counted (as counted here from the page times),
    every sample within a second of its true time, the rate as measured (66.67 Hz) and the
    hours right (0.75 h)."""
    pages, true_rate = 600, 200 / 3
    true_start = START + 0.25 + np.arange(pages) * PAGE / true_rate
    stamps = np.floor(true_start)
    n = pages * PAGE
    path = write_bin(tmp_path / "g667.bin", stamps, postures(n, true_rate),
                     25 + 5 * np.sin(np.arange(pages) / 50))
    # pages whose stamp is at or before the page before's last sample (actfast's spacing, 1/66.7)
    expected = int(np.sum(stamps[1:] <= stamps[:-1] + (PAGE - 1) / 66.7))
    assert expected >= pages // 3
    rec = open_recording(path)
    assert rec.overlapping_pages == expected
    t = np.concatenate([c.t for c in rec.chunks()])
    assert len(t) == n and (np.diff(t) > 0).all()
    true_t = START + 0.25 + np.arange(n) / true_rate
    assert np.abs(t - true_t).max() < 1.0
    code, out, err = run_main(capsys, ["calibrate", path, "--json"])
    assert "time does not increase" not in err and code in (0, 2), err
    r = json.loads(out)
    assert r["overlapping_pages"] == expected
    assert abs(r["rate_hz"] - true_rate) < 0.05 and r["rate_hz_device"] == 67, r["rate_hz"]
    assert abs(r["hours"] - n / true_rate / 3600) < 0.002 and r["gaps"] == 0, r


def test_pages_that_do_not_overlap_keep_their_times():
    """The rule moves only a page stamped at or before the page before's last sample: a page
    stamped late (a gap) or exactly on time keeps its time; a moved page lands one sample
    period after the last sample before it, its own spacing kept."""
    step = 0.01
    t = np.concatenate([s + np.arange(3) * step for s in (0.0, 0.03, 0.04, 5.0, 5.01)])
    before = t.copy()
    assert resolve_overlaps(t, page=3) == 2
    assert np.allclose(t[:6], before[:6])                    # on time: kept
    assert np.allclose(t[6:9], 0.06 + np.arange(3) * step)   # 0.04 <= 0.05: after it
    assert np.allclose(t[9:12], before[9:12])                # late (a gap): kept
    assert np.allclose(t[12:], 5.03 + np.arange(3) * step)   # 5.01 <= 5.02: moved
    clean = np.arange(30) * step
    assert resolve_overlaps(clean, page=3) == 0 and np.array_equal(clean, np.arange(30) * step)


def test_a_1_56_hz_recording_has_its_hours(tmp_path, capsys):
    """An AX3 recording at 1.5625 Hz (3200 / 2^11, a rate cwa.h encodes) of 14 days: reported as
    2 Hz and 262 h before; now 1.5625 Hz and 336 h."""
    from accelcal.simulate.cwa import CwaWriter
    rate, days = 1.5625, 14
    n = int(days * 86400 * rate)
    path = tmp_path / "slow.cwa"
    with open(path, "wb") as fh:
        w = CwaWriter(fh, rate, start_s=START)
        t = np.arange(n) / rate
        w.write(t, postures(n, rate, seed=1, hold_s=1800), 30 + 3 * np.sin(t / 86400 * 2 * np.pi))
        w.close()
    code, out, err = run_main(capsys, ["calibrate", path, "--json"])
    r = json.loads(out)
    assert abs(r["rate_hz"] - rate) < 0.001 and r["rate_hz_device"] == 2, r["rate_hz"]
    assert abs(r["hours"] - days * 24) < 0.5 and r["gaps"] == 0, r


def test_a_drifting_rate_is_kept_as_measured(tmp_path, capsys):
    """A CSV whose clock drifts from 25 Hz to 26 Hz over 4 hours, with a 10-minute gap: the
    rate is the samples over the time they span outside the gap (25.5 Hz, not the first
    chunk's 25), the hours the 4 hours less the gap."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    span = 4 * 3600.0
    # instantaneous rate 25 + s / span: t(s) solves dN/dt = rate, N(t) = 25 t + t^2 / (2 span)
    n_total = int(25 * span + span / 2)
    k = np.arange(n_total)
    t = (-25 + np.sqrt(25 ** 2 + 2 * k / span)) * span
    keep = (t < 3600) | (t >= 3600 + 600)
    t, n = t[keep], int(keep.sum())
    v = postures(n, 25.5, seed=2)
    path = tmp_path / "drift.csv"
    pacsv.write_csv(pa.table({"t": np.round(t, 4), "x": np.round(v[:, 0], 4),
                              "y": np.round(v[:, 1], 4), "z": np.round(v[:, 2], 4)}), path)
    code, out, err = run_main(capsys, ["calibrate", path, "--json"])
    r = json.loads(out)
    gap_free = span - 600
    assert r["gaps"] == 1 and r["rate_hz_device"] == 25, r
    assert abs(r["hours"] - gap_free / 3600) < 0.005, r["hours"]
    assert abs(r["rate_hz"] - (n - 2) / (t[-1] - t[0] - 600)) < 0.01, r["rate_hz"]
