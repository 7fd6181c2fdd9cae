"""accelcal: accelerometer self-calibration (Farago 2024) on the device and beside it.

Every command has --help.  Errors: one line on stderr and exit status 2, never a traceback."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from accelcal.io import InputError

EPILOG_CAL = """\
Input: a recording (CSV header t,x,y,z or t,x,y,z,temp; g and s) goes through rest detection,
bins and the optimiser; a points file (CSV with x,y,z and optional temp,t,device) through bins and
the optimiser.  The reference methods (lsq, linauto) are fitted on the points the device's bins
selected.  Exit status 2 when any group fails (the reason is on stderr and in the JSON).
"""


def _positive_int(s):
    v = int(s)
    if v < 1:
        raise argparse.ArgumentTypeError("must be >= 1")
    return v


def _rates(s):
    try:
        vals = [float(v) for v in s.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError("three numbers, e.g. 0.3,0.8,0.2") from None
    tenths = [round(v * 10) for v in vals]
    if len(vals) != 3 or any(abs(v * 10 - t) > 1e-9 or t < 0 for v, t in zip(vals, tenths)):
        raise argparse.ArgumentTypeError("three non-negative multiples of 0.1, e.g. 0.3,0.8,0.2")
    return tuple(tenths)


def _add_pipeline_args(p):
    g = p.add_argument_group("device pipeline")
    g.add_argument("--seconds", type=_positive_int, default=5, help="rest segment length, s (default 5)")
    g.add_argument("--threshold", type=float, default=0.12, help="max-min rest threshold, g (default 0.12)")
    g.add_argument("--axis", choices="xyz", default="x", help="axis for the rest test (default x)")
    g.add_argument("--min-count", type=_positive_int, default=2, help="points per subset to calibrate (default 2)")
    g.add_argument("--max-count", type=_positive_int, default=2, help="points kept per subset (default 2)")
    g.add_argument("--differ", type=float, default=0.1,
                   help="a new rest mean must differ by this much (max-norm, g) from held points (default 0.1)")
    g.add_argument("--select", choices=["centre", "first"], default="centre",
                   help="point selection once a subset is full: centre (replace by better-placed points) "
                        "or first (first come, as printed in the paper)")
    g.add_argument("--iterations", type=_positive_int, default=50, help="optimiser iterations M (default 50)")
    g.add_argument("--rates", type=_rates, default=(3, 8, 2), metavar="S,M,O",
                   help="learning rates for scale, misalignment, offset, multiples of 0.1 "
                        "(default 0.3,0.8,0.2, the paper's)")


def _config(args):
    from accelcal.runtime import Config
    if args.max_count < args.min_count:
        raise InputError("--max-count must be >= --min-count")
    return Config(seconds=args.seconds, threshold_g=args.threshold, axis="xyz".index(args.axis),
                  min_count=args.min_count, max_count=args.max_count, differ_g=args.differ,
                  policy=args.select, iterations=args.iterations, rates_tenths=args.rates)


def cmd_calibrate(args) -> int:
    from accelcal.calibrate import calibrate_groups
    from accelcal.io import read_table, save_params
    if args.model != "base":
        raise InputError(f"unknown model {args.model!r}: this version knows only 'base'")
    table = read_table(args.input)
    recs = calibrate_groups(table, args.by, _config(args), args.method, args.runtime)
    failed = [r for r in recs if r["status"] != "calibrated"]
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


def _print_record(r, by):
    head = f"{by} {r[by]}: " if by else ""
    if r["status"] != "calibrated":
        print(f"{head}FAILED: {r['reason']}")
        return
    it = f", {r['iterations']} iterations" if r.get("iterations") else ""
    print(f"{head}calibrated by {r['method']} ({r['runtime']}) on {r['points']} points "
          f"of {r['rest_points']} rest points{it}")
    print("  " + "  ".join(f"{k}={v:+.5f}" for k, v in r["params"].items()))
    print(f"  calibration error: {r['error_before_mg']:.2f} mg before -> {r['error_after_mg']:.2f} mg after")


def cmd_apply(args) -> int:
    from accelcal.calibrate import apply_to_samples
    from accelcal.io import load_params, read_table, write_csv
    p_int = load_params(args.params, args.device)
    table = read_table(args.input)
    if table.kind != "recording":
        raise InputError(f"{args.input}: apply needs a recording (header t,x,y,z[,temp])")
    a = apply_to_samples(p_int, table.xyz)
    cols = [table.columns["t"], a[:, 0], a[:, 1], a[:, 2]]
    header = ["t", "x", "y", "z"]
    fmt = ["%.6f", "%.6f", "%.6f", "%.6f"]
    if "temp" in table.columns:
        cols.append(table.columns["temp"])
        header.append("temp")
        fmt.append("%.3f")
    write_csv(args.output, header, cols, fmt)
    print(f"wrote {len(a)} calibrated samples to {args.output}", file=sys.stderr)
    return 0


def cmd_simulate_paper(args) -> int:
    from accelcal import simulate
    from acal.fixed import PARAM_NAMES
    rng = np.random.default_rng(args.seed)
    rows, truth = [], {}
    for s in range(args.scenarios):
        p, v = simulate.paper_scenario(rng, args.points, args.noise_mg * 1e-3, args.noise_dist)
        name = f"s{s:04d}"
        truth[name] = dict(zip(PARAM_NAMES, map(float, p)))
        rows.append((name, v))
    out = Path(args.output)
    with open(out, "w") as fh:
        fh.write("x,y,z,device\n")
        for name, v in rows:
            for x, y, z in v:
                fh.write(f"{x:.7f},{y:.7f},{z:.7f},{name}\n")
    tpath = out.with_suffix(".truth.json")
    tpath.write_text(json.dumps({"simulation": "farago2024 section III-A", "noise_mg": args.noise_mg,
                                 "noise_dist": args.noise_dist, "seed": args.seed,
                                 "points_per_device": args.points, "params": truth}, indent=1) + "\n")
    print(f"wrote {args.scenarios} devices x {args.points} points to {out}, truth to {tpath}",
          file=sys.stderr)
    return 0


def cmd_table2(args) -> int:
    from accelcal.paper import table2_main
    return table2_main(args)


def cmd_bench(args) -> int:
    from accelcal.bench import bench_main
    return bench_main(args)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="accelcal", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("calibrate", help="calibrate a recording or points file",
                       description="Run the device pipeline (or a reference method on the points "
                                   "it selects) and report parameters and calibration error.",
                       epilog=EPILOG_CAL, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", help="recording or points CSV")
    p.add_argument("--model", default="base", help="model spec (this version: base, the 9-parameter model)")
    p.add_argument("--method", choices=["device", "lsq", "linauto"], default="device",
                   help="device: the integer optimiser (default); lsq: float least squares; "
                        "linauto: Gietzelt 2013")
    p.add_argument("--runtime", choices=["cpython", "micropython"], default="cpython",
                   help="interpreter that runs the device modules (micropython: the real unix port)")
    p.add_argument("--by", metavar="COLUMN", help="calibrate each value of COLUMN (e.g. device) separately")
    p.add_argument("--save", metavar="PARAMS.json", help="save the parameters (with --by: all devices)")
    p.add_argument("--json", action="store_true", help="one JSON object per group on stdout")
    _add_pipeline_args(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("apply", help="calibrate a recording with saved parameters",
                       description="Apply saved parameters to every sample with the device's "
                                   "integer per-sample code; writes t,x,y,z[,temp] in g.")
    p.add_argument("params", help="parameters JSON from calibrate --save")
    p.add_argument("input", help="recording CSV")
    p.add_argument("-o", "--output", required=True, help="output CSV")
    p.add_argument("--device", help="which device of a `calibrate --by ... --save` file")
    p.set_defaults(func=cmd_apply)

    p = sub.add_parser("simulate", help="simulate data with known truth")
    ssub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = ssub.add_parser("paper", help="the paper's simulation (eqs. 17-20): rest means per device",
                        description="Random 9-parameter sensors (eq. 17), unit points turned into "
                                    "measurements by the exact inverse of eqs. 7-9, plus noise. "
                                    "Writes a points file with a device column; the truth goes "
                                    "beside it as NAME.truth.json.")
    q.add_argument("--noise-mg", type=float, default=1.0, help="noise per axis, mg (default 1)")
    q.add_argument("--noise-dist", choices=["normal", "uniform"], default="normal",
                   help="normal: sd = noise; uniform: on [-noise, +noise]")
    q.add_argument("--scenarios", type=_positive_int, default=10, help="devices (default 10)")
    q.add_argument("--points", type=_positive_int, default=300, help="rest means per device (default 300)")
    q.add_argument("--seed", type=int, default=1)
    q.add_argument("-o", "--output", required=True, help="points CSV to write")
    q.set_defaults(func=cmd_simulate_paper)

    p = sub.add_parser("paper", help="reproduce the paper's results")
    psub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = psub.add_parser("table2", help="Farago 2024 Table 2 (simulation) beside ours",
                        description="Runs the simulation at 1 mg and 5 mg through the device bins and "
                                    "optimiser; prints mean/SD absolute parameter errors beside the "
                                    "paper, lsq on the same points, the Cramer-Rao bound of those "
                                    "points, and first-come selection.")
    q.add_argument("--scenarios", type=_positive_int, default=500)
    q.add_argument("--candidates", type=_positive_int, default=300,
                   help="random rest means offered to the bins per scenario (default 300)")
    q.add_argument("--noise-dist", choices=["normal", "uniform"], default="normal")
    q.add_argument("--runtime", choices=["cpython", "micropython"], default="cpython")
    q.add_argument("--no-first", action="store_true", help="skip the first-come comparison")
    q.add_argument("--seed", type=int, default=2024)
    q.add_argument("--json", action="store_true")
    q.set_defaults(func=cmd_table2)

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


if __name__ == "__main__":
    sys.exit(main())
