"""Commands that calibrate: `calibrate` (one input, or a batch) and `apply`."""
from __future__ import annotations

import argparse
import os
import sys

from accelcal.bridge.runtime import RUNTIMES
from accelcal.cli.options import (COMMANDS, add_effects_arg, add_pipeline_args, dask_address, int_in,
                                  pipeline_config, register_effects)
from accelcal.errors import InputError, one_line, printable
from accelcal.files.outputs import FORCE_HELP, check_output
from accelcal.files.readers import RULE


EPILOG_CAL = RULE + """

A recording goes through rest detection, bins and the optimiser, streamed in
constant memory; a points file (CSV with x,y,z and optional temp,t,device) through bins and the
optimiser.  The float reference methods (lsq, de, linauto, linminvar, campolo, merayo, minvol) are
fitted on the points the device's bins selected; `accelcal compare` runs them all side by side.

A recording's record carries its quality: hours, gaps, still windows kept and excluded (non-wear:
still on every axis and colder than skin or cooling; imputed: every axis constant; clipped: at
full scale), bins filled, temperature range, clipping share, calibration error before/after (mg),
and status: calibrated, not_enough_data or failed, with the reason.  Nothing is applied silently:
--fallback names the calibration a file gets instead.

Exit status: one input: 2 when it did not calibrate (reason on stderr and in the JSON) unless a
--fallback was used.  Several inputs (a batch): 0, with each file's status in the summary; 2 with
--strict when any file did not calibrate.  Bad options: 2.
"""


def cmd_calibrate(args) -> int:
    from accelcal.pipeline.job import Job, calibrate_by, calibrate_file
    register_effects(args)
    if args.points and args.method == "device":
        raise InputError("--points applies to the float methods (--method lsq, ...); the device "
                         "method fits the points its bins select")
    from accelcal.bridge.runtime import check
    check(args.runtime)
    if args.model is None and args.by:   # auto chooses per file, --by fits one model per device
        args.model = "base"
    cfg = pipeline_config(args, "+" in (args.model or ""))
    if args.discover:
        from dataclasses import replace
        cfg = replace(cfg, discover=True)
    job = Job.of(cfg=cfg, model=args.model,
                 method=args.method, runtime=args.runtime, engine=args.engine,
                 fallback=args.fallback, points=args.points or "bins", effects=args.effects)
    job.spec()   # bad options are bad input, before any file is read or written
    if args.save:
        check_output(args.save, [*args.input, args.fallback, args.effects], args.force, "--save")
    if len(args.input) > 1 or args.summary or args.jobs > 1 or args.dask:
        return _calibrate_batch(args, job)
    if args.by:
        recs = calibrate_by(args.input[0], args.by, job)
    else:
        bar = progress = None
        if not args.quiet and sys.stderr.isatty():   # tqdm imported only to be shown
            from tqdm import tqdm
            bar = tqdm(unit=" samples", unit_scale=True, file=sys.stderr, desc="reading")
            progress = lambda n: bar.update(n - bar.n)  # noqa: E731
        try:
            recs = [calibrate_file(args.input[0], job, progress)]
        finally:
            if bar is not None:
                bar.close()
    failed = [r for r in recs if not r.usable]
    for r in recs:   # a --by column's values come from the file: printable, as every echo
        print(r.to_json() if args.json else "\n".join(map(printable, r.report(args.by).split("\n"))))
    for r in failed:
        who = f"{args.by} {r[args.by]}: " if args.by else ""
        print(f"accelcal: {one_line(who + str(r['reason']))}", file=sys.stderr)
    if args.save:
        from accelcal.files.params import save_params
        ok = [r for r in recs if r.ok]
        if ok:
            save_params(args.save, ok[0] if not args.by else {"by": args.by, "devices": ok})
    return 2 if failed else 0


def _calibrate_batch(args, job) -> int:
    from accelcal.pipeline import batch
    from accelcal.pipeline.results import save_summary, summary_table
    if args.by:
        raise InputError("--by applies to one points file, not to a batch")
    summary = args.summary or "accelcal-summary.csv"
    check_output(summary, [*args.input, args.fallback, args.save, args.effects], args.force,
                 "--summary")
    from tqdm import tqdm
    bar = tqdm(total=len(args.input), unit="file", file=sys.stderr, disable=args.quiet,
               dynamic_ncols=True,
               bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} files [{elapsed}<{remaining}]{postfix}")

    def done(rec):
        bar.set_postfix_str(f"{os.path.basename(rec['file'])}: {rec['status']}", refresh=False)
        bar.update(1)
    try:
        if args.dask:
            recs = batch.run_dask(args.input, job, args.dask, done)
        else:
            recs = batch.run_local(args.input, job, args.jobs, done)
    finally:
        bar.close()
    save_summary(summary, recs)
    if args.json:
        for r in recs:
            print(r.to_json())
    else:
        print(summary_table(recs))
    print(f"summary: {summary}", file=sys.stderr)
    if args.save:
        from accelcal.files.params import save_params
        ok = [r for r in recs if r.ok]
        if ok:
            save_params(args.save, {"by": "file", "devices": ok})
    bad = [r for r in recs if not r.ok]
    return 2 if args.strict and bad else 0


def cmd_apply(args) -> int:
    from accelcal.pipeline.apply import apply
    register_effects(args)
    out = apply(args.params, args.input, args.output, device=args.device, range_g=args.range,
                force=args.force, effects=args.effects)
    print(out.report(), file=sys.stderr)
    return 0


