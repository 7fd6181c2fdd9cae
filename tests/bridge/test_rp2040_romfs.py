"""The emulated RP2040 on MicroPython v1.28.0 built with a ROMFS partition (firmware/
micropython-rp2040-romfs, issue 26): the package, written as a ROMFS image at the partition's
flash offset, is imported from /rom (run in place, not copied to the heap as from littlefs) and
gives CPython's integers on a fit.  Skipped, saying why, where Node, rp2040js or either firmware
is missing."""
import json

import pytest

from accelcal.bridge import rp2040
from conftest import emulated_chip, run_main

# gc.mem_free() before and after importing the app, and where its module came from
HEAP_AFTER_IMPORT = ("import gc\ngc.collect()\nbefore = gc.mem_free()\nimport acal.logger.app\n"
                     "gc.collect()\nprint(acal.logger.app.__file__, before - gc.mem_free())\n")


@pytest.fixture(scope="module")
def chips():
    return emulated_chip(rp2040.MICROPYTHON_ROMFS), emulated_chip(rp2040.MICROPYTHON)


def test_package_executes_from_rom_and_leaves_the_heap(chips):
    chip = chips[0]
    where_rom, cost_rom = chip.run_script(HEAP_AFTER_IMPORT, fw=rp2040.MICROPYTHON_ROMFS).out.split()
    where_lfs, cost_lfs = chip.run_script(HEAP_AFTER_IMPORT, fw=rp2040.MICROPYTHON).out.split()
    assert where_rom == "/rom/lib/acal/logger/app.mpy"     # the ROMFS copy, not a littlefs one
    assert where_lfs == "/lib/acal/logger/app.mpy"
    # the same .mpy files: from littlefs their bytecode and constants are copied to the heap,
    # from /rom they stay in flash (the viper code is copied either way); measured here: 47.2 kB
    # from /rom against 74.7 kB from littlefs, so a quarter less is a safe floor
    assert 0 < int(cost_rom) < int(cost_lfs) * 3 // 4, (cost_rom, cost_lfs)


def test_fit_from_rom_equals_cpython(chips, tmp_path, capsys):
    pts = tmp_path / "pts.csv"
    from accelcal import cli
    assert cli.main(["simulate", "paper", "--noise-mg", "1", "--scenarios", "1", "--seed", "7",
                     "-o", str(pts)]) == 0
    capsys.readouterr()
    records = {}
    for rt in ("cpython", "rp2040-romfs"):
        code, out, err = run_main(capsys, ["calibrate", str(pts), "--runtime", rt, "--json"])
        assert code == 0 and out, err
        rec = json.loads(out)
        assert rec.pop("runtime") == rt
        records[rt] = rec
    assert records["rp2040-romfs"] == records["cpython"]
