"""`simulate paper` and `simulate wrist`: data with known truth."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from accelcal.cli.options import COMMANDS, add_effects_arg, float_in, int_in, register_effects
from accelcal.errors import InputError
from accelcal.files.arguments import CHOICES, FLOATS
from accelcal.files.outputs import FORCE_HELP, atomic, check_output, write_text


def cmd_simulate_paper(args) -> int:
    from accelcal import simulate
    from acal.core.fixed import PARAM_NAMES
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
    from accelcal.model.effects import CATALOGUE
    from accelcal.simulate import public
    register_effects(args)
    for name in args.effect:
        if name not in CATALOGUE:
            raise InputError(f"--effect {name!r}: not an effect (one of {', '.join(CATALOGUE)}, "
                             "or one --effects FILE declares)")
    if len(set(args.effect)) != len(args.effect):
        raise InputError("--effect: the same effect twice")
    out = check_output(args.output, [args.effects], args.force, "-o/--output")
    check_output(out.with_suffix(".truth.json"), [args.effects], args.force, "its truth file")
    if args.stimulus:
        check_output(args.stimulus, [out], args.force, "--stimulus")

    def progress(done, total):
        print(f"\rsimulated {done / (86400 * args.rate):5.2f} of {args.days:g} days", end="",
              file=sys.stderr, flush=True)
    truth = public.simulate_wrist(out, args.days, args.rate, args.seed, effect=args.effect,
                                  stimulus=args.stimulus, range_g=args.range, progress=progress,
                                  force=args.force)
    print(file=sys.stderr)
    h = ", ".join(f"{k} {v:.1f} h" for k, v in truth["hours"].items())
    print(f"wrote {truth['samples']} samples to {out}, truth to {out.with_suffix('.truth.json')}"
          + (f", stimulus to {args.stimulus}" if args.stimulus else "") + f"\n  {h}", file=sys.stderr)
    return 0


def add_parsers(sub) -> None:
    p = sub.add_parser("simulate", help=COMMANDS["simulate"][1])
    ssub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = ssub.add_parser("paper", help="the paper's simulation (eqs. 17-20): rest means per device",
                        description="Random 9-parameter sensors (eq. 17), unit points turned into "
                                    "measurements by the exact inverse of eqs. 7-9, plus noise. "
                                    "Writes a points file with a device column; the truth goes "
                                    "beside it as NAME.truth.json.")
    q.add_argument("--noise-mg", type=float_in(0, 1000), default=1.0, help="noise per axis, mg (default 1)")
    q.add_argument("--noise-dist", choices=["normal", "uniform"], default="normal",
                   help="normal: sd = noise; uniform: on [-noise, +noise]")
    q.add_argument("--scenarios", type=int_in(1, 100000), default=10, help="devices (default 10)")
    q.add_argument("--points", type=int_in(1, 10 ** 6), default=300, help="rest means per device (default 300)")
    q.add_argument("--seed", type=int_in(0, 2 ** 32 - 1), default=1)
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
    q.add_argument("--days", type=float_in(*FLOATS["days"][:2], lo_open=True), default=1.0,
                   help="days of wear (default 1)")
    q.add_argument("--rate", type=int, choices=CHOICES["rate"], default=25, help="Hz (default 25)")
    q.add_argument("--range", type=int, choices=CHOICES["range"], default=2, help="full scale, g (default 2)")
    q.add_argument("--seed", type=int_in(0, 2 ** 32 - 1), default=1)
    q.add_argument("--stimulus", metavar="FILE.bin", help="also write the stimulus for `board virtual`")
    from accelcal.model.effects import CATALOGUE
    q.add_argument("--effect", action="append", default=[], metavar="NAME",
                   help="add a hidden physical effect (repeatable): " + ", ".join(CATALOGUE)
                   + ", or one --effects declares; its true values go to the truth JSON (an "
                   "effect that follows a recording column gets the column, after temp: a "
                   "battery's voltage, in mV for supply_mv, the board's own supply)")
    add_effects_arg(q)
    q.add_argument("-o", "--output", required=True, help="recording CSV to write")
    q.add_argument("--force", action="store_true", help=FORCE_HELP)
    q.set_defaults(func=cmd_simulate_wrist)

