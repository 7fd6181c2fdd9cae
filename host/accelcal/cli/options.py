"""What every command group shares: the parser whose errors are one line, option types with
bounds (every numeric option has one; NaN and infinities are refused), and the device pipeline's
options with the Config they make."""
from __future__ import annotations

import argparse
import math
from dataclasses import replace

from accelcal.errors import InputError, one_line
from accelcal.files.arguments import AXES, CHOICES, FLOATS, INTS, outside_float, outside_int


class Parser(argparse.ArgumentParser):
    """An option error is one line (and exit 2) like every other bad input, with the command's
    --help named for the details.  A long option is taken only as spelled in full: argparse's
    prefix matching (allow_abbrev) is off here and in every subcommand's parser (add_parser
    makes them of this class), so `--effect` is an unknown option, never `--effects`."""

    def __init__(self, *args, **kwargs):
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)

    def error(self, message):
        self.exit(2, f"accelcal: error: {one_line(message)} (see `{self.prog} --help`)\n")

    def parse_args(self, args=None, namespace=None):
        """As argparse's, but an unknown option is named beside the nearest the command has
        (`--effect`: did you mean --effects?) and the command's own --help."""
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self._chosen(ns)
            known = [o for a in parser._actions for o in a.option_strings if o.startswith("--")]
            import difflib
            near = [m for e in extras if e.startswith("-")
                    for m in difflib.get_close_matches(e.split("=")[0], known, 1, 0.75)]
            parser.error(f"unrecognized arguments: {' '.join(extras)}"
                         + (f"; did you mean {' or '.join(dict.fromkeys(near))}?" if near else ""))
        return ns

    def _chosen(self, ns) -> "Parser":
        """The (sub)command's parser the parsed namespace ns went through, deepest first."""
        for a in self._actions:
            if isinstance(a, argparse._SubParsersAction):
                name = getattr(ns, a.dest, None)
                if name in a.choices:
                    return a.choices[name]._chosen(ns)
        return self


# Every command, in `accelcal --help`'s order: name -> (the module of accelcal.cli that builds its
# parser and runs it, its one-line help).  `accelcal --help` is made from this table alone, and a
# command imports only its own module (cli/__init__.py): the help without numpy or the device code.
COMMANDS = {
    "calibrate": ("calibrate", "calibrate a recording or points file"),
    "apply": ("calibrate", "calibrate a recording with saved parameters"),
    "simulate": ("simulate", "simulate data with known truth"),
    "board": ("board", "boards: the virtual board"),
    "deploy": ("board", "copy the device package and a board file to a board"),
    "acquire": ("board", "run the deployed app for a while (virtual board: simulated time)"),
    "pull": ("board", "copy a board's logs off and decode them"),
    "replay": ("board", "re-run a pulled capture through the current device modules"),
    "diagnose": ("diagnose", "where the model fails, and which effect is missing"),
    "report": ("diagnose", "the model steps of a diagnose --history file"),
    "compare": ("diagnose", "every calibration method on the same data, one table"),
    "paper": ("studies", "reproduce the paper's results"),
    "bench": ("studies", "timings and allocations under MicroPython and CPython"),
}


# points per subset the fits take (bridge.protocol.MAX_PER_SUBSET, derived there from the
# device's bounds; written here so that building the parser imports neither numpy nor acal)
MAX_PER_SUBSET = 14


def int_in(lo, hi):
    """An int option within [lo, hi] (every numeric option has an upper bound)."""
    def parse(s):
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{s!r} is not a whole number") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(outside_int(v, lo, hi))
        return v
    parse.__name__ = "int"
    return parse


def float_in(lo, hi, lo_open=False):
    """A finite float option within [lo, hi] ((lo, hi] with lo_open)."""
    def parse(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{s!r} is not a number") from None
        if not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo):
            raise argparse.ArgumentTypeError(outside_float(s, lo, hi, lo_open))
        return v
    parse.__name__ = "float"
    return parse


positive_int = int_in(1, 10 ** 6)


def dask_address(s):
    """A scheduler address: [scheme://]host:port, the port a number."""
    import re
    m = re.fullmatch(r"(?:(tcp|tls|ws|wss|inproc|ucx)://)?(\[[0-9a-fA-F:]+\]|[A-Za-z0-9_.-]+):(\d{1,5})",
                     s)
    if not m or not 0 < int(m.group(3)) < 65536:
        raise argparse.ArgumentTypeError(f"{s!r} is not a scheduler address such as "
                                         "tcp://10.0.0.5:8786")
    return s


