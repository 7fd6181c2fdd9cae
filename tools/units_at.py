"""Each install unit's import time and free heap on the emulated Pico, an older revision's device
package and this checkout's in one run (issue 48's 5 % bars, "before and after in the same run").

    python tools/units_at.py [REV] [--cases base,discover,paper]    # REV: de6b2b0 by default

Each tree's package is installed on its own flash image (REV's from `git archive`, nothing
checked out) and host/accelcal/bridge/scripts/mp_units_bench.py, this checkout's, runs main(case)
on a fresh boot per tree and case, as `accelcal bench --runtime rp2040` does for its units_ rows.
The emulator's clock is the chip's cycles: a tree gives the same figures on every run.  Prints
one line a figure: `units_{case}_{figure} REV_value this_value change_percent`.
"""
import argparse
import io
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "host"), str(ROOT / "device")]

from accelcal.bridge import rp2040  # noqa: E402
from accelcal.locations import DEVICE_PACKAGE, script  # noqa: E402

FIGURES = ("import_app_us", "free_after_import_bytes", "free_with_processor_bytes", "modules")


def old_package(rev: str, into: Path) -> Path:
    """REV's device/acal extracted under into; SystemExit(2) with one line when REV is not a
    commit of this checkout or has no device package."""
    p = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "device/acal"],
                       capture_output=True)
    if p.returncode != 0:
        sys.exit(f"units_at: {rev!r} is not a revision of {ROOT} with device/acal: "
                 + (p.stderr.decode(errors="replace").strip().splitlines() or ["git failed"])[-1])
    with tarfile.open(fileobj=io.BytesIO(p.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into / "device" / "acal"


def units(image: Path, case: str) -> dict:
    """mp_units_bench.py main(case) on a fresh boot of image: its units_{case}_ figures."""
    code = Path(script("mp_units_bench.py")).read_text() + f"\nmain({case!r})\n"
    out = rp2040.run_script(code, image=image).out
    kv = dict(line.split()[:2] for line in out.splitlines() if line.startswith("units_"))
    return {k: int(kv[f"units_{case}_{k}"]) for k in FIGURES}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rev", nargs="?", default="de6b2b0")
    ap.add_argument("--cases", default="base,discover,paper",
                    help="mp_units_bench.py's cases, comma-separated (base, paper, discover, all)")
    a = ap.parse_args(argv)
    cases = a.cases.split(",")
    bad = [c for c in cases if c not in ("base", "paper", "discover", "all")]
    if bad:
        print(f"units_at: no case {bad[0]!r} (base, paper, discover, all)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        try:
            old = old_package(a.rev, Path(tmp))
        except SystemExit as e:
            print(e.code, file=sys.stderr)
            return 2
        images = {}
        # the older tree's first: flash_image keeps only its newest image, and this checkout's
        # is then the one left in build/rp2040 for the other runs
        for name, root in (("old", old), ("new", DEVICE_PACKAGE)):
            images[name] = Path(tmp) / f"{name}.bin"
            shutil.copyfile(rp2040.flash_image(rp2040.MICROPYTHON, root), images[name])
        for case in cases:
            before, after = units(images["old"], case), units(images["new"], case)
            for k in FIGURES:
                change = 100 * (after[k] - before[k]) / before[k]
                print(f"units_{case}_{k} {before[k]} {after[k]} {change:+.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
