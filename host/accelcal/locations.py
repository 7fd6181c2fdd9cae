"""Where the files the host hands to MicroPython live, in a checkout and in an installed wheel alike:
the device package `acal` (deployed to boards, put on MICROPYPATH), the board files, the scripts run
inside MicroPython (bridge/scripts) and the simulated chip (simulate/chip).  All are found through
the import system, never by walking up from this file, so an installed `accelcal` works anywhere."""
from __future__ import annotations

from importlib import resources
from pathlib import Path

import acal

DEVICE_PACKAGE = Path(acal.__file__).resolve().parent      # .../acal: what `deploy` copies
DEVICE_PATH = DEVICE_PACKAGE.parent                         # on MICROPYPATH, so `import acal` works
SCRIPTS_DIR = Path(str(resources.files("accelcal.bridge.scripts")))
CHIP_DIR = Path(str(resources.files("accelcal.simulate.chip")))
# The device package's features, each a folder and an install unit (docs/method-and-formats.md
# "The device package"): core and logger on every board, paper and discover where they run.
DEVICE_UNITS = ("core", "logger", "paper", "discover")


# Modules only CircuitPython boards get (by module name, relative to acal).
CIRCUITPYTHON_ONLY = ("lis3dh_cp",)


def module_name(rel: Path) -> str:
    """acal's module for a file of the package: core/fixed.py -> core.fixed, core/__init__.py ->
    core, __init__.py -> '' (the package itself)."""
    parts = list(rel.with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def unit_of(rel: Path) -> str:
    """The install unit a file of the package belongs to: its feature folder; the package's own
    __init__.py goes with core, which every board has."""
    return rel.parts[0] if len(rel.parts) > 1 else DEVICE_UNITS[0]


def package_sources(circuitpython: bool = True, root: Path = DEVICE_PACKAGE,
                    units: tuple[str, ...] | None = None) -> list[Path]:
    """The one walk of the device package (deploy, make build, the mip and freeze units, the
    interpreters' copies): its sources relative to root, sorted, the whole tree (never a flat list
    of names, whatever subfolders it has), without caches, only the given units' files (all by
    default) and, unless circuitpython, without the CircuitPython driver."""
    out = []
    for p in sorted(root.rglob("*.py")):
        rel = p.relative_to(root)
        if "__pycache__" in rel.parts or (units is not None and unit_of(rel) not in units):
            continue
        if module_name(rel).rpartition(".")[2] in CIRCUITPYTHON_ONLY and not circuitpython:
            continue
        out.append(rel)
    return out


def device_modules(units: tuple[str, ...] | None = None) -> list[str]:
    """package_sources as posix strings ("__init__.py", "core/bins.py" ...), every driver
    included: the files the host's interpreters and the emulated chips load."""
    return [p.as_posix() for p in package_sources(True, units=units)]


def checkout() -> Path | None:
    """The source checkout this package runs from (it holds .venv-mpy and build/mp32 after
    `make setup`), or None when installed from a wheel."""
    root = DEVICE_PATH.parent
    return root if (root / "pyproject.toml").exists() and (root / "host").is_dir() else None


def _boards_dir() -> Path:
    """A wheel packs boards/ as accelcal/boards; a checkout (also an editable install) has it at
    its root."""
    packed = Path(str(resources.files("accelcal"))) / "boards"
    if packed.is_dir():
        return packed
    root = checkout()
    if root is None:
        raise RuntimeError("accelcal is installed without its board files")
    return root / "boards"


BOARDS_DIR = _boards_dir()


def script(name: str) -> str:
    """A MicroPython-side script (bridge/scripts/NAME) as a path an interpreter can run."""
    return str(SCRIPTS_DIR / name)
