"""The device package as a tree of files, on the host and on the board: which modules a board
gets (every `.py` under device/acal, in whatever subfolders it has, the CircuitPython driver only
on CircuitPython boards), and the board-side code that swaps the deployed package for a new one
so that exactly the new files remain (`deploy`)."""
from __future__ import annotations

from pathlib import Path

from accelcal.locations import DEVICE_PACKAGE

# Modules only CircuitPython boards get (by module name, relative to acal).
CIRCUITPYTHON_ONLY = ("lis3dh_cp",)
# Where deploy stages the new package before the swap, and where it ends up.
STAGE = "lib/.acal-new"
TARGET = "lib/acal"


def module_name(rel: Path) -> str:
    """acal's module for a file of the package: core/fixed.py -> core.fixed, core/__init__.py ->
    core, __init__.py -> '' (the package itself)."""
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_sources(circuitpython: bool, root: Path = DEVICE_PACKAGE) -> list[Path]:
    """The package's sources a board gets, relative to root, sorted: the whole tree (never a flat
    list of names), without caches and, unless circuitpython, without the CircuitPython driver."""
    out = []
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root)
        if "__pycache__" in rel.parts:
            continue
        leaf = module_name(rel).rpartition(".")[2]
        if leaf in CIRCUITPYTHON_ONLY and not circuitpython:
            continue
        out.append(rel)
    return out


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
