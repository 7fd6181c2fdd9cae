"""python -m accelcal.studies.powercut [--cuts N] [--seed S]: power cuts on the emulated Pico's
littlefs (board/powercut.py) counted, one JSON object."""
from __future__ import annotations

import argparse
import json
import sys

from accelcal.board import powercut
from accelcal.bridge import rp2040
from accelcal.errors import InputError, one_line


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(allow_abbrev=False, prog="python -m accelcal.studies.powercut",
                                 description="Cut the emulated Pico's power at pseudo-random cycles "
                                 "while the app appends to its log and while it writes its "
                                 "calibration store; reboot from the flash and count what was "
                                 "lost, damaged or mixed (one JSON object).")
    ap.add_argument("--cuts", type=int, default=100, help="cuts of each workload (default 100)")
    ap.add_argument("--seed", type=int, default=1, help="where the cuts fall (default 1)")
    args = ap.parse_args(argv)
    if args.cuts < 1:
        ap.error("--cuts: at least 1")
    try:
        rp2040.emulator_index()
    except InputError as e:
        print(f"powercut: {one_line(e)}", file=sys.stderr)
        return 2
    print(json.dumps(powercut.run_cuts(args.cuts, args.seed)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
