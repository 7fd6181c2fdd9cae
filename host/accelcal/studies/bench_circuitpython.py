"""CircuitPython's figures for `accelcal bench --runtime rp2040|circuitpython`: Adafruit
CircuitPython 10.2.1 for the Feather RP2040 booted on the emulated RP2040 (bridge/rp2040.py), the
package installed as CircuitPython .mpy.  Measured, not estimated: emulated time at 125 MHz (no
XIP cache misses modelled: a lower bound for a real board).  Keys circuitpython_emulated_*, the
chip table's CircuitPython column (bench_chip.py):

From bridge/scripts/cp_bench.py (run(), cp_figures()): rest_*us_per_sample, a rest detector per
sample (paper: one axis; wear: every axis with the noise gauge), 1000 samples; default_fit_*, the
wear profile's Gauss-Newton fit of 72 points with two outliers, slice by slice as the app runs it
(status, iterations, rejected, slices, bytes in its worst slice); free_after_import_app_bytes and
free_with_processor_largest_bytes, gc.mem_free() after a collection, after `import acal.logger.app` and
with a Processor (the app's pipeline, bins, calibration) of the larger of the largest models (four
effects); bytes_per_sample_and_fit, allocated with the collector off (CircuitPython has no
heap_lock) over the detectors' stream, the apply at every full scale and the fit: 0 where nothing
is allocated (bytes_control_list shows the counting sees an allocation).
From MicroPython's chip scripts run there (mp_paths_bench.py, mp_fit_bench.py: bench_chip.
paths_and_fits; mp_discover_bench.py's rounds(): bench_chip.discovery_rounds, without its
heap_lock variant): the same keys as rp2040_emulated_*'s, so each sits beside MicroPython's."""
from __future__ import annotations

import numpy as np

from accelcal import simulate
from accelcal.bridge import rp2040
from accelcal.locations import script
from accelcal.studies import bench_chip

FIT_POINTS = 72
TRUTH = (1.03, 0.98, 1.01, 0.02, -0.01, 0.015, 0.05, -0.03, 0.04)


def fit_points(seed: int = 5) -> list[int]:
    """72 rest means (Q16 g, flat) of a sensor with errors, 1 mg noise and two outliers."""
    rng = np.random.default_rng(seed)
    v = simulate.uncorrect(np.array(TRUTH), simulate.unit_points(rng, FIT_POINTS))
    v = v + rng.normal(scale=1e-3, size=v.shape)
    v[5] *= 1.2
    v[40] *= 0.85
    return [int(x) for x in np.round(v * 65536).astype(np.int64).ravel()]


def run(points: list[int] | None = None, whole: bool = True) -> dict:
    """cp_bench.py's lines as a dict (ints where a value is one int, else the text); whole:
    also time the fit in one go."""
    pts = fit_points() if points is None else points
    with open(script("cp_bench.py")) as fh:
        code = fh.read().replace("PTS = None", f"PTS = array(\"i\", {pts!r})", 1)
    if not whole:
        code = code.replace("WHOLE = True", "WHOLE = False", 1)
    out = rp2040.run_script(code, fw=rp2040.CIRCUITPYTHON).out
    res: dict = {}
    for line in out.splitlines():
        if line.startswith("free_with_processor "):
            key, model, value = line.split()
            res[f"free_with_processor_{model}"] = int(value)
            continue
        key, _, value = line.partition(" ")
        res[key] = int(value) if value.lstrip("-").isdigit() else value
    return res


# CircuitPython's drive is read-only to code until remounted (a board does it in boot.py): the
# paths' log appends write a file
REMOUNT = "import storage\nstorage.remount('/', readonly=False)\n"


def cp_figures(r: dict) -> dict:
    """cp_bench.py's results (run()) as the bench's keys: per-sample rest detectors, free heap,
    the default fit's status and the bytes allocated per sample and fit slice."""
    e = bench_chip.CP
    free_models = [v for k, v in r.items() if k.startswith("free_with_processor_")]
    status, iterations, rejected = map(int, r["fit_wear_status"].split())
    res = {
        e + "rest_us_per_sample": r["rest_paper_ns_per_sample"] / 1000,
        e + "rest_wear_us_per_sample": r["rest_wear_ns_per_sample"] / 1000,
        e + "default_fit_status": status,
        e + "default_fit_iterations": iterations,
        e + "default_fit_rejected": rejected,
        e + "default_fit_slices": r["fit_wear_slices"],
        e + "default_fit_worst_slice_bytes": r["bytes_fit_worst_slice"],
        e + "free_after_import_app_bytes": r["free_after_import_app"],
        e + "free_with_processor_largest_bytes": min(free_models),
        e + "bytes_per_sample_and_fit": sum(v for k, v in r.items()
                                            if k.startswith("bytes_") and k != "bytes_control_list"),
        e + "bytes_control_list": r["bytes_control_list"],
    }
    if "fit_wear_whole_ms" in r:
        res[e + "default_fit_whole_ms"] = r["fit_wear_whole_ms"]
    return res


def measure() -> dict:
    """The figures `accelcal bench` prints for CircuitPython (keys circuitpython_emulated_*):
    cp_bench.py's, and the MicroPython chip's scripts (mp_paths_bench.py, mp_fit_bench.py) on
    CircuitPython, so that each path and fit sits beside MicroPython's."""
    res = cp_figures(run(whole=False))
    res.update(bench_chip.paths_and_fits(rp2040.CIRCUITPYTHON, bench_chip.CP, REMOUNT))
    res.update(bench_chip.discovery_rounds(rp2040.CIRCUITPYTHON, bench_chip.CP))
    return res
