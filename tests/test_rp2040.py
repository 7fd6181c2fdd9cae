"""The emulated RP2040 as a runtime: MicroPython's own RPI_PICO firmware on rp2040js, the device
package installed as armv6m .mpy files, gives the same integers as CPython."""
import json

import pytest

from accelcal.bridge import rp2040, runtime
from accelcal.errors import InputError
from conftest import run_main


@pytest.fixture(scope="session")
def chip():
    """The emulated chip with the package installed; skipped, saying why, where Node or
    rp2040js is missing (make setup installs it; CI has both)."""
    try:
        rp2040.emulator_index()
        rp2040.flash_image()
    except InputError as e:
        pytest.skip(f"emulated RP2040 not available: {e}")
    return rp2040


def test_firmware_is_micropython_on_an_rp2040(chip):
    out = chip.run_script("import sys, gc\nprint(sys.implementation._machine)\n"
                          "print(sys.maxsize)\nimport acal.fixed\nprint(acal.fixed.__file__)\n").out
    machine, maxsize, where = out.split("\n")[:3]
    assert "RP2040" in machine
    assert int(maxsize) == 2**31 - 1             # 32-bit words: small ints stop at 2^30
    assert where.endswith("acal/fixed.mpy")      # installed as .mpy, as a deployment is


def test_cycles_are_counted(chip):
    short = chip.run_script("x = 0\n").cycles
    loop = chip.run_script("x = 0\nfor i in range(2000):\n    x += i\n").cycles
    assert loop > short + 2000 * 10              # every bytecode costs cycles


def test_calibrate_on_the_chip_equals_cpython(tmp_path, chip, capsys):
    pts = tmp_path / "pts.csv"
    assert run_main(capsys, ["simulate", "paper", "--noise-mg", "1", "--scenarios", "1",
                             "--seed", "7", "-o", str(pts)])[0] == 0
    records = {}
    for rt in ("cpython", "rp2040"):
        code, out, err = run_main(capsys, ["calibrate", str(pts), "--by", "device",
                                           "--runtime", rt, "--json"])
        assert code == 0, err
        rec = json.loads(out)
        assert rec.pop("runtime") == rt
        records[rt] = rec
    assert records["rp2040"] == records["cpython"]
    assert records["cpython"]["points"] >= 18


def test_missing_emulator_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv("ACCELCAL_RP2040JS", str(tmp_path / "nowhere.js"))
    with pytest.raises(InputError, match="rp2040js is not installed"):
        rp2040.emulator_index()
    assert "rp2040" in runtime.RUNTIMES
