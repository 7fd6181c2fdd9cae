"""accelcal: accelerometer self-calibration (Farago 2024) on the device and beside it.

Every command has --help.  Errors: one line on stderr and exit status 2, never a traceback."""
from __future__ import annotations

import argparse
import sys

from accelcal.cli import board, calibrate, diagnose, simulate, studies
from accelcal.cli.options import Parser
from accelcal.errors import InputError, one_line

GROUPS = (calibrate, simulate, board, diagnose, studies)   # the order of `accelcal --help`


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog="accelcal", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    return ap


def main(argv=None) -> int:
    from accelcal.files.outputs import forget_inputs
    forget_inputs()
    if not sys.warnoptions:   # a library's warnings (numpy's on a damaged file) are not our lines
        import warnings
        warnings.simplefilter("ignore")
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except InputError as e:
        print(f"accelcal: error: {one_line(e)}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except OSError as e:   # the system refused a read or a write (disk full, permissions...)
        where = f"{e.filename}: " if e.filename else ""
        print(f"accelcal: error: {one_line(f'{where}{e.strerror or e}')}", file=sys.stderr)
        return 2
