"""`accelcal bench`: figures measured in one run (ratios within the run, not against constants).

optimiser_ms_micropython / optimiser_ms_cpython: the device optimiser, N=18, M=50, best of 7.
per_sample_ratio: rest detector per sample / a bare loop reading the same buffer (MicroPython).
bytes_per_sample: heap bytes per sample (MicroPython mem_total), the slope between a call over
  N/2 and one over N samples; bytes_per_detector_call: the frame MicroPython takes from the heap
  for a call with many locals (freed on return; on the C stack when the heap is locked, which
  rest_heap_locked_ok proves over the whole stream).
bytes_per_optimiser_run: the same per-call frames, one per objective evaluation (10 M + 1).
long_ints_per_optimiser_run_32bit: optimiser values >= 2**30 in one run, counted under CPython
with traced ints: each is a heap-allocated long on a 32-bit port (RP2040, ESP32)."""
from __future__ import annotations

import json
import sys
import tempfile
import timeit
from pathlib import Path

import numpy as np

from acal.bins import Bins
from acal.optimiser import Optimiser
from accelcal import runtime, simulate
from accelcal.io import g_to_point
from accelcal.ranges import Tracer, traced

BENCH_SAMPLES = 10000


def bench_points(seed=11) -> list[int]:
    """18 points selected by the device bins from one paper scenario (1 mg)."""
    rng = np.random.default_rng(seed)
    _, v = simulate.paper_scenario(rng, 300, 1e-3)
    b = Bins()
    for x, y, z in g_to_point(v).tolist():
        b.offer(x, y, z)
    out = [0] * 54
    n = b.gather(out)
    assert n == 18, "bench scenario did not fill the bins"
    return out


def measure() -> dict:
    pts = bench_points()
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "pts.txt"
        f.write_text(" ".join(map(str, pts)) + "\n")
        out = runtime.run_micropython_script(str(Path(__file__).with_name("mp_bench.py")),
                                             str(f), str(BENCH_SAMPLES))
    mp = {k: int(v) for k, v in (line.split() for line in out.splitlines() if line.strip())}
    opt = Optimiser(18)
    cp_s = min(timeit.repeat(lambda: opt.run(pts, 18, 50), number=1, repeat=7))
    tr = Tracer()
    T = traced(tr)
    Optimiser(18).run([T(v) for v in pts], 18, 50)
    return {
        "optimiser_ms_micropython": mp["optimiser_us"] / 1000.0,
        "optimiser_ms_cpython": cp_s * 1000.0,
        "per_sample_ratio": mp["rest_us"] / mp["bare_us"],
        "rest_ns_per_sample_micropython": 1000.0 * mp["rest_us"] / BENCH_SAMPLES,
        "bytes_per_sample": (mp["bytes_full"] - mp["bytes_half"]) / (BENCH_SAMPLES - BENCH_SAMPLES // 2),
        "bytes_per_detector_call": mp["bytes_half"],
        "rest_heap_locked_ok": bool(mp["rest_heap_locked_ok"]),
        "bytes_per_optimiser_run": mp["bytes_per_optimiser_run"],
        "long_ints_per_optimiser_run_32bit": tr.big,
        "int_ops_per_optimiser_run": tr.ops,
        "optimiser_max_abs_int_log2": round(float(np.log2(tr.max_abs)), 2),
    }


def bench_main(args) -> int:
    print("measuring (MicroPython unix port and CPython)...", file=sys.stderr)
    m = measure()
    if args.json:
        print(json.dumps(m))
        return 0
    targets = {"optimiser_ms_micropython": "<= 10 ms", "per_sample_ratio": "<= 4x",
               "bytes_per_sample": "0"}
    for k, v in m.items():
        t = targets.get(k, "")
        val = f"{v:.3f}" if isinstance(v, float) else str(v)
        print(f"{k:<36}{val:>14}   {t}")
    return 0
