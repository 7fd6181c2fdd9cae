"""The device package as a tree of files, on the host and on the board: which modules a board
gets (every `.py` under device/acal, in whatever subfolders it has, the CircuitPython driver only
on CircuitPython boards), and the board-side code that swaps the deployed package for a new one
so that exactly the new files remain (`deploy`)."""
from __future__ import annotations

from pathlib import Path

from accelcal.locations import (CIRCUITPYTHON_ONLY, DEVICE_PACKAGE, DEVICE_UNITS, module_name,
                                package_sources, unit_of)

__all__ = ["CIRCUITPYTHON_ONLY", "STAGE", "TARGET", "module_name", "package_sources", "stage_code",
           "swap_code", "swap_report", "unit_of", "unit_package", "unit_manifest", "unit_files"]

# Where deploy stages the new package before the swap, and where it ends up.
STAGE = "lib/.acal-new"
TARGET = "lib/acal"
# Each install unit's mip package and freeze manifest, written from package_sources' walk by
# tools/units.py and checked against it (tests/board/test_units.py).
UNIT_JSON = "{unit}.json"                      # in device/: `mpremote mip install device/core.json`
UNIT_MANIFEST = "manifests/{unit}/manifest.py"  # in device/: include("…/device/manifests/core")

MANIFEST_HEAD = """# The install unit `{unit}` of the device package acal, for a MicroPython firmware that freezes
# only the units its board runs: in the board's manifest (FROZEN_MANIFEST), include() this folder
# for each unit: core and logger on every board, paper for the paper profile, discover for
# --discover.  Written by tools/units.py from the walk deploy copies (host/accelcal/board/tree.py);
# device/{unit}.json is the same unit for mip.  The sources as they are: `make build` writes
# build/BOARD/freeze/ with the same units and the hot loops compiled as viper.
"""


def unit_files(unit: str, root: Path = DEVICE_PACKAGE) -> list[str]:
    """A unit's files relative to the package, posix, sorted (the CircuitPython driver included:
    mip and deploy copy it to CircuitPython boards; a MicroPython firmware's manifest leaves it)."""
    return [p.as_posix() for p in package_sources(True, root, (unit,))]


def unit_package(unit: str, version: str, root: Path = DEVICE_PACKAGE) -> dict:
    """device/UNIT.json: mip's package of one unit, its urls relative to the file itself (mip
    and mpremote resolve a relative url against the package.json's own folder)."""
    return {"urls": [[f"acal/{f}", f"acal/{f}"] for f in unit_files(unit, root)], "deps": [],
            "version": version}


def unit_manifest(unit: str, root: Path = DEVICE_PACKAGE, base: str = "../..",
                  head: str = MANIFEST_HEAD) -> str:
    """A unit's manifest.py as micropython-lib writes one: the units it needs include()d (core,
    for every other unit), then package("acal", files=[...]) of its own files, from base (the
    folder holding acal/, relative to the manifest)."""
    files = [f for f in unit_files(unit, root)
             if module_name(Path(f)).rpartition(".")[2] not in CIRCUITPYTHON_ONLY]
    needs = "" if unit == DEVICE_UNITS[0] else f'include("../{DEVICE_UNITS[0]}")\n'
    listed = "".join(f"        {f!r},\n" for f in files).replace("'", '"')
    return (head.format(unit=unit) + needs +
            f'package(\n    "acal",\n    files=[\n{listed}    ],\n    base_path="{base}",\n)\n')


# Board-side helpers (MicroPython and CircuitPython alike: os.listdir and os.stat, no ilistdir).
# Any error is raised, so mpremote exits non-zero and deploy reports it.
BOARD_FS = """import os
def _isdir(p):
    return os.stat(p)[0] & 0x4000
def _exists(p):
    try:
        os.stat(p)
        return True
    except OSError:
        return False
def _rm(p):
    if _isdir(p):
        for n in os.listdir(p):
            _rm(p + '/' + n)
        os.rmdir(p)
    else:
        os.remove(p)
def _walk(p, pre=''):
    out = []
    for n in os.listdir(p):
        q = p + '/' + n
        out += _walk(q, pre + n + '/') if _isdir(q) else [pre + n]
    return out
"""


def stage_code(folders: list[str]) -> str:
    """Board code: an empty staging folder (a killed deploy's leftovers removed) with the
    package's subfolders."""
    dirs = ["lib", STAGE, *(f"{STAGE}/{d}" for d in folders)]
    return (BOARD_FS + f"if _exists({STAGE!r}):\n    _rm({STAGE!r})\n"
            f"for d in {dirs!r}:\n    if not _exists(d):\n        os.mkdir(d)\n")


def swap_code() -> str:
    """Board code: the deployed package (lib/acal, and an `acal` at the top of the filesystem,
    which would shadow lib/) removed, the staged one renamed into its place; prints every file
    it removed (ACAL_OLD path) and every file now there (ACAL_NEW path)."""
    return (BOARD_FS +
            "for old in ('acal', " + repr(TARGET) + "):\n"
            "    if _exists(old):\n"
            "        for f in (_walk(old) if _isdir(old) else ['']):\n"
            "            print('ACAL_OLD', (old + '/' + f).rstrip('/'))\n"
            "        _rm(old)\n"
            f"os.rename({STAGE!r}, {TARGET!r})\n"
            f"for f in _walk({TARGET!r}):\n"
            "    print('ACAL_NEW', f)\n")


def swap_report(out: str, deployed: list[str]) -> list[str]:
    """From swap_code()'s output: the files removed that the new package does not have (stale
    ones: an orphan module, a .py beside the new .mpy, a shadowing /acal), checked that the
    board holds exactly the deployed files."""
    old = [line.split(None, 1)[1] for line in out.splitlines() if line.startswith("ACAL_OLD ")]
    new = sorted(line.split(None, 1)[1] for line in out.splitlines() if line.startswith("ACAL_NEW "))
    if new != sorted(deployed):
        from accelcal.errors import InputError
        missing = sorted(set(deployed) - set(new))
        extra = sorted(set(new) - set(deployed))
        raise InputError(f"after the copy, {TARGET} does not hold exactly the package: missing "
                         f"{' '.join(missing) or 'nothing'}, extra {' '.join(extra) or 'nothing'}")
    kept = {f"{TARGET}/{f}" for f in deployed}
    return [f for f in old if f not in kept]
