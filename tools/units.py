"""The install units' files (issue 48 part 1): device/UNIT.json (mip), device/manifests/UNIT/
manifest.py (a firmware that freezes only the units its board runs) and the whole package's
package.json, all written from the one walk deploy copies (accelcal.locations.package_sources).

    python tools/units.py          # write them
    python tools/units.py --check  # exit 1 naming each file that differs (tests/board/test_units.py)
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "host"), str(ROOT / "device")]

import acal  # noqa: E402
from accelcal.board import tree  # noqa: E402
from accelcal.locations import DEVICE_UNITS, package_sources  # noqa: E402


def files() -> dict[Path, str]:
    """Every file this tool owns, path -> its text."""
    out = {}
    for unit in DEVICE_UNITS:
        pkg = tree.unit_package(unit, acal.__version__)
        out[ROOT / "device" / tree.UNIT_JSON.format(unit=unit)] = json.dumps(pkg, indent=2) + "\n"
        out[ROOT / "device" / tree.UNIT_MANIFEST.format(unit=unit)] = tree.unit_manifest(unit)
    whole = {"urls": [[f"acal/{p.as_posix()}", f"device/acal/{p.as_posix()}"]
                      for p in package_sources(True)], "deps": [], "version": acal.__version__}
    out[ROOT / "package.json"] = json.dumps(whole, indent=2) + "\n"
    return out


def main(argv: list[str]) -> int:
    stale = []
    for path, text in files().items():
        if "--check" in argv:
            if not path.exists() or path.read_text() != text:
                stale.append(path.relative_to(ROOT).as_posix())
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
    if stale:
        print("not as the package's walk gives it (run python tools/units.py): " + " ".join(stale))
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
