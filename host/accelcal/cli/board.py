"""Boards: `board virtual`, `deploy`, `acquire`, `pull` and `replay` (a pulled capture through the
current device modules)."""
from __future__ import annotations

import json
import sys

from acal.core.fixed import PARAM_NAMES
from accelcal.cli.options import COMMANDS, add_effects_arg, float_in, int_in, register_effects
from accelcal.errors import InputError


def cmd_board_virtual(args) -> int:
    import signal
    from accelcal.board.virtual import serve_until, start_virtual
    say = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    board, flash = start_virtual(flash_dir=args.flash, stimulus=args.stimulus, days=args.days,
                                 rate=args.rate, seed=args.seed, bus_faults=args.bus_faults,
                                 heap=args.heap, speed=args.speed, link=args.link,
                                 port_file=args.port_file, chip=args.chip, bus=args.bus, say=say)
    print(board.port, flush=True)
    what = "emulated Pico (RP2040, MicroPython firmware)" if args.chip == "rp2040" else "virtual board"
    say(f"{what} on {board.port} (flash {flash.resolve()}); try: mpremote connect "
        f"{board.port} exec \"import sys; print(sys.platform)\"; Ctrl-C stops it")
    stopping = []
    signal.signal(signal.SIGTERM, lambda *a: stopping.append(1))
    serve_until(board, args.link, lambda: bool(stopping))
    return 0


def _app_settings(args) -> dict:
    from acal.core import profile as dprofile
    s = {"rate_hz": args.rate, "profile": dprofile.parse(args.profile)}
    if args.capture_kb:
        s["capture_bytes"] = args.capture_kb * 1024
    if args.registers:
        if args.fifo:
            raise InputError("--fifo and --registers: one reader, not both")
        s["fifo"] = False
    if args.recal_hours is not None:
        s["recal_seconds"] = int(args.recal_hours * 3600)
    if args.bus is not None:
        s["bus"] = args.bus
    if args.discover:
        if args.profile != "wear" or args.model != "base":
            raise InputError("--discover: the board discovers from the wear profile's base model "
                             f"(given --profile {args.profile} --model {args.model})")
        s["discover"] = True
    if args.model != "base":
        from accelcal.model.effects import ModelSpec
        register_effects(args)
        try:
            spec = ModelSpec.parse(args.model)
            s["model"] = spec.device_model   # ValueError: an effect the board does not have
            from acal.core import effects as deff
            if deff.STEP in spec.kinds and args.profile != "wear":
                raise ValueError(f"model {spec}: a step's time is found by the wear profile's "
                                 "fit; the paper profile has no search for it")
        except ValueError as e:
            raise InputError(str(e)) from None
    return s


def _warn_slow_reader(args) -> None:
    """One line before the board starts when its reader cannot keep up (measured)."""
    if args.registers:
        print(f"accelcal: warning: --registers at {args.rate} Hz: the app reads a sample a period "
              "and falls behind, losing samples (the emulated Pico: 1 in 200 at 10 Hz, 76 in 1000 "
              "at 100 Hz; docs/boards-and-logs.md); the FIFO, the default, loses none",
              file=sys.stderr)


def _app_options(args) -> dict:
    """The app options as given (the "app settings" group), what deploy records on the board."""
    return {dest: getattr(args, dest) for dest in args.app_flags}


def cmd_deploy(args) -> int:
    from accelcal.board import deploy
    settings = _app_settings(args)
    _warn_slow_reader(args)
    r = deploy.deploy(args.port, args.board, settings, write_main=not args.no_main,
                      say=lambda m: print(m, file=sys.stderr), units=args.units,
                      options=_app_options(args))
    print(json.dumps(r) if args.json else
          f"deployed to {r['port']}: board {r['board']} ({r['platform']}), {r['modules']} modules as "
          f".{r['format']} ({', '.join(r['units'])})"
          + (", main.py starts logging at power-up" if r["main_py"] else "")
          + ("; boot.py makes the drive writable to the app and read-only to the computer from "
             "the next power-up" if r["boot_py"] else ""))
    return 0