def add_parsers(sub) -> None:
    p = sub.add_parser("calibrate", help=COMMANDS["calibrate"][1],
                       description="Run the device pipeline (or a reference method on the points "
                                   "it selects) and report parameters and calibration error.",
                       epilog=EPILOG_CAL, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", nargs="+", metavar="INPUT",
                   help="recording (CSV t,x,y,z[,temp][,NAME...]; Axivity .cwa, GENEActiv .bin, ActiGraph "
                        ".gt3x) or points CSV; several make a batch")
    p.add_argument("--model", default=None,
                   help="model spec: auto (default, --method device: base+temp_offset where the "
                        "data has temperature and that fit calibrates, else base), base (the paper's "
                        "9; default of float methods, --by, --discover) or base+EFFECT[+EFFECT...] "
                        "(temp_offset, temp_scale, drift, nonlinear: --method device or lsq; "
                        "temp_offset2, step and --effects ones: --method lsq --points all). "
                        "A composed device fit keeps points spread in temperature (>= 3 degC) and time "
                        "(>= 12 h): wear profile 14 per subset, the base fit first and kept if the "
                        "composed one fails or is worse; paper profile 4 per subset, 200 iterations")
    add_effects_arg(p)
    from accelcal.methods import METHODS
    p.add_argument("--method", choices=["device", *METHODS], default="device",
                   help="device: the integer optimiser (default); the float reference methods, "
                        "fitted on the points the device's bins selected (or --points all): "
                        + "; ".join(f"{n}: {m.role}" for n, m in METHODS.items()))
    p.add_argument("--points", choices=["bins", "all"], default=None,
                   help="float methods: fit the points the device's bins selected and its fit "
                        "kept (bins, the default), or every usable rest point (all: |v| within "
                        "0.5-1.5 g; the bins need not fill).  The same for the paper's model and "
                        "composed ones; the record says which (points_from)")
    p.add_argument("--runtime", choices=RUNTIMES, default="cpython",
                   help="interpreter that runs the device modules: micropython, the real unix port "
                        "(64-bit); micropython32, the 32-bit MicroPython (WebAssembly under Node, "
                        "ints past 2^30 allocate as on an RP2040); rp2040, MicroPython's own "
                        "Pico firmware on the emulated RP2040 (rp2040js), the package as .mpy; "
                        "rp2040-romfs, the same with a ROMFS partition, the package run from /rom; "
                        "rv32, an ESP32-C3-class RISC-V MicroPython under qemu, rv32imc .mpy")
    p.add_argument("--engine", choices=["vector", "device"], default=None,
                   help="recordings: vector (default under cpython) finds rest segments with the "
                        "numpy twin of the device's detector, bit-exact with it, and offers them "
                        "to the device's bins; device (default under micropython) feeds every "
                        "sample through the device modules, for regression testing device code")
    p.add_argument("--discover", action="store_true",
                   help="the board's own model discovery (model base, --method device, wear "
                        "profile): after the base fit, each catalogue effect the device runs is "
                        "fitted and scored on held-out 2-hour blocks in integers, and adopted by "
                        "diagnose's rule; prints the effect named and the held-out error after "
                        "(docs/model-discovery.md \"Discovery on the board\")")
    p.add_argument("--by", metavar="COLUMN", help="calibrate each value of COLUMN (e.g. device) separately")
    p.add_argument("--save", metavar="PARAMS.json", help="save the parameters (with --by: all devices)")
    p.add_argument("--force", action="store_true", help=FORCE_HELP + ": --save, --summary")
    p.add_argument("--json", action="store_true", help="one JSON object per group (or file) on stdout")
    p.add_argument("--fallback", metavar="PARAMS.json",
                   help="a device's last good calibration (from --save): a file that does not "
                        "calibrate reports it with calibration \"fallback\" and its error, never "
                        "silently")
    g = p.add_argument_group("batches (several INPUTs)")
    g.add_argument("--jobs", type=int_in(1, 256), default=1, metavar="N",
                   help="files calibrated at once in a process pool (default 1)")
    g.add_argument("--dask", metavar="ADDRESS", type=dask_address,
                   help="run the batch on an existing Dask cluster (scheduler address, e.g. "
                        "tcp://10.0.0.5:8786); its workers need accelcal and the files.  Name "
                        "only a scheduler you trust: Dask exchanges pickles, so the scheduler "
                        "and its workers can run any code on this machine and read what is sent")
    g.add_argument("--summary", metavar="CSV",
                   help="the summary table, one row per file (default accelcal-summary.csv)")
    g.add_argument("--strict", action="store_true",
                   help="exit 2 when any file did not calibrate (default: 0; the status is in "
                        "the summary)")
    g.add_argument("--quiet", action="store_true", help="no progress bar")
    add_pipeline_args(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("apply", help=COMMANDS["apply"][1],
                       description="Apply saved parameters to every sample with the device's "
                                   "integer per-sample code (the paper's model through its numpy "
                                   "twin, bit-exact); writes t,x,y,z[,temp] in g, then the "
                                   "recording's further columns as read.  Streams: any length "
                                   "of recording in constant memory.",
                       epilog=RULE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("params", help="parameters JSON from calibrate --save")
    p.add_argument("input", help="recording CSV")
    p.add_argument("-o", "--output", required=True,
                   help="output CSV (written whole or not at all; never one of the inputs)")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--device", help="which device of a `calibrate --by ... --save` file")
    add_effects_arg(p)
    p.add_argument("--range", type=int, choices=[2, 4, 8, 16], default=None,
                   help="full scale of the device's apply, g: its fixed-point format (output Q13 g "
                        "at 2 g, 0.12 mg; one bit less per doubling) and where readings are "
                        "clipped (default: the file's declared range, else 2)")
    p.set_defaults(func=cmd_apply)

