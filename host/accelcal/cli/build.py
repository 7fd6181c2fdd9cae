"""`make build` (`python -m accelcal.cli.build [OUT]`): the device package built once per board
with an `.mpy` architecture, for the two install routes beside `deploy` that give the same
running code:

* mip: OUT/BOARD/package.json lists the prebuilt `.mpy` (viper where the arch has it), the board
  file, a `main.py` and the settings file, at the paths `deploy` puts them (`:lib/acal/...`,
  `:acal_board.py`, `:main.py`, `:acal_settings.json`): `mpremote mip install --target /
  OUT/BOARD/package.json`.  The settings are deploy's defaults (`accelcal deploy --port P`).
* freeze: OUT/BOARD/freeze/manifest.py with the sources as the arch compiles them
  (rp2040.emitted_source: the marked hot loops as viper), one manifest per install unit
  (freeze/manifests/UNIT, include()d for the units the board's default settings run) and the
  board file, for a custom firmware (`make BOARD=RPI_PICO FROZEN_MANIFEST=.../manifest.py` in MicroPython's ports/rp2).

CircuitPython has no mip: given a CircuitPython board, its `.mpy` tree is OUT/BOARD/lib/acal like
the others (by default `make build` makes build/circuitpython/acal with CP_MPY_CROSS)."""
from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

from accelcal.board import deploy, settings as bsettings, tree
from accelcal.bridge import rp2040
from accelcal.locations import DEVICE_PACKAGE, DEVICE_UNITS

MANIFEST = """# Written by `make build` (accelcal.cli.build): acal's install units and the {board} board
# file, frozen into a MicroPython firmware for {arch}.  Build it from MicroPython's ports/rp2 (or
# esp32):  make BOARD=... FROZEN_MANIFEST={path}
# Only the units the board runs: core and logger on every board; uncomment paper for the paper
# profile, discover for --discover (each unit's manifest is in manifests/UNIT).
# main.py stays on the board's filesystem (mpremote fs cp {main} :main.py).
include("$(PORT_DIR)/boards/manifest.py")
{units}module("acal_board.py")
"""
UNIT_HEAD = """# The install unit `{unit}` of acal as `make build` compiled it for this board (the hot loops
# as viper); include() it from the board's manifest.  Written from the walk deploy copies.
"""


def freeze_units(fz: Path, arch: str, units: tuple[str, ...]) -> str:
    """fz/acal (the arch's sources) and fz/manifests/UNIT/manifest.py for every unit; the
    include() lines of the board's manifest: the given units, the others commented out."""
    for rel in tree.package_sources(False):
        dst = fz / "acal" / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_text(rp2040.emitted_source((DEVICE_PACKAGE / rel).read_text(), arch))
    lines = ""
    for unit in DEVICE_UNITS:
        m = fz / "manifests" / unit / "manifest.py"
        m.parent.mkdir(parents=True)
        m.write_text(tree.unit_manifest(unit, head=UNIT_HEAD))
        lines += ("" if unit in units else "# ") + f'include("manifests/{unit}")\n'
    return lines


def default_settings() -> tuple[dict, dict]:
    """deploy's app options and acal.logger.app.main's arguments when none is given."""
    from accelcal.cli import build_parser
    from accelcal.cli.board import _app_options, _app_settings
    args = build_parser().parse_args(["deploy", "--port", "-"])
    return _app_options(args), _app_settings(args)


def build_board(board: str, out: Path, info: dict | None = None) -> dict:
    """OUT/BOARD made anew: lib/acal (the `.mpy`), acal_board.py, main.py, acal_settings.json,
    package.json (MicroPython boards) and freeze/ (boards with an arch).  info: the board's
    (deploy.board_info; another ARCH for a test)."""
    info = info or deploy.board_info(board)
    d = out / board
    if d.exists():
        shutil.rmtree(d)
    d.mkdir(parents=True)
    cp = info["RUNTIME"] == "circuitpython"
    files, what = deploy.package_files(info, tree.package_sources(cp), d / "lib" / "acal")
    options, app = default_settings()
    others = deploy.board_files(info, app, True, d)
    for local, remote in others:      # board_files writes main.py into d; the board file copied
        if Path(local).parent != d:
            shutil.copy(local, d / remote)
    (d / bsettings.SETTINGS_FILE).write_text(
        bsettings.settings_text(options, app, board, "mpy" if what.startswith(".mpy") else "py"))
    rels = [f.relative_to(d).as_posix() for f in files]
    rels += [remote for _, remote in others] + [bsettings.SETTINGS_FILE]
    made = {"board": board, "what": what, "files": len(rels)}
    if not cp:
        pkg = {"urls": [[r, r] for r in rels], "version": str(deploy_version())}
        (d / "package.json").write_text(json.dumps(pkg, indent=1) + "\n")
        made["package_json"] = str(d / "package.json")
    if info["ARCH"]:
        fz = d / "freeze"
        units = freeze_units(fz, info["ARCH"], deploy.units_run(app))
        shutil.copy(info["path"], fz / "acal_board.py")
        (fz / "manifest.py").write_text(MANIFEST.format(board=board, arch=info["ARCH"], units=units,
                                                        path=fz / "manifest.py", main=d / "main.py"))
        made["manifest"] = str(fz / "manifest.py")
    return made


def deploy_version() -> str:
    import acal
    return acal.__version__


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0] if argv else "build")
    # CircuitPython's tree: the Makefile, with its own mpy-cross (CP_MPY_CROSS)
    boards = argv[1:] or [b for b in deploy.boards() if deploy.board_info(b)["ARCH"]]
    from accelcal.errors import InputError
    try:
        for b in boards:
            m = build_board(b, out)
            print(f"{out / b}: {m['files']} files ({m['what']})"
                  + (f"; mip: {m['package_json']}" if "package_json" in m else "")
                  + (f"; freeze: {m['manifest']}" if "manifest" in m else ""))
    except InputError as e:
        print(f"build: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
