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


def device_modules(units: tuple[str, ...] = DEVICE_UNITS) -> list[str]:
    """The device package's module files as paths relative to it ("__init__.py", "core/bins.py"
    ...), sorted: the package's own __init__.py and every module of the given units."""
    out = ["__init__.py"]
    for unit in units:
        out += sorted(p.relative_to(DEVICE_PACKAGE).as_posix()
                      for p in (DEVICE_PACKAGE / unit).glob("*.py"))
    return sorted(out)


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
