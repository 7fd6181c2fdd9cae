"""`accelcal bench --runtime rp2040`: every device figure on the emulated RP2040 (MicroPython's
RPI_PICO firmware on rp2040js, the package as armv6m .mpy: bridge/rp2040.py) beside the unix
port's, measured in the same run.  The scripts are the unix port's (bridge/scripts/mp_bench.py,
mp_fit_bench.py, mp_paths_bench.py), sent to the chip as text with their main() call; they time
with time.ticks_us(), which on the chip follows the emulated clock: emulated µs, cycles = µs ×
125 (125 MHz).  The emulator models no XIP cache misses nor flash erase/program time (the boot
ROM's flash routines are done by the runner at no cost), so these are lower bounds for a Pico.

Keys (JSON): rp2040_emulated_* in emulated µs or ms; unix_* the unix port's, where bench.py's
own keys do not already carry it."""
from __future__ import annotations

import tempfile
from pathlib import Path

from accelcal.bridge import rp2040, runtime
from accelcal.locations import DEVICE_PACKAGE, script as mp_script

FIT_CASES = ("paper_base", "wear_base", "wear_temp_offset", "wear_four_effects")
CHIP_SAMPLES = 2000   # the rest detectors' stream on the chip: 24 kB of its 245 kB heap


def _kv(out: str) -> dict:
    return {k: int(v) for k, v in (line.split()[:2] for line in out.splitlines() if line.strip())}


def _on_chip(name: str, call: str) -> str:
    return rp2040.run_script(Path(mp_script(name)).read_text() + "\n" + call + "\n").out


def _unix_paths() -> dict:
    """mp_paths_bench.py on the unix port, with the package compiled to .mpy (x64) as on the
    chip, so that import times compare loading with loading, not compiling."""
    with tempfile.TemporaryDirectory() as tmp:
        pkg = Path(tmp) / "lib" / "acal"
        pkg.mkdir(parents=True)
        for src in sorted(DEVICE_PACKAGE.glob("*.py")):
            rp2040.mpy_cross(src, pkg / (src.stem + ".mpy"), "x64")
        work = Path(tmp) / "work"
        work.mkdir()
        return _kv(runtime.run_micropython_script(mp_script("mp_paths_bench.py"), str(work),
                                                  device_path=str(pkg.parent)))


def measure_chip(pts: list[int], n_samples: int = CHIP_SAMPLES) -> dict:
    """The chip's figures and the unix port's for those bench.py does not measure."""
    chip = _kv(_on_chip("mp_bench.py", f"main({pts!r}, {n_samples}, 1)"))
    paths = _kv(_on_chip("mp_paths_bench.py", "main('/', 1)"))
    unix_paths = _unix_paths()
    fits = {}
    for line in _on_chip("mp_fit_bench.py", "").splitlines():
        if line.strip():
            name, slices, worst, total, status, used = line.split()
            fits[name] = (int(slices), int(worst), int(total), int(status), int(used))
    res = {
        "rp2040_emulated_optimiser_ms": chip["optimiser_us"] / 1000,
        "rp2040_emulated_bare_us_per_sample": chip["bare_us"] / n_samples,
        "rp2040_emulated_rest_us_per_sample": chip["rest_us"] / n_samples,
        "rp2040_emulated_rest_wear_us_per_sample": chip["rest_wear_us"] / n_samples,
        "rp2040_emulated_rest_heap_locked_ok": bool(chip["rest_heap_locked_ok"]
                                                    and chip["rest_wear_heap_locked_ok"]),
        "rp2040_emulated_import_app_ms": paths["import_app_us"] / 1000,
        "rp2040_emulated_apply_base_us_per_sample": paths["apply_base_us_per_1000"] / 1000,
        "rp2040_emulated_apply_largest_us_per_sample": paths["apply_largest_us_per_1000"] / 1000,
        "rp2040_emulated_log_rest_ms_per_record": paths["log_rest_us_per_1000"] / 1e6,
        "rp2040_emulated_processor_us_per_sample": paths["processor_us_per_1000"] / 1000,
        "rp2040_emulated_heap_total_bytes": paths["heap_total"],
        "rp2040_emulated_heap_free_before_app_bytes": paths["heap_free_before_app"],
        "rp2040_emulated_heap_free_app_largest_bytes": paths["heap_free_app_largest"],
        "unix_import_app_mpy_ms": unix_paths["import_app_us"] / 1000,
        "unix_apply_base_us_per_sample": unix_paths["apply_base_us_per_1000"] / 1000,
        "unix_apply_largest_us_per_sample": unix_paths["apply_largest_us_per_1000"] / 1000,
        "unix_log_rest_ms_per_record": unix_paths["log_rest_us_per_1000"] / 1e6,
        "unix_processor_us_per_sample": unix_paths["processor_us_per_1000"] / 1000,
    }
    for name, (slices, worst, total, status, used) in fits.items():
        res[f"rp2040_emulated_fit_{name}_slices"] = slices
        res[f"rp2040_emulated_fit_{name}_total_ms"] = total / 1000
        res[f"rp2040_emulated_fit_{name}_worst_slice_ms"] = worst / 1000
        res[f"rp2040_emulated_fit_{name}_status"] = status
        if used >= 0:
            res[f"rp2040_emulated_fit_{name}_bytes"] = used
    return res