def rates(s):
    try:
        vals = [float(v) for v in s.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError("three numbers, e.g. 0.3,0.8,0.2") from None
    if not all(math.isfinite(v) and 0 <= v <= 100 for v in vals):
        raise argparse.ArgumentTypeError("three rates in [0, 100], e.g. 0.3,0.8,0.2")
    tenths = [round(v * 10) for v in vals]
    if len(vals) != 3 or any(abs(v * 10 - t) > 1e-9 or t < 0 for v, t in zip(vals, tenths)):
        raise argparse.ArgumentTypeError("three non-negative multiples of 0.1, e.g. 0.3,0.8,0.2")
    return tuple(tenths)


def threshold(s):
    if s == "auto":
        return "auto"
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError("a number of g (e.g. 0.05) or auto") from None
    lo, hi, lo_open = FLOATS["threshold"]
    if not (math.isfinite(v) and lo < v <= hi):
        raise argparse.ArgumentTypeError(outside_float(s, lo, hi, lo_open) + " g, or auto")
    return v




def add_pipeline_args(p):
    g = p.add_argument_group("device pipeline",
                             "--profile sets every default below; an option given overrides it.")
    g.add_argument("--profile", choices=CHOICES["profile"], default="wear",
                   help="wear (default): rest on all axes against a threshold from the sensor's "
                        "measured noise, 8 points per subset (14 for a composed model), a "
                        "Gauss-Newton fit to the optimum "
                        "with outlier rejection, ready on coverage; paper: Farago 2024 to the "
                        "letter (x axis, 0.12 g, 2 points per subset, 50 gradient steps)")
    g.add_argument("--seconds", type=int_in(*INTS["seconds"]), default=5, help="rest segment length, s (default 5)")
    g.add_argument("--threshold", type=threshold, default=None,
                   help="max-min rest threshold, g, or auto (from the measured noise); "
                        "default: wear auto, paper 0.12")
    g.add_argument("--axis", choices=CHOICES["axis"], default=None,
                   help="axis for the rest test, or all; default: wear all, paper x")
    g.add_argument("--min-count", type=int_in(1, MAX_PER_SUBSET), default=None,
                   help="points per subset to calibrate (default 2)")
    g.add_argument("--max-count", type=int_in(1, MAX_PER_SUBSET), default=None,
                   help="points kept per subset (default: wear 8, 14 for a composed model; paper "
                        f"2, 4 for a composed model); at most {MAX_PER_SUBSET}: both fits take at "
                        "most 128 points, the count their integer sums are proven for")
    g.add_argument("--differ", type=float_in(*FLOATS["differ"][:2]), default=0.1,
                   help="a new rest mean must differ by this much (max-norm, g) from held points (default 0.1)")
    g.add_argument("--select", choices=CHOICES["select"], default="centre",
                   help="point selection once a subset is full: centre (replace by better-placed points) "
                        "or first (first come, as printed in the paper)")
    g.add_argument("--iterations", type=int_in(*INTS["iterations"]), default=None,
                   help="optimiser iterations (default: wear up to 20 Gauss-Newton steps per "
                        "round; paper 50, 200 for a composed model)")
    g.add_argument("--rates", type=rates, default=(3, 8, 2), metavar="S,M,O",
                   help="paper profile: learning rates for scale, misalignment, offset, multiples "
                        "of 0.1 (default 0.3,0.8,0.2, the paper's)")


def pipeline_config(args, composed=False):
    from accelcal.bridge.runtime import Config
    thr = None if args.threshold in (None, "auto") else args.threshold
    cfg = Config.for_profile(args.profile, composed, threshold_g=thr,
                             axis=None if args.axis is None else AXES[args.axis],
                             min_count=args.min_count, max_count=args.max_count,
                             iterations=args.iterations)
    cfg = replace(cfg, seconds=args.seconds, differ_g=args.differ, policy=args.select,
                  rates_tenths=args.rates)
    if args.threshold == "auto":
        cfg = replace(cfg, threshold_g=None)
    if cfg.max_count < cfg.min_count:
        raise InputError("--max-count must be >= --min-count")
    return cfg


EFFECTS_HELP = ("a Python file declaring effects of your own (EFFECTS = [dict(name=..., regressor="
                "'temperature'|'time'|'reading'|'column:NAME', power=..., form='offset'|'gain', unit=..., "
                "bound=..., explanation=...)]): they join the catalogue for this command "
                "(docs/model-discovery.md \"Effects you declare\").  The file is run as Python "
                "code, first, before any output is touched: name only a file you trust, as you "
                "would a config file.  At most 64 effects; anything it raises or exits with is "
                "one line, exit 2")


def add_effects_arg(p) -> None:
    p.add_argument("--effects", metavar="FILE.py", help=EFFECTS_HELP)


def register_effects(args) -> None:
    """The user's declared effects into the catalogue, checked (one line, exit 2, if bad)."""
    if getattr(args, "effects", None):
        from accelcal.files.outputs import note_input
        from accelcal.model.declared import register
        note_input(args.effects)   # run as code, and never an output (--force or not)
        register(args.effects)
