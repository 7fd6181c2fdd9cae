"""Power cuts on the emulated Pico's real littlefs (board/powercut.py): the chip stopped at
pseudo-random cycles while the device appends to its log and while it saves calibrations,
powered up again on the flash as the cut left it.  0 acknowledged records lost, 0 damaged,
0 mixed calibrations, 0 failed boots; and the judge sees each of those when it is there."""
import struct

import pytest

from acal.logger import log
from accelcal.board import powercut
from conftest import emulated_chip


@pytest.fixture(scope="module")
def emulator():
    emulated_chip()


def _encode_values(rtype, values):
    # a record of rtype's layout (log.FORMATS) holding values, framed as the board writes it
    return log.encode(rtype, struct.pack(log.FORMATS[rtype], *values))


def _log_bytes(values):
    return b"".join(_encode_values(log.REST, v) for v in values)


def _store_bytes(values):
    return log.encode(log.STORE, _encode_values(log.CAL, values)[3:-4])


def test_the_judge_sees_lost_damaged_and_mixed(tmp_path):
    """Findings made by hand, one of each kind, so the counts below cannot be zero for want
    of looking."""
    good = [powercut.rest_values(i) for i in range(5)]
    resumed = "ACAL_RESUMED 0 0\n"
    boot = _encode_values(log.BOOT, (0, 2, 100, 5, 0, 0, 2, 1, 2, 2, 0, 50, 0, -128, 0, 0, 0))
    after = (_log_bytes(good[:3]) + boot).hex()
    rec = {"out": "W 0\nW 1\nW 2\nW 3\n", "resume_out": resumed,
           "before": {"log.bin": _log_bytes(good[:3]).hex()}, "after": {"log.bin": after}}
    assert powercut.judge("log", rec, tmp_path)["lost"] == 1          # W 3 acknowledged, absent
    bad = good[:2] + [(1,) + good[2][1:]]
    rec["before"]["log.bin"] = _log_bytes(bad).hex()
    rec["after"]["log.bin"] = (_log_bytes(bad) + boot).hex()
    assert powercut.judge("log", rec, tmp_path)["damaged"] == 1
    mixed = powercut.cal_values(3)[:1] + (4,) + powercut.cal_values(3)[2:]
    rec = {"out": "S 1\nS 2\nS 3\n", "resume_out": "ACAL_RESUMED 0 4\n",
           "before": {"cal_a.bin": _store_bytes(mixed).hex(),
                      "cal_b.bin": _store_bytes(powercut.cal_values(2)).hex()}}
    assert powercut.judge("store", rec, tmp_path)["mixed"] == 1
    rec["before"]["cal_a.bin"] = _store_bytes(powercut.cal_values(4)).hex()
    assert powercut.judge("store", rec, tmp_path) == {"acked": 3, "lost": 0, "damaged": 0,
                                                      "mixed": 0, "failed_boot": 0}
    rec["resume_out"] = "ACAL_RESUMED 0 3\n"     # the app did not take the stored calibration
    assert powercut.judge("store", rec, tmp_path)["failed_boot"] == 1
    assert powercut.judge("store", {"out": "", "boot_error": "stuck"}, tmp_path)["failed_boot"] == 1


def test_power_cuts_lose_nothing(emulator):
    """Two cuts of each workload (the default run; make bench cuts 200)."""
    r = powercut.run_cuts(2, seed=11)
    assert r["cuts"] == 4
    assert (r["records_lost"], r["records_damaged"], r["mixed_calibrations"], r["failed_boots"]) \
        == (0, 0, 0, 0), r["problems"]


@pytest.mark.slow
def test_200_power_cuts_lose_nothing(emulator):
    r = powercut.run_cuts(100, seed=1)
    print(f"\npower cuts on the emulated Pico: {r['cuts']} cuts ({r['log_cycles']} and "
          f"{r['store_cycles']} cycles of log and store workload), {r['records_acked']} log records "
          f"acknowledged before a cut: {r['records_lost']} lost, {r['records_damaged']} damaged; "
          f"{r['mixed_calibrations']} mixed calibrations; {r['failed_boots']} failed boots")
    assert r["cuts"] == 200
    assert (r["records_lost"], r["records_damaged"], r["mixed_calibrations"], r["failed_boots"]) \
        == (0, 0, 0, 0), r["problems"]
