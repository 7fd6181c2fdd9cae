"""accelcal: accelerometer self-calibration (Farago 2024) on the device and beside it.

Every command has --help.  Errors: one line on stderr and exit status 2, never a traceback."""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from accelcal.io import InputError
from accelcal.outputs import FORCE_HELP, atomic, check_output, write_text

EPILOG_CAL = """\
Input: a recording (CSV header t,x,y,z or t,x,y,z,temp in s, g, degC; or an Axivity .cwa,
GENEActiv .bin, ActiGraph .gt3x) goes through rest detection, bins and the optimiser, streamed in
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


class _Parser(argparse.ArgumentParser):
    """An option error is one line (and exit 2) like every other bad input, with the command's
    --help named for the details."""

    def error(self, message):
        self.exit(2, f"accelcal: error: {message} (see `{self.prog} --help`)\n")


def _int_in(lo, hi):
    """An int option within [lo, hi] (every numeric option has an upper bound)."""
    def parse(s):
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{s!r} is not a whole number") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{v} is outside [{lo}, {hi}]")
        return v
    parse.__name__ = "int"
    return parse


def _float_in(lo, hi, lo_open=False):
    """A finite float option within [lo, hi] ((lo, hi] with lo_open)."""
    def parse(s):
        try:
            v = float(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{s!r} is not a number") from None
        if not math.isfinite(v) or v < lo or v > hi or (lo_open and v == lo):
            raise argparse.ArgumentTypeError(
                f"{s} is outside {'(' if lo_open else '['}{lo:g}, {hi:g}]")
        return v
    parse.__name__ = "float"
    return parse


_positive_int = _int_in(1, 10 ** 6)


def _dask_address(s):
    """A scheduler address: [scheme://]host:port, the port a number."""
    import re
    m = re.fullmatch(r"(?:(tcp|tls|ws|wss|inproc|ucx)://)?(\[[0-9a-fA-F:]+\]|[A-Za-z0-9_.-]+):(\d{1,5})",
                     s)
    if not m or not 0 < int(m.group(3)) < 65536:
        raise argparse.ArgumentTypeError(f"{s!r} is not a scheduler address such as "
                                         "tcp://10.0.0.5:8786")
    return s


def _rates(s):
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


def _threshold(s):
    if s == "auto":
        return "auto"
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError("a number of g (e.g. 0.05) or auto") from None
    if not 0 < v <= 2:
        raise argparse.ArgumentTypeError("must be in (0, 2] g, or auto")
    return v


AXES = {"x": 0, "y": 1, "z": 2, "all": 3}  # 3: acal.rest.ALL_AXES


def _add_pipeline_args(p):
    g = p.add_argument_group("device pipeline",
                             "--profile sets every default below; an option given overrides it.")
    g.add_argument("--profile", choices=["wear", "paper"], default="wear",
                   help="wear (default): rest on all axes against a threshold from the sensor's "
                        "measured noise, 8 points per subset, a Gauss-Newton fit to the optimum "
                        "with outlier rejection, ready on coverage; paper: Farago 2024 to the "
                        "letter (x axis, 0.12 g, 2 points per subset, 50 gradient steps)")
    g.add_argument("--seconds", type=_int_in(1, 3600), default=5, help="rest segment length, s (default 5)")
    g.add_argument("--threshold", type=_threshold, default=None,
                   help="max-min rest threshold, g, or auto (from the measured noise); "
                        "default: wear auto, paper 0.12")
    g.add_argument("--axis", choices=["x", "y", "z", "all"], default=None,
                   help="axis for the rest test, or all; default: wear all, paper x")
    g.add_argument("--min-count", type=_int_in(1, 64), default=None,
                   help="points per subset to calibrate (default 2)")
    g.add_argument("--max-count", type=_int_in(1, 64), default=None,
                   help="points kept per subset (default: wear 8; paper 2, 4 for a composed model)")
    g.add_argument("--differ", type=_float_in(0, 2), default=0.1,
                   help="a new rest mean must differ by this much (max-norm, g) from held points (default 0.1)")
    g.add_argument("--select", choices=["centre", "first"], default="centre",
                   help="point selection once a subset is full: centre (replace by better-placed points) "
                        "or first (first come, as printed in the paper)")
    g.add_argument("--iterations", type=_int_in(1, 100000), default=None,
                   help="optimiser iterations (default: wear up to 20 Gauss-Newton steps per "
                        "round; paper 50, 200 for a composed model)")
    g.add_argument("--rates", type=_rates, default=(3, 8, 2), metavar="S,M,O",
                   help="paper profile: learning rates for scale, misalignment, offset, multiples "
                        "of 0.1 (default 0.3,0.8,0.2, the paper's)")


def _config(args, composed=False):
    from accelcal.runtime import Config
    thr = None if args.threshold in (None, "auto") else args.threshold
    cfg = Config.for_profile(args.profile, composed, threshold_g=thr,
                             axis=None if args.axis is None else AXES[args.axis],
                             min_count=args.min_count, max_count=args.max_count,
                             iterations=args.iterations)
    if args.threshold == "auto":
        cfg.threshold_g = None
    cfg.seconds = args.seconds
    cfg.differ_g = args.differ
    cfg.policy = args.select
    cfg.rates_tenths = args.rates
    if cfg.max_count < cfg.min_count:
        raise InputError("--max-count must be >= --min-count")
    return cfg


def cmd_calibrate(args) -> int:
    from accelcal.calibrate import calibrate_groups
    from accelcal.effects import ModelSpec
    from accelcal.io import read_table, save_params
    try:
        spec = ModelSpec.parse(args.model)
    except ValueError as e:
        raise InputError(str(e)) from None
    if spec.effects and args.method not in ("device", "lsq"):
        raise InputError(f"model {spec}: composed models are fitted by --method device (the "
                         "device's integer optimiser) or lsq (float; --points bins|all)")
    if args.points and args.method == "device":
        raise InputError("--points applies to the float methods (--method lsq, ...); the device "
                         "method fits the points its bins select")
    engine = args.engine or ("vector" if args.runtime == "cpython" else "device")
    inputs = args.input
    reads = [*inputs, args.fallback]
    if args.save:
        check_output(args.save, reads, args.force, "--save")
    if len(inputs) > 1 or args.summary or args.jobs > 1 or args.dask:
        return _calibrate_batch(args, spec, engine)
    from accelcal.recording import is_recording
    if is_recording(inputs[0]):
        if args.by:
            raise InputError(f"{inputs[0]}: --by applies to points files; this is a recording")
        from accelcal.calibrate import calibrate_recording
        from tqdm import tqdm
        bar = tqdm(unit=" samples", unit_scale=True, file=sys.stderr, disable=args.quiet or not sys.stderr.isatty(),
                   desc="reading")
        recs = [calibrate_recording(inputs[0], _config(args, bool(spec.effects)), args.method,
                                    args.runtime, spec, engine, progress=lambda n: bar.update(n - bar.n),
                                    fallback=args.fallback, points=args.points or "bins")]
        bar.close()
    else:
        recs = calibrate_groups(read_table(inputs[0]), args.by, _config(args, bool(spec.effects)),
                                args.method, args.runtime, spec, args.points or "bins")
        if args.fallback:
            raise InputError("--fallback applies to recordings")
    failed = [r for r in recs if r["status"] != "calibrated" and r.get("calibration") != "fallback"]
    for r in recs:
        if args.json:
            print(json.dumps(r))
        else:
            _print_record(r, args.by)
    for r in failed:
        who = f"{args.by} {r[args.by]}: " if args.by else ""
        print(f"accelcal: {who}{r['reason']}", file=sys.stderr)
    if args.save:
        ok = [r for r in recs if r["status"] == "calibrated"]
        if ok:
            save_params(args.save, ok[0] if not args.by else {"by": args.by, "devices": ok})
    return 2 if failed else 0


def _calibrate_batch(args, spec, engine) -> int:
    from accelcal import batch
    from accelcal.io import save_params
    if args.by:
        raise InputError("--by applies to one points file, not to a batch")
    summary = args.summary or "accelcal-summary.csv"
    check_output(summary, [*args.input, args.fallback, args.save], args.force, "--summary")
    job = batch.Job(_config(args, bool(spec.effects)), args.method, args.runtime, str(spec), engine,
                    args.fallback, args.points or "bins")
    if args.fallback:
        from accelcal.io import load_params
        load_params(args.fallback)  # a bad fallback is bad input, before any file is read
    if args.dask:
        recs = batch.run_dask(args.input, job, args.dask, quiet=args.quiet)
    else:
        recs = batch.run_local(args.input, job, args.jobs, quiet=args.quiet)
    batch.write_summary(summary, recs)
    if args.json:
        for r in recs:
            print(json.dumps(r))
    else:
        batch.print_summary(recs)
    print(f"summary: {summary}", file=sys.stderr)
    if args.save:
        ok = [r for r in recs if r["status"] == "calibrated"]
        if ok:
            save_params(args.save, {"by": "file", "devices": ok})
    bad = [r for r in recs if r["status"] != "calibrated"]
    return 2 if args.strict and bad else 0


def _print_record(r, by):
    head = f"{by} {r[by]}: " if by else ""
    if "hours" in r:  # a recording: its quality first
        ex = r["excluded"]
        tr = r["temp_range_c"]
        print(f"{head}{r['file']} ({r['format']}, {r['rate_hz']} Hz): {r['hours']:.2f} h, "
              f"{r['gaps']} gaps, {r['still_windows']} still windows kept (excluded: "
              f"{ex['nonwear']} non-wear = {r['nonwear_hours']:.2f} h, {ex['imputed']} imputed, "
              f"{ex['clipped']} clipped), clipping {r['clipped_pct']:.3f} %"
              + (f", {tr[0]:.1f}..{tr[1]:.1f} degC" if tr else ", no temperature"))
    if r["status"] != "calibrated":
        label = "NOT ENOUGH DATA" if r["status"] == "not_enough_data" else "FAILED"
        print(f"{head}{label}: {r['reason']}")
        if r.get("calibration") == "fallback":
            print(f"  using the fallback calibration {r['fallback']} (not this file's): "
                  + "  ".join(f"{k}={v:+.5g}" for k, v in r["params"].items()))
            if r.get("error_after_mg") is not None and r.get("error_before_mg") is not None:
                print(f"  calibration error: {r['error_before_mg']:.2f} mg before -> "
                      f"{r['error_after_mg']:.2f} mg with the fallback")
        return
    it = f", {r['iterations']} iterations" if r.get("iterations") else ""
    print(f"{head}calibrated {r['model']} by {r['method']} ({r['runtime']}) on {r['points']} points "
          f"of {r['rest_points']} rest points{it}")
    print("  " + "  ".join(f"{k}={v:+.5g}" for k, v in r["params"].items()))
    if "reference" in r:
        print(f"  reference: {r['reference']['T0']:g} degC, t = {r['reference']['t0']:g} s")
    print(f"  calibration error: {r['error_before_mg']:.2f} mg before -> {r['error_after_mg']:.2f} mg after")


def cmd_apply(args) -> int:
    from accelcal.calibrate import apply_file
    from accelcal.io import load_params
    from accelcal.recording import is_recording
    model, p_int, ref = load_params(args.params, args.device)
    if not is_recording(args.input):
        raise InputError(f"{args.input}: apply needs a recording (header t,x,y,z[,temp], or "
                         ".cwa/.bin/.gt3x)")
    check_output(args.output, [args.params, args.input], args.force, "-o/--output")
    n, clipped, rng = apply_file(p_int, model, ref, args.input, args.output, args.range)
    print(f"wrote {n} calibrated samples to {args.output} (the device's apply at +-{rng} g"
          + (f"; {clipped} samples past that full scale were clipped, as the device's would be: "
             f"--range 4, 8 or 16 keeps them" if clipped else "") + ")", file=sys.stderr)
    return 0


def cmd_simulate_paper(args) -> int:
    from accelcal import simulate
    from acal.fixed import PARAM_NAMES
    out = check_output(args.output, (), args.force, "-o/--output")
    check_output(out.with_suffix(".truth.json"), (), args.force, "its truth file")
    rng = np.random.default_rng(args.seed)
    rows, truth = [], {}
    for s in range(args.scenarios):
        p, v = simulate.paper_scenario(rng, args.points, args.noise_mg * 1e-3, args.noise_dist)
        name = f"s{s:04d}"
        truth[name] = dict(zip(PARAM_NAMES, map(float, p)))
        rows.append((name, v))
    out = Path(args.output)
    tpath = out.with_suffix(".truth.json")
    with atomic(out) as fh:
        fh.write("x,y,z,device\n")
        for name, v in rows:
            for x, y, z in v:
                fh.write(f"{x:.7f},{y:.7f},{z:.7f},{name}\n")
    write_text(tpath, json.dumps({"simulation": "farago2024 section III-A", "noise_mg": args.noise_mg,
                                 "noise_dist": args.noise_dist, "seed": args.seed,
                                 "points_per_device": args.points, "params": truth}, indent=1) + "\n")
    print(f"wrote {args.scenarios} devices x {args.points} points to {out}, truth to {tpath}",
          file=sys.stderr)
    return 0


def cmd_simulate_wrist(args) -> int:
    from accelcal import wearer
    out = check_output(args.output, (), args.force, "-o/--output")
    check_output(out.with_suffix(".truth.json"), (), args.force, "its truth file")
    if args.stimulus:
        check_output(args.stimulus, [out], args.force, "--stimulus")

    def progress(done, total):
        print(f"\rsimulated {done / (86400 * args.rate):5.2f} of {args.days:g} days", end="",
              file=sys.stderr, flush=True)
    truth = wearer.simulate_wrist(out, args.days, args.rate, args.seed, effects=args.effect,
                                  stimulus=args.stimulus, range_g=args.range, progress=progress)
    print(file=sys.stderr)
    h = ", ".join(f"{k} {v:.1f} h" for k, v in truth["hours"].items())
    print(f"wrote {truth['samples']} samples to {out}, truth to {out.with_suffix('.truth.json')}"
          + (f", stimulus to {args.stimulus}" if args.stimulus else "") + f"\n  {h}", file=sys.stderr)
    return 0


def cmd_board_virtual(args) -> int:
    from accelcal.vboard import serve_main
    return serve_main(args)


def _app_settings(args) -> dict:
    from acal import profile as dprofile
    s = {"rate_hz": args.rate, "profile": dprofile.parse(args.profile)}
    if args.capture_kb:
        s["capture_bytes"] = args.capture_kb * 1024
    if args.fifo:
        s["fifo"] = True
    if args.recal_hours is not None:
        s["recal_seconds"] = int(args.recal_hours * 3600)
    if args.model != "base":
        from accelcal.effects import ModelSpec
        try:
            s["model"] = str(ModelSpec.parse(args.model))
        except ValueError as e:
            raise InputError(str(e)) from None
    return s


def cmd_deploy(args) -> int:
    from accelcal import boardtools
    r = boardtools.deploy(args.port, args.board, _app_settings(args), write_main=not args.no_main,
                          say=lambda m: print(m, file=sys.stderr))
    print(json.dumps(r) if args.json else
          f"deployed to {r['port']}: board {r['board']} ({r['platform']}), {r['modules']} modules as "
          f".{r['format']}" + (", main.py starts logging at power-up" if r["main_py"] else ""))
    return 0


def cmd_acquire(args) -> int:
    from accelcal import boardtools
    boardtools.acquire(args.port, int(args.hours * 3600), _app_settings(args),
                       say=lambda m: print(m, file=sys.stderr, flush=True))
    return 0


def cmd_pull(args) -> int:
    from accelcal import boardtools
    s = boardtools.pull(args.port, args.output, say=lambda m: print(m, file=sys.stderr),
                        force=args.force)
    if args.json:
        print(json.dumps(s))
        return 0
    _print_summary(s, args.output)
    return 0


def _print_summary(s, where):
    c = s["counters"] or {}
    print(f"{where}: {s['log_bytes']} B of log, {s['boots']} boot(s), {len(s['rest_points'])} rest records, "
          f"{len(s['calibrations'])} calibration record(s)")
    if c:
        print(f"  samples {c['samples']}, lost {c['lost']}, FIFO overruns {c['fifo_overruns']}, "
              f"bus errors {c['bus_errors']} ({c['bus_retries']} retried), rest segments {c['rest_segments']}")
    for cal in s["calibrations"]:
        vals = " ".join(f"{n}={cal[n]:+.4f}" for n in ("kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz"))
        print(f"  calibration {cal['number']} at sample {cal['index']}: {cal['status']}, "
              f"{cal['iterations']} iterations, {cal['points']} points: {vals}")
        for name, e in cal.get("effects", {}).items():
            vals = " ".join(f"{n}={v:+.4g}" for n, v in e["params"].items())
            print(f"    + {name} ({e['unit']}): {vals}; reference {e['ref_temp']} degC, "
                  f"{e['ref_time_s']} s of running time")
    if s["stored_calibration"]:
        print(f"  stored calibration: number {s['stored_calibration']['number']} (slot {s['stored_calibration']['slot']})")
    for d in s["dropped"]:
        print("  " + d)


def cmd_replay(args) -> int:
    from accelcal import boardlog
    r = boardlog.replay(args.dir, args.profile)
    if args.json:
        print(json.dumps(r))
    else:
        how = f", with the {args.profile} profile's settings" if args.profile else ""
        print(f"replayed {r['samples_replayed']} samples of {args.dir}/capture.bin through the current "
              f"device modules{how}")
        for k in ("rest", "cal", "effect"):
            d = r[k]
            if k == "effect" and not d["board"] and not d["replay"]:
                continue  # the paper's model: no effect records
            first = "" if d["first_difference"] is None else f", first difference at record {d['first_difference']}"
            print(f"  {k:4s}: board {d['board']}, replay {d['replay']}, differing {d['differ']}{first}")
        print("identical" if r["identical"] else
              "DIFFERENT: " + (f"the {args.profile} profile parts from what the board did" if args.profile
                               else "the device code no longer does what the board did"))
    return 0 if r["identical"] else 1


def cmd_diagnose(args) -> int:
    from accelcal.diagnose import diagnose_main
    return diagnose_main(args)


def cmd_report(args) -> int:
    from accelcal.diagnose import report_main
    return report_main(args)


def cmd_table2(args) -> int:
    from accelcal.paper import table2_main
    return table2_main(args)


def cmd_compare(args) -> int:
    from accelcal.compare import compare_main
    return compare_main(args, _config(args))


def cmd_gietzelt(args) -> int:
    from accelcal.gietzelt import gietzelt_main
    return gietzelt_main(args)


def cmd_table3(args) -> int:
    from accelcal.table3 import table3_main
    return table3_main(args)


def cmd_bench(args) -> int:
    from accelcal.bench import bench_main
    return bench_main(args)


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="accelcal", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("calibrate", help="calibrate a recording or points file",
                       description="Run the device pipeline (or a reference method on the points "
                                   "it selects) and report parameters and calibration error.",
                       epilog=EPILOG_CAL, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", nargs="+", metavar="INPUT",
                   help="recording (CSV t,x,y,z[,temp]; Axivity .cwa, GENEActiv .bin, ActiGraph "
                        ".gt3x) or points CSV; several make a batch")
    p.add_argument("--model", default="base",
                   help="model spec: base (the paper's 9 parameters) or base+EFFECT[+EFFECT...] "
                        "(temp_offset, temp_scale, drift, nonlinear; with --method device or lsq). "
                        "A composed device fit keeps points spread in temperature (>= 3 degC) and time "
                        "(>= 12 h): wear profile 8 per subset, the base fit first and kept if the "
                        "composed one fails or is worse; paper profile 4 per subset, 200 iterations")
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
    p.add_argument("--runtime", choices=["cpython", "micropython", "micropython32"], default="cpython",
                   help="interpreter that runs the device modules: micropython, the real unix port "
                        "(64-bit); micropython32, the 32-bit MicroPython (WebAssembly under Node, "
                        "ints past 2^30 allocate as on an RP2040)")
    p.add_argument("--engine", choices=["vector", "device"], default=None,
                   help="recordings: vector (default under cpython) finds rest segments with the "
                        "numpy twin of the device's detector, bit-exact with it, and offers them "
                        "to the device's bins; device (default under micropython) feeds every "
                        "sample through the device modules, for regression testing device code")
    p.add_argument("--by", metavar="COLUMN", help="calibrate each value of COLUMN (e.g. device) separately")
    p.add_argument("--save", metavar="PARAMS.json", help="save the parameters (with --by: all devices)")
    p.add_argument("--force", action="store_true", help=FORCE_HELP + ": --save, --summary")
    p.add_argument("--json", action="store_true", help="one JSON object per group (or file) on stdout")
    p.add_argument("--fallback", metavar="PARAMS.json",
                   help="a device's last good calibration (from --save): a file that does not "
                        "calibrate reports it with calibration \"fallback\" and its error, never "
                        "silently")
    g = p.add_argument_group("batches (several INPUTs)")
    g.add_argument("--jobs", type=_int_in(1, 256), default=1, metavar="N",
                   help="files calibrated at once in a process pool (default 1)")
    g.add_argument("--dask", metavar="ADDRESS", type=_dask_address,
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
    _add_pipeline_args(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("apply", help="calibrate a recording with saved parameters",
                       description="Apply saved parameters to every sample with the device's "
                                   "integer per-sample code (the paper's model through its numpy "
                                   "twin, bit-exact); writes t,x,y,z[,temp] in g.  Streams: any "
                                   "length of recording in constant memory.")
    p.add_argument("params", help="parameters JSON from calibrate --save")
    p.add_argument("input", help="recording CSV")
    p.add_argument("-o", "--output", required=True,
                   help="output CSV (written whole or not at all; never one of the inputs)")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--device", help="which device of a `calibrate --by ... --save` file")
    p.add_argument("--range", type=int, choices=[2, 4, 8, 16], default=None,
                   help="full scale of the device's apply, g: its fixed-point format (Q14 at 2 g, "
                        "one bit less per doubling) and where readings are clipped (default: the "
                        "file's declared range, else 2)")
    p.set_defaults(func=cmd_apply)

    p = sub.add_parser("simulate", help="simulate data with known truth")
    ssub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = ssub.add_parser("paper", help="the paper's simulation (eqs. 17-20): rest means per device",
                        description="Random 9-parameter sensors (eq. 17), unit points turned into "
                                    "measurements by the exact inverse of eqs. 7-9, plus noise. "
                                    "Writes a points file with a device column; the truth goes "
                                    "beside it as NAME.truth.json.")
    q.add_argument("--noise-mg", type=_float_in(0, 1000), default=1.0, help="noise per axis, mg (default 1)")
    q.add_argument("--noise-dist", choices=["normal", "uniform"], default="normal",
                   help="normal: sd = noise; uniform: on [-noise, +noise]")
    q.add_argument("--scenarios", type=_int_in(1, 100000), default=10, help="devices (default 10)")
    q.add_argument("--points", type=_int_in(1, 10 ** 6), default=300, help="rest means per device (default 300)")
    q.add_argument("--seed", type=_int_in(0, 2 ** 32 - 1), default=1)
    q.add_argument("-o", "--output", required=True, help="points CSV to write")
    q.add_argument("--force", action="store_true", help=FORCE_HELP)
    q.set_defaults(func=cmd_simulate_paper)

    q = ssub.add_parser("wrist", help="a realistic wrist-worn recording, truth beside it",
                        description="Days of wrist wear (sleep postures, desk work, walking, sitting, "
                                    "off-wrist) seen through a simulated LIS3DH: the 9-parameter "
                                    "errors, 220 ug/sqrt(Hz) noise, 12-bit quantisation, clipping and a "
                                    "temperature trace.  Writes the recording CSV (t,x,y,z,temp), its "
                                    "truth as NAME.truth.json, and with --stimulus the virtual board's "
                                    "input (before quantisation: the simulated chip quantises).")
    q.add_argument("--days", type=_float_in(0, 3650, lo_open=True), default=1.0,
                   help="days of wear (default 1)")
    q.add_argument("--rate", type=int, choices=[10, 25, 50, 100], default=25, help="Hz (default 25)")
    q.add_argument("--range", type=int, choices=[2, 4, 8, 16], default=2, help="full scale, g (default 2)")
    q.add_argument("--seed", type=_int_in(0, 2 ** 32 - 1), default=1)
    q.add_argument("--stimulus", metavar="FILE.bin", help="also write the stimulus for `board virtual`")
    from accelcal.effects import CATALOGUE
    q.add_argument("--effect", action="append", default=[], choices=list(CATALOGUE),
                   help="add a hidden physical effect (repeatable): " + ", ".join(CATALOGUE)
                   + "; its true values go to the truth JSON")
    q.add_argument("-o", "--output", required=True, help="recording CSV to write")
    q.add_argument("--force", action="store_true", help=FORCE_HELP)
    q.set_defaults(func=cmd_simulate_wrist)

    p = sub.add_parser("board", help="boards: the virtual board", description="Board tools.")
    bsub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = bsub.add_parser("virtual", help="start the virtual board on a pseudo-terminal",
                        description="The MicroPython unix port on a pseudo-terminal, a folder as its "
                                    "flash, a simulated LIS3DH behind a fake machine.I2C fed by a "
                                    "stimulus (a simulated wrist day unless --stimulus), virtual time. "
                                    "Prints the port on stdout; then any `mpremote connect PORT ...` works. "
                                    "Runs until Ctrl-C or SIGTERM.")
    q.add_argument("--flash", default="vboard-flash", help="folder that is the board's flash (default vboard-flash)")
    q.add_argument("--stimulus", help="stimulus file (from `simulate wrist --stimulus`)")
    q.add_argument("--days", type=_float_in(0, 3650, lo_open=True), default=1.0,
                   help="without --stimulus: days to simulate (default 1)")
    q.add_argument("--rate", type=int, choices=[10, 25, 50, 100], default=25,
                   help="without --stimulus: Hz (default 25)")
    q.add_argument("--seed", type=_int_in(0, 2 ** 32 - 1), default=1)
    q.add_argument("--bus-faults", type=_int_in(0, 1000), default=0, metavar="PER_MILLE",
                   help="share of I2C transactions that fail, per mille (default 0)")
    q.add_argument("--heap", help="MicroPython heap size, e.g. 160k (an RP2040's)")
    q.add_argument("--speed", type=_int_in(0, 10000), default=0, help="0: as fast as possible (default); N: N x real time")
    q.add_argument("--link", help="also make this symlink to the port")
    q.add_argument("--port-file", help="also write the port to this file")
    q.set_defaults(func=cmd_board_virtual)

    def app_args(q):
        g = q.add_argument_group("app settings")
        g.add_argument("--rate", type=int, choices=[10, 25, 50, 100, 200, 400], default=100,
                       help="output data rate, Hz (default 100)")
        g.add_argument("--capture-kb", type=_int_in(0, 1 << 20), default=0,
                       help="also capture the raw samples, up to this many kB (for `accelcal replay`)")
        g.add_argument("--fifo", action="store_true", help="read the FIFO (10 bits) instead of the registers")
        g.add_argument("--recal-hours", type=_float_in(0, 8760, lo_open=True), help="least time between calibrations (default 6)")
        g.add_argument("--model", default="base",
                       help="the model the board fits and applies: base (the paper's) or a composed "
                            "one such as base+temp_offset (what `accelcal diagnose` named)")
        g.add_argument("--profile", choices=["wear", "paper"], default="wear",
                       help="wear (default): all-axis rest against the measured noise, 72 points, "
                            "Gauss-Newton with outlier rejection, sliced between FIFO reads; "
                            "paper: Farago 2024 to the letter")

    p = sub.add_parser("deploy", help="copy the device package and a board file to a board",
                       description="With mpremote: the device package into :lib/acal (as .mpy built by "
                                   "mpy-cross where the board's architecture is known), the board file "
                                   "as :acal_board.py, and a main.py that starts the app at power-up "
                                   "with the app settings given here.")
    p.add_argument("--port", required=True, help="serial port (or the virtual board's pty)")
    p.add_argument("--board", help="board file name (default: from the board's sys.platform)")
    p.add_argument("--no-main", action="store_true", help="do not write main.py")
    p.add_argument("--json", action="store_true")
    app_args(p)
    p.set_defaults(func=cmd_deploy)

    p = sub.add_parser("acquire", help="run the deployed app for a while (virtual board: simulated time)",
                       description="Runs acal.app.main(seconds=...) on the board with mpremote exec and "
                                   "shows its hourly progress lines.")
    p.add_argument("--port", required=True)
    p.add_argument("--hours", type=_float_in(0, 87600, lo_open=True), required=True, help="hours of board time")
    app_args(p)
    p.set_defaults(func=cmd_acquire)

    p = sub.add_parser("pull", help="copy a board's logs off and decode them",
                       description="Copies log.bin, capture.bin, cal_a.bin, cal_b.bin into DIR, decodes "
                                   "them (records dropped by a power cut are reported) and writes "
                                   "DIR/summary.json.")
    p.add_argument("--port", required=True)
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="folder for the logs (made if missing; the files arrive whole or not at all)")
    p.add_argument("--force", action="store_true", help="replace an earlier pull's files in DIR")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_pull)

    p = sub.add_parser("replay", help="re-run a pulled capture through the current device modules",
                       description="Feeds DIR/capture.bin through the device Processor under CPython with "
                                   "the settings of the board's BOOT record and diffs every rest point "
                                   "and calibration against DIR/log.bin.  Exit 0 identical, 1 different, "
                                   "2 bad input.")
    p.add_argument("dir", help="folder written by `accelcal pull`")
    p.add_argument("--profile", choices=["wear", "paper"], default=None,
                   help="replay with this profile's pipeline settings instead of the board's "
                        "(its BOOT record's): what the other profile would have done on the same "
                        "samples; the diff then shows where they part")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("diagnose", help="where the model fails, and which effect is missing",
                       description="Fits the model on even 2-hour blocks of the rest points and "
                                   "measures on the odd ones: held-out calibration error beside the "
                                   "noise floor, residuals against time, temperature, each axis and "
                                   "|a|, and for every catalogue effect not in the model the held-out "
                                   "error with it added; names the missing effect, or none.")
    p.add_argument("input", help="recording CSV (t,x,y,z[,temp]) or points file")
    p.add_argument("--model", default="base", help="model spec: base, base+temp_offset, ... (default base)")
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

    p = sub.add_parser("report", help="the model steps of a diagnose --history file",
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

    p = sub.add_parser("compare", help="every calibration method on the same data, one table",
                       description="Rest points (the device's detector) split into training and "
                                   "held-out parts (recordings: 2-hour blocks, even/odd; points "
                                   "files without t: alternate points).  The device's bins and "
                                   "optimiser run on the training part; every float method is "
                                   "fitted on the points the bins selected (--train all: on every "
                                   "training point).  All are scored on the held-out part: mean "
                                   "| |a| - 1 g | in mg before and after, R (Farago eq. 21), fit "
                                   "time measured in this run.  A method that cannot fit shows "
                                   "its reason; the others still run.")
    p.add_argument("input", help="recording CSV (t,x,y,z[,temp]) or points file")
    p.add_argument("--methods", metavar="M1,M2,...",
                   help="default all: device," + ",".join(METHODS))
    p.add_argument("--train", choices=["selected", "thinned", "all"], default="selected",
                   help="what the float methods are fitted on: the device bins' selection (default, "
                        "as Farago Table 3; thinned when the bins do not fill), the training points "
                        "thinned to at most 10 per direction (Gietzelt 2.4), or all of them (de "
                        "then costs O(points) per generation: minutes on days of data)")
    p.add_argument("--runtime", choices=["cpython", "micropython", "micropython32"], default="cpython",
                   help="interpreter for the device method")
    p.add_argument("--plots", metavar="DIR",
                   help="write training_curve.png: held-out error against the number of training "
                        "vectors per method (Gietzelt figure 3)")
    p.add_argument("--json", action="store_true")
    _add_pipeline_args(p)
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("paper", help="reproduce the paper's results")
    psub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = psub.add_parser("table2", help="Farago 2024 Table 2 (simulation) beside ours",
                        description="Runs the simulation at 1 mg and 5 mg through the device bins and "
                                    "optimiser; prints mean/SD absolute parameter errors beside the "
                                    "paper, lsq on the same points, the Cramer-Rao bound of those "
                                    "points, and first-come selection.")
    q.add_argument("--scenarios", type=_int_in(1, 100000), default=500)
    q.add_argument("--candidates", type=_int_in(1, 100000), default=300,
                   help="random rest means offered to the bins per scenario (default 300)")
    q.add_argument("--noise-dist", choices=["normal", "uniform"], default="normal")
    q.add_argument("--runtime", choices=["cpython", "micropython", "micropython32"], default="cpython")
    q.add_argument("--no-first", action="store_true", help="skip the first-come comparison")
    q.add_argument("--profile", choices=["paper", "wear"], default="paper",
                   help="paper (default: the paper's Table 2), or wear: the default profile's "
                        "72 points and Gauss-Newton fit, beside lsq on the same points")
    q.add_argument("--seed", type=_int_in(0, 2 ** 32 - 1), default=2024)
    q.add_argument("--json", action="store_true")
    q.set_defaults(func=cmd_table2)

    q = psub.add_parser("gietzelt", help="Gietzelt 2013: Table 4 simulation, unequal and misaligned axes",
                        description="Section 2.3 (200 points on o = 2300, s = 500 counts, 1 %% jitter, "
                                    "100 train / 100 test, ten passes) with every method beside the "
                                    "paper's Table 4 and execution times (Table 3); section 3.5 "
                                    "(unequal axes up to 1:2:3) and 3.6 (axes misaligned by up to 2 "
                                    "degrees).")
    q.add_argument("--passes", type=_int_in(1, 10000), default=10)
    q.add_argument("--jitter", type=_float_in(0, 100), default=1.0,
                   help="total width of the uniform radial jitter, %% of the radius (default 1, "
                        "i.e. +-0.5 %%: matches the spread of Table 4; 2 gives +-1 %%)")
    q.add_argument("--seed", type=_int_in(0, 2 ** 32 - 1), default=2013)
    q.add_argument("--plots", metavar="DIR", help="write gietzelt_fig3.png (error against training vectors)")
    q.add_argument("--json", action="store_true")
    q.set_defaults(func=cmd_gietzelt)

    q = psub.add_parser("farago-table3", help="Farago 2024 Table 3: four methods on simulated wrist data",
                        description="Simulated wrist recordings, one per device; each through "
                                    "`compare` with the device method, linauto (the non-iterative "
                                    "method), lsq (fminunc's role) and de (LabVIEW's global search), "
                                    "all fitted on the points the device's bins selected from the "
                                    "training blocks and scored on the held-out blocks; the mean over "
                                    "devices beside the paper's Table 3.")
    q.add_argument("--devices", type=_int_in(1, 1000), default=10, help="recordings (default 10, as the paper)")
    q.add_argument("--days", type=_float_in(0, 3650, lo_open=True), default=3.0,
                   help="days per recording (default 3)")
    q.add_argument("--rate", type=int, choices=[10, 25, 50, 100], default=10, help="Hz (default 10)")
    q.add_argument("--seed", type=_int_in(0, 2 ** 32 - 1), default=300)
    q.add_argument("--keep", metavar="DIR", help="keep the simulated recordings here")
    q.add_argument("--json", action="store_true")
    q.set_defaults(func=cmd_table3)

    p = sub.add_parser("bench", help="timings and allocations under MicroPython and CPython",
                       description="Measured in one run: optimiser time (N=18, M=50) under both "
                                   "runtimes, rest-detector cost per sample as a ratio to a bare "
                                   "loop, bytes allocated per sample and per optimiser run.")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_bench)
    return ap


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except InputError as e:
        print(f"accelcal: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
    except OSError as e:   # the system refused a read or a write (disk full, permissions...)
        where = f"{e.filename}: " if e.filename else ""
        print(f"accelcal: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