def cmd_acquire(args) -> int:
    import argparse
    from accelcal.board import deploy, settings
    given = _app_options(args)
    # the options given, checked before the board is touched (the defaults for those not given)
    _app_settings(argparse.Namespace(**{**vars(args), **{
        d: args.app_defaults[d] if v is None else v for d, v in given.items()}}))

    def resolve(recorded: dict | None) -> dict:
        """The settings deploy recorded on the board (None: a board deployed before they were
        recorded), an app option given here checked against them; acal.logger.app.main's arguments."""
        for dest, value in settings.resolve(given, args.app_defaults, args.app_flags, recorded,
                                            args.port).items():
            setattr(args, dest, value)
        app = _app_settings(args)
        _warn_slow_reader(args)
        return app

    deploy.acquire(args.port, int(args.hours * 3600), resolve,
                   say=lambda m: print(m, file=sys.stderr, flush=True))
    return 0


def cmd_pull(args) -> int:
    from accelcal.board import deploy
    from tqdm import tqdm
    # a bar for a person watching (a terminal): bytes, rate and time left as measured so far
    with tqdm(unit="B", unit_scale=True, desc="pull", file=sys.stderr, leave=False,
              disable=not sys.stderr.isatty()) as bar:
        def progress(done, total):
            bar.total = total
            bar.update(done - bar.n)
        s = deploy.pull(args.port, args.output, say=lambda m: print(m, file=sys.stderr),
                        force=args.force, progress=progress)
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
        vals = " ".join(f"{n}={cal[n]:+.4f}" for n in PARAM_NAMES)
        print(f"  calibration {cal['number']} at sample {cal['index']}: {cal['status']}, "
              f"{cal['iterations']} iterations, {cal['points']} points: {vals}")
        for name, e in cal.get("effects", {}).items():
            vals = " ".join(f"{n}={v:+.4g}" for n, v in e["params"].items())
            where = (f"{e['ref_time_s']} s of running time" if "ref_time_s" in e else
                     f"step at {e['step_time_s']} s of running time" if "step_time_s" in e else
                     f"supply {e['ref_supply_mv']} mV")
            print(f"    + {name} ({e['unit']}): {vals}; reference {e['ref_temp']:g} degC, {where}")
    from accelcal.pipeline.results import board_discovery_line
    for d in s.get("discoveries", []):
        print("  " + board_discovery_line(d))
    if s.get("deployed"):
        from accelcal.pipeline.results import deployed_line
        print("  " + deployed_line(s["deployed"]))
    if s["stored_calibration"]:
        print(f"  stored calibration: number {s['stored_calibration']['number']} (slot {s['stored_calibration']['slot']})")
    for d in s["dropped"]:
        print("  " + d)


def cmd_replay(args) -> int:
    from accelcal.bridge import boardlog
    r = boardlog.replay(args.dir, args.profile)
    if args.json:
        print(json.dumps(r))
    else:
        how = f", with the {args.profile} profile's settings" if args.profile else ""
        print(f"replayed {r['samples_replayed']} samples of {args.dir}/capture.bin through the current "
              f"device modules{how}")
        for k in ("rest", "cal", "effect", "discovery"):
            d = r[k]
            if k in ("effect", "discovery") and not d["board"] and not d["replay"]:
                continue  # the paper's model, a board that does not discover: no such records
            first = "" if d["first_difference"] is None else f", first difference at record {d['first_difference']}"
            print(f"  {k:4s}: board {d['board']}, replay {d['replay']}, differing {d['differ']}{first}")
        print("identical" if r["identical"] else
              "DIFFERENT: " + (f"the {args.profile} profile parts from what the board did" if args.profile
                               else "the device code no longer does what the board did"))
    return 0 if r["identical"] else 1