def rows(m: dict) -> list[tuple[str, float | None, float, str]]:
    """(figure, unix port, RP2040 emulated, unit) for the side-by-side table; times in the unit
    named, the unix port's None where it has no counterpart."""
    e = "rp2040_emulated_"
    out = [
        ("bare loop, per sample", m["bare_ns_per_sample_micropython"] / 1000,
         m[e + "bare_us_per_sample"], "us"),
        ("rest detector, paper profile, per sample", m["rest_ns_per_sample_micropython"] / 1000,
         m[e + "rest_us_per_sample"], "us"),
        ("rest detector, wear profile, per sample", m["rest_wear_ns_per_sample_micropython"] / 1000,
         m[e + "rest_wear_us_per_sample"], "us"),
        ("apply, base, per sample", m["unix_apply_base_us_per_sample"],
         m[e + "apply_base_us_per_sample"], "us"),
        ("apply, four effects, per sample", m["unix_apply_largest_us_per_sample"],
         m[e + "apply_largest_us_per_sample"], "us"),
        ("log append (rest record, flushed)", m["unix_log_rest_ms_per_record"],
         m[e + "log_rest_ms_per_record"], "ms"),
        ("app after acquisition, per sample", m["unix_processor_us_per_sample"],
         m[e + "processor_us_per_sample"], "us"),
        ("paper optimiser N=18 M=50", m["optimiser_ms_micropython"], m[e + "optimiser_ms"], "ms"),
    ]
    for name in FIT_CASES:
        if e + f"fit_{name}_total_ms" not in m:
            continue
        out.append((f"fit {name}, whole", m.get(f"fit_{name}_total_ms_unix"),
                    m[e + f"fit_{name}_total_ms"], "ms"))
        worst = m.get(f"fit_{name}_worst_slice_us_unix")
        out.append((f"fit {name}, worst slice", None if worst is None else worst / 1000,
                    m[e + f"fit_{name}_worst_slice_ms"], "ms"))
    out.append(("import acal.app (.mpy)", m["unix_import_app_mpy_ms"], m[e + "import_app_ms"], "ms"))
    return out


def format_chip(m: dict) -> str:
    e = "rp2040_emulated_"
    lines = ["", "emulated RP2040 (MicroPython RPI_PICO firmware on rp2040js, 125 MHz; lower bounds: "
             "no XIP cache misses, no flash erase/program time), beside the unix port, one run:",
             f"{'figure':<44}{'unix port':>12}{'RP2040 cycles':>15}{'RP2040':>12}{'ratio':>9}"]
    for name, unix, chip, unit in rows(m):
        us = chip * (1000 if unit == "ms" else 1)
        u = f"{unix:.4g} {unit}" if unix is not None else "-"
        ratio = f"{chip / unix:.0f}x" if unix else "-"
        lines.append(f"{name:<44}{u:>12}{round(us * rp2040.HZ / 1e6):>15,}{chip:>9.4g} {unit}{ratio:>9}")
    lines.append(f"{'heap: total / free before the app / free with App(' + 'four effects)':<44}"
                 f"{m[e + 'heap_total_bytes']:>12,} / {m[e + 'heap_free_before_app_bytes']:,} / "
                 f"{m[e + 'heap_free_app_largest_bytes']:,} bytes")
    alloc = [f"{n} {m[e + f'fit_{n}_bytes']}" for n in FIT_CASES if e + f"fit_{n}_bytes" in m]
    lines.append(f"{'bytes a fit allocates (32-bit firmware)':<44}{', '.join(alloc)}")
    lines.append(f"{'rest detectors allocate nothing (heap_lock)':<44}{m[e + 'rest_heap_locked_ok']}")
    return "\n".join(lines)
