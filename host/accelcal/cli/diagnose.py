"""Finding the model: `diagnose` (where it fails, which effect is missing), `report` (its steps,
a board's calibrations) and `compare` (every method on the same data)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from accelcal.bridge.runtime import RUNTIMES
from accelcal.cli.options import COMMANDS, add_effects_arg, add_pipeline_args, pipeline_config, register_effects
from accelcal.files.outputs import FORCE_HELP, check_figure_name, check_output
from accelcal.files.readers import RULE


def cmd_diagnose(args) -> int:
    from accelcal.pipeline.diagnose import diagnose
    register_effects(args)
    out = diagnose(args.input, args.model, args.plots, history=args.history, report=args.report,
                   force=args.force, effects=args.effects)
    print(out.to_json() if args.json else out.report())
    return 0


def cmd_report(args) -> int:
    reads = [args.history]
    if Path(args.history).is_dir():   # a pulled folder: every file of the pull is read
        from accelcal.bridge.boardlog import LOG_FILES
        reads += [Path(args.history) / f for f in (*LOG_FILES, "summary.json")]
    if args.plot:   # a figure, regenerated from what it reads: replaced if it exists
        check_output(args.plot, reads, True, "--plot")
        check_figure_name(args.plot, "--plot")
    if args.html:
        check_output(args.html, [*reads, args.plot], args.force, "--html")
    if Path(args.history).is_dir():
        from accelcal.board.report import board_report
        out = board_report(pulled_dir=args.history, html=args.html, force=args.force)
    else:
        from accelcal.pipeline.history import history_report
        out = history_report(history=args.history, plot=args.plot, html=args.html,
                             force=args.force)
    print(out.to_json() if args.json else out.table())
    if out.get("plot"):
        say(f"plot: {out['plot']}")
    if out["report"]:
        say(f"report: {out['report']}")
    return 0


def cmd_compare(args) -> int:
    from accelcal.bridge.runtime import check
    from accelcal.pipeline.compare import compare
    register_effects(args)
    check(args.runtime)
    # progress for a person watching (a terminal); errors stay one line for scripts
    quiet = args.json or not sys.stderr.isatty()
    out = compare(args.input, methods=args.methods, model=args.model, train=args.train,
                  cfg=pipeline_config(args), runtime=args.runtime,
                  plots=args.plots, split=args.split, progress=None if quiet else say)
    if args.json:
        print(out.to_json())
    else:
        print(out.table())
        if args.plots:
            print(f"\nplot: {out['plots'][0]}")
    return 0 if out.any_calibrated else 2


def say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def add_parsers(sub) -> None:
    from accelcal.methods import METHODS
    from accelcal.pipeline.restpoints import SPLIT_RULES
    p = sub.add_parser("diagnose", help=COMMANDS["diagnose"][1],
                       description="Fits the model on even 2-hour blocks of the rest points and "
                                   "measures on the odd ones: held-out calibration error beside the "
                                   "noise floor, residuals against time, temperature, each axis and "
                                   "|a|, and for every catalogue effect not in the model the held-out "
                                   "error with it added; names the missing effect, or none.",
                       epilog=RULE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="recording CSV (t,x,y,z[,temp][,NAME...]: further columns such "
                                 "as supply_mv are regressors too) or points file")
    p.add_argument("--model", default="base", help="model spec: base, base+temp_offset, ... (default base)")
    add_effects_arg(p)
    p.add_argument("--report", metavar="DIR",
                   help="write DIR/report.html: one self-contained file (figures inside, no "
                        "network needed) with the held-out table, the candidates, the named "
                        "effect's physics, the steps so far (with --history) and the commands to "
                        "run next; its numbers are --json's (embedded in it)")
    p.add_argument("--force", action="store_true", help=FORCE_HELP + ": DIR/report.html")
    p.add_argument("--plots", metavar="DIR", help="write residuals.png and candidates.png here "
                   "(the folder is made if missing; figures in it are replaced)")
    p.add_argument("--history", metavar="FILE", help="append this step (model, held-out error) to FILE "
                                                     "for `accelcal report`")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("report", help=COMMANDS["report"][1],
                       description="A table of each model step with its held-out error and noise floor, "
                                   "and with --plot a PNG of the error per step.")
    p.add_argument("history", help="file written by diagnose --history, or a folder `pull` "
                                   "wrote (a board's logs)")
    p.add_argument("--plot", metavar="PNG", help="the steps as a figure (replaced if it exists)")
    p.add_argument("--html", metavar="FILE",
                   help="one self-contained HTML file (figures inside; opens from disk with no "
                        "network): the steps, or the board's calibrations over time")
    p.add_argument("--force", action="store_true", help=FORCE_HELP + ": --html")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("compare", help=COMMANDS["compare"][1],
                       description="Rest points (the device's detector) split into training and "
                                   "held-out parts (recordings: 2-hour blocks, even/odd; points "
                                   "files without t: alternate points; --split: the halves of "
                                   "the time span).  The device's bins and "
                                   "optimiser run on the training part; every float method is "
                                   "fitted on the points the bins selected (--train all: on every "
                                   "training point).  All are scored on the held-out part: mean "
                                   "| |a| - 1 g | in mg before and after, R (Farago eq. 21), fit "
                                   "time measured in this run.  A method that cannot fit shows "
                                   "its reason; the others still run.",
                       epilog=RULE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="recording CSV (t,x,y,z[,temp][,NAME...]: further columns such "
                                 "as supply_mv are regressors too) or points file")
    p.add_argument("--methods", metavar="M1,M2,...",
                   help="default all: device," + ",".join(METHODS))
    p.add_argument("--train", choices=["selected", "thinned", "all"], default="selected",
                   help="what the float methods are fitted on: the device bins' selection (default, "
                        "as Farago Table 3; thinned when the bins do not fill), the training points "
                        "thinned to at most 10 per direction (Gietzelt 2.4), or all of them (de "
                        "then costs O(points) per generation: minutes on days of data)")
    p.add_argument("--split", choices=SPLIT_RULES, default="blocks",
                   help="how the rest points are split: blocks (default: alternate 2-hour blocks, "
                        "even train, odd held out; points files without t: alternate points), "
                        "first-half (cut at the middle of their time span: the first half trains, "
                        "the second is held out) or second-half (the reverse)")
    p.add_argument("--runtime", choices=RUNTIMES, default="cpython",
                   help="interpreter for the device method")
    p.add_argument("--plots", metavar="DIR",
                   help="write training_curve.png: held-out error against the number of training "
                        "vectors per method (Gietzelt figure 3)")
    p.add_argument("--model", default="base",
                   help="also fit this composed model (base+EFFECT...: the catalogue's or yours, "
                        "--effects) by the device pipeline and by lsq on the same training points, "
                        "scored on the same held-out points: two more rows")
    add_effects_arg(p)
    p.add_argument("--json", action="store_true")
    add_pipeline_args(p)
    p.set_defaults(func=cmd_compare)