def _add_virtual(bsub) -> None:
    q = bsub.add_parser("virtual", help="start the virtual board on a pseudo-terminal",
                        description="The MicroPython unix port on a pseudo-terminal, a folder as its "
                                    "flash, a simulated LIS3DH behind a fake machine.I2C fed by a "
                                    "stimulus (a simulated wrist day unless --stimulus), virtual time. "
                                    "With --chip rp2040, an emulated Pico instead: the RP2040 running "
                                    "MicroPython's own firmware, its USB serial on the pty, the LIS3DH "
                                    "on its I2C bus, a flash image file as its flash. "
                                    "Prints the port on stdout; then any `mpremote connect PORT ...` works. "
                                    "Runs until Ctrl-C or SIGTERM.")
    q.add_argument("--chip", choices=["unix", "rp2040"], default="unix",
                   help="unix (default): the MicroPython unix port; rp2040: an emulated Pico, "
                        "MicroPython's own RPI_PICO firmware on rp2040js with the simulated LIS3DH "
                        "on its I2C0 (make setup installs it), on its emulated clock")
    q.add_argument("--flash", help="the board's flash: a folder for the unix port (default "
                                   "vboard-flash), a 2 MB image file for rp2040 (default "
                                   "vboard-pico.bin, made on first use, saved when the board "
                                   "stops; an existing file must be such an image by its "
                                   "content: the RP2040 boot stage, else it is refused)")
    q.add_argument("--stimulus", help="stimulus file (from `simulate wrist --stimulus`)")
    q.add_argument("--days", type=float_in(0, 3650, lo_open=True), default=1.0,
                   help="without --stimulus: days to simulate (default 1)")
    q.add_argument("--rate", type=int, choices=[10, 25, 50, 100], default=25,
                   help="without --stimulus: Hz (default 25)")
    q.add_argument("--seed", type=int_in(0, 2 ** 32 - 1), default=1)
    q.add_argument("--bus-faults", type=int_in(0, 1000), default=0, metavar="PER_MILLE",
                   help="share of I2C transactions that fail, per mille (default 0)")
    q.add_argument("--bus", choices=["i2c", "spi"], default="i2c",
                   help="where the LIS3DH is wired (default i2c): with --chip rp2040 on I2C0 "
                        "(GP4/GP5) or on SPI0 (GP18 SCK, GP19 MOSI, GP16 MISO, GP17 CS) only, as "
                        "boards/pico.py has them; the unix port's chip answers on both, and this "
                        "is its board file's BUS (ACCELCAL_BUS)")
    q.add_argument("--heap", help="MicroPython heap size, e.g. 160k (an RP2040's)")
    q.add_argument("--speed", type=int_in(0, 10000), default=0, help="0: as fast as possible (default); N: N x real time")
    q.add_argument("--link", help="also make this symlink to the port")
    q.add_argument("--port-file", help="also write the port to this file")
    q.set_defaults(func=cmd_board_virtual)


BUS_HELP = ("the LIS3DH's bus (default: the board file's BUS; the Pico's and the Feather's: auto, "
            "SPI where the chip answers there, else I2C); SPI keeps the board awake under a third "
            "as long at 100 Hz (docs/boards-and-logs.md)")


