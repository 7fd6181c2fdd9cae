"""accelcal: accelerometer self-calibration (Farago 2024) on the device and beside it.

Every command has --help.  Errors: one line on stderr and exit status 2, never a traceback."""
from __future__ import annotations

import argparse
import importlib
import sys

from accelcal.cli.options import COMMANDS, Parser
from accelcal.errors import InputError, one_line

GROUPS = ("calibrate", "simulate", "board", "diagnose", "studies")   # modules of accelcal.cli


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command (command None), or of one command in full beside one-line
    entries for the others (COMMANDS: the same `accelcal --help`, made without importing the
    other commands' modules, numpy or the device code; "" for none in full)."""
    ap = Parser(prog="accelcal", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    full = set(GROUPS) if command is None else {COMMANDS[command][0]} if command in COMMANDS else set()
    built = set()
    for name, (group, help_) in COMMANDS.items():
        if group not in full:
            sub.add_parser(name, help=help_)
        elif group not in built:   # a group adds its commands, in COMMANDS' order
            importlib.import_module(f"accelcal.cli.{group}").add_parsers(sub)
            built.add(group)
    return ap


def _command(argv) -> str:
    """The command argv names (its first word not an option), or "" (help, none, unknown)."""
    for a in argv:
        if not a.startswith("-"):
            return a
    return ""


def main(argv=None) -> int:
    from accelcal.files.outputs import forget_inputs
    forget_inputs()
    if not sys.warnoptions:   # a library's warnings (numpy's on a damaged file) are not our lines
        import warnings
        warnings.simplefilter("ignore")
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = build_parser(_command(argv))
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
