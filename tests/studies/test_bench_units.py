"""`accelcal bench --runtime rp2040`'s install units (docs/boards-and-logs.md "Install units"):
the rows for a firmware with the units frozen in are measured where such a firmware is in the
checkout and printed beside the littlefs ones; without one, nothing is claimed for it."""
import dataclasses

from accelcal.bridge import rp2040
from accelcal.studies import bench_chip


def units(pre, ms, free):
    m = {}
    for i, case in enumerate(bench_chip.UNIT_CASES):
        u = pre + f"units_{case}_"
        m.update({u + "import_app_ms": ms, u + "free_after_import_bytes": free,
                  u + "free_with_processor_bytes": free - 1000 * (i + 1), u + "modules": 22 + i,
                  u + "discover_modules": i, u + "paper_modules": 0})
    return m


def test_no_frozen_firmware_no_frozen_rows(monkeypatch):
    monkeypatch.setattr(rp2040, "MICROPYTHON_FROZEN", dataclasses.replace(
        rp2040.MICROPYTHON_FROZEN, folder="no-such-firmware-folder"))
    assert bench_chip.frozen_units() == {}
    out = bench_chip.format_chip(units(bench_chip.MP, 436.8, 156944))
    assert "install units, MicroPython:" in out and "frozen" not in out


def test_the_frozen_rows_beside_the_littlefs_ones():
    m = {**units(bench_chip.MP, 436.8, 156944), **units(bench_chip.FROZEN, 56.1, 224240)}
    lines = bench_chip.format_chip(m).splitlines()
    i = next(n for n, line in enumerate(lines) if line.startswith("install units, MicroPython, the units frozen"))
    rows = dict(line.split(None, 1) for line in lines[i + 1:i + 1 + len(bench_chip.UNIT_CASES)])
    assert rows["base"].startswith("56.1 ms / 224,240 / 223,240 bytes; 22 (0, 0)")
    assert rows["all"].startswith("56.1 ms / 224,240 / 220,240 bytes; 25 (3, 0)")