def add_parsers(sub) -> None:
    p = sub.add_parser("board", help=COMMANDS["board"][1], description="Board tools.")
    bsub = p.add_subparsers(dest="what", required=True, metavar="WHAT")
    _add_virtual(bsub)

    def app_args(q, recorded=False):
        """The app settings; recorded: acquire's, whose options default to what deploy
        recorded on the board (given, they must agree with it)."""
        g = q.add_argument_group("app settings" + (" (default: as deployed; given, they must "
                                                   "agree with what deploy recorded)" if recorded else ""))
        g.add_argument("--rate", type=int, choices=[10, 25, 50, 100, 200, 400], default=100,
                       help="output data rate, Hz (default 100)")
        g.add_argument("--capture-kb", type=int_in(0, 1 << 20), default=0,
                       help="also capture the raw samples, up to this many kB (for `accelcal replay`)")
        g.add_argument("--fifo", action="store_true", help="read the FIFO past its watermark (default)")
        g.add_argument("--registers", action="store_true", help="read the output registers (warned: loses samples)")
        g.add_argument("--bus", choices=["auto", "spi", "i2c"], help=BUS_HELP)
        g.add_argument("--recal-hours", type=float_in(0, 8760, lo_open=True), help="least time between calibrations (default 6)")
        g.add_argument("--model", default="base",
                       help="the model the board fits and applies: base (the paper's) or a composed "
                            "one such as base+temp_offset (what `accelcal diagnose` named); a "
                            "declared effect (--effects) runs as the device kind of its shape")
        add_effects_arg(g)
        g.add_argument("--profile", choices=["wear", "paper"], default="wear",
                       help="wear (default): all-axis rest against the measured noise, 72 points, "
                            "Gauss-Newton with outlier rejection, sliced between FIFO reads; "
                            "paper: Farago 2024 to the letter")
        g.add_argument("--discover", action="store_true",
                       help="the board finds its own missing effect: after each calibration it fits "
                            "every effect of its catalogue, scores them on rest points of held-out "
                            "2-hour blocks, adopts one by diagnose's rule and logs a DISCOVERY "
                            "record (wear profile, base model)")
        acts = g._group_actions
        q.set_defaults(app_flags={a.dest: a.option_strings[0] for a in acts},
                       app_defaults={a.dest: a.default for a in acts})
        if recorded:
            for a in acts:
                a.default = None

    p = sub.add_parser("deploy", help=COMMANDS["deploy"][1],
                       description="With mpremote: the device package into :lib/acal (as .mpy built by "
                                   "mpy-cross where the board's architecture is known), the board file "
                                   "as :acal_board.py, and a main.py that starts the app at power-up "
                                   "with the app settings given here; on a CircuitPython board also "
                                   "a boot.py that makes its drive writable to the app (and read-only "
                                   "to the computer) from the next power-up, unless it has its own.")
    p.add_argument("--port", required=True, help="serial port (or the virtual board's pty)")
    p.add_argument("--board", help="board file name (default: from the board's sys.platform)")
    p.add_argument("--no-main", action="store_true", help="do not write main.py")
    p.add_argument("--units", choices=["all", "run"], default="all",
                   help="the device package's install units to copy: all (default: core, logger, "
                        "paper, discover) or run: those the app settings given here run (core and "
                        "logger; paper with --profile paper; discover with --discover), so the "
                        "board holds no code it does not load (acquire then needs the same settings)")
    p.add_argument("--json", action="store_true")
    app_args(p)
    p.set_defaults(func=cmd_deploy)

    p = sub.add_parser("acquire", help=COMMANDS["acquire"][1],
                       description="Runs acal.logger.app.main(seconds=...) on the board with mpremote exec and "
                                   "shows its hourly progress lines.")
    p.add_argument("--port", required=True)
    p.add_argument("--hours", type=float_in(0, 87600, lo_open=True), required=True, help="hours of board time")
    app_args(p, recorded=True)
    p.set_defaults(func=cmd_acquire)

    p = sub.add_parser("pull", help=COMMANDS["pull"][1],
                       description="Copies log.bin, capture.bin, cal_a.bin, cal_b.bin into DIR, decodes "
                                   "them (records dropped by a power cut are reported) and writes "
                                   "DIR/summary.json.")
    p.add_argument("--port", required=True)
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="folder for the logs (made if missing; the files arrive whole or not at all)")
    p.add_argument("--force", action="store_true", help="replace an earlier pull in DIR: all of it (its files this board does not "
                        "hold are removed, so DIR holds this pull only)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_pull)

    p = sub.add_parser("replay", help=COMMANDS["replay"][1],
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

