"""Studies: the papers' tables (`paper table2`, `paper gietzelt`, `paper farago-table3`) and
`bench`."""
from __future__ import annotations

from accelcal.bridge.runtime import RUNTIMES
from accelcal.cli.options import COMMANDS, float_in, int_in


def cmd_table2(args) -> int:
    from accelcal.bridge.runtime import check
    from accelcal.studies.paper import table2_main
    check(args.runtime)
    return table2_main(scenarios=args.scenarios, candidates=args.candidates,
                       noise_dist=args.noise_dist, runtime_name=args.runtime,
                       no_first=args.no_first, profile=args.profile, seed=args.seed,
                       as_json=args.json)


def cmd_gietzelt(args) -> int:
    from accelcal.studies.gietzelt import gietzelt_main
    return gietzelt_main(passes=args.passes, jitter=args.jitter, seed=args.seed, plots_dir=args.plots,
                         as_json=args.json)


def cmd_table3(args) -> int:
    from accelcal.studies.table3 import table3_main
    return table3_main(devices=args.devices, days=args.days, rate=args.rate, seed=args.seed,
                       keep=args.keep, as_json=args.json)


def cmd_bench(args) -> int:
    from accelcal.studies.bench import bench_main
    return bench_main(runtime_name=args.runtime, as_json=args.json)


def add_parsers(sub) -> None:
    p = sub.add_parser("paper", help=COMMANDS["paper"][1])
    psub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    q = psub.add_parser("table2", help="Farago 2024 Table 2 (simulation) beside ours",
                        description="Runs the simulation at 1 mg and 5 mg through the device bins and "
                                    "optimiser; prints mean/SD absolute parameter errors beside the "
                                    "paper, lsq on the same points, the Cramer-Rao bound of those "
                                    "points, and first-come selection.")
    q.add_argument("--scenarios", type=int_in(1, 100000), default=500)
    q.add_argument("--candidates", type=int_in(1, 100000), default=300,
                   help="random rest means offered to the bins per scenario (default 300)")
    q.add_argument("--noise-dist", choices=["normal", "uniform"], default="normal")
    q.add_argument("--runtime", choices=RUNTIMES, default="cpython")
    q.add_argument("--no-first", action="store_true", help="skip the first-come comparison")
    q.add_argument("--profile", choices=["paper", "wear"], default="paper",
                   help="paper (default: the paper's Table 2), or wear: the default profile's "
                        "72 points and Gauss-Newton fit, beside lsq on the same points")
    q.add_argument("--seed", type=int_in(0, 2 ** 32 - 1), default=2024)
    q.add_argument("--json", action="store_true")
    q.set_defaults(func=cmd_table2)

    q = psub.add_parser("gietzelt", help="Gietzelt 2013: Table 4 simulation, unequal and misaligned axes",
                        description="Section 2.3 (200 points on o = 2300, s = 500 counts, 1 %% jitter, "
                                    "100 train / 100 test, ten passes) with every method beside the "
                                    "paper's Table 4 and execution times (Table 3); section 3.5 "
                                    "(unequal axes up to 1:2:3) and 3.6 (axes misaligned by up to 2 "
                                    "degrees).")
    q.add_argument("--passes", type=int_in(1, 10000), default=10)
    q.add_argument("--jitter", type=float_in(0, 100), default=1.0,
                   help="total width of the uniform radial jitter, %% of the radius (default 1, "
                        "i.e. +-0.5 %%: matches the spread of Table 4; 2 gives +-1 %%)")
    q.add_argument("--seed", type=int_in(0, 2 ** 32 - 1), default=2013)
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
    q.add_argument("--devices", type=int_in(1, 1000), default=10, help="recordings (default 10, as the paper)")
    q.add_argument("--days", type=float_in(0, 3650, lo_open=True), default=3.0,
                   help="days per recording (default 3)")
    q.add_argument("--rate", type=int, choices=[10, 25, 50, 100], default=10, help="Hz (default 10)")
    q.add_argument("--seed", type=int_in(0, 2 ** 32 - 1), default=300)
    q.add_argument("--keep", metavar="DIR", help="keep the simulated recordings here")
    q.add_argument("--json", action="store_true")
    q.set_defaults(func=cmd_table3)

    p = sub.add_parser("bench", help=COMMANDS["bench"][1],
                       description="Measured in one run: optimiser time (N=18, M=50) under both "
                                   "runtimes, rest-detector cost per sample as a ratio to a bare "
                                   "loop, bytes allocated per sample and per optimiser run, "
                                   "the fits' slices, the app on the simulated LIS3DH, and a file "
                                   "pulled off the virtual board (and the emulated Pico with "
                                   "--runtime rp2040) by mpremote fs cp and by pull's copy.")
    p.add_argument("--runtime", choices=["micropython", "rp2040", "rp2040-romfs", "circuitpython"],
                   default="micropython",
                   help="micropython (default): the unix port, the 32-bit port and CPython, with "
                        "RP2040 figures estimated as unix x 70; rp2040: also every device figure "
                        "on the emulated RP2040 (MicroPython's Pico firmware on rp2040js: cycles "
                        "and emulated ms of the per-sample paths, each fit's whole time and worst "
                        "slice, import time, free heap) beside the unix port's, with their ratios "
                        "(a few minutes more), and CircuitPython's (Feather RP2040 firmware) beside "
                        "them, or a line saying why not; its fit figures replace the estimates; "
                        "rp2040-romfs: rp2040's MicroPython figures and beside them the same "
                        "firmware built with a ROMFS partition, the package run in place from "
                        "/rom (firmware/micropython-rp2040-romfs; a line saying why not where it "
                        "is missing); "
                        "circuitpython: the chip's figures on CircuitPython only (MicroPython's "
                        "RP2040 figures stay the unix x 70 estimates)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_bench)

