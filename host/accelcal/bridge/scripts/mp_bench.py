# Benchmarks that run inside the MicroPython unix port (host/accelcal/studies/bench.py starts it)
# or on the emulated RP2040 (studies/bench_chip.py: the script's text with main(...) appended).
# Prints "key value" lines.  Input (the unix port): a file with 54 ints (18 points, Q16 g) on one
# line and the sample count.  Where the firmware has no micropython.mem_total (the RP2040's), the
# byte counts are left out; the heap_lock proofs are not.
import sys
import time
import micropython
from array import array

from acal.paper.optimiser import Optimiser
from acal.core.rest import RestDetector, ALL_AXES, AUTO


def samples(n):
    # A deterministic stream: rest at (0.1, -0.2, 0.97) g with +-3 LSB noise (an LCG), Q10 g.
    buf = array("i", [0] * (3 * n))
    s = 12345
    for i in range(3 * n):
        s = (s * 1103515245 + 12345) & 0x7FFFFFFF
        base = 102 if i % 3 == 0 else (-205 if i % 3 == 1 else 993)
        buf[i] = base + (s >> 16) % 7 - 3
    return buf


def bare(buf, n):  # reads each sample and does nothing else: the yardstick
    i = 0
    end = 3 * n
    while i < end:
        x = buf[i]
        y = buf[i + 1]
        z = buf[i + 2]
        i += 3


def detect(det, buf, n):
    start = 0
    while n > 0:
        used = det.add_samples(buf, start, n)
        start += used
        n -= used


def best_us(fn, repeat):
    best = 1 << 40
    for _ in range(repeat):
        t0 = time.ticks_us()
        fn()
        dt = time.ticks_diff(time.ticks_us(), t0)
        if dt < best:
            best = dt
    return best


def main(pts, n_samples, repeat):
    """repeat: timed runs of each, the shortest kept (1 on the deterministic emulator)."""
    counts = hasattr(micropython, "mem_total")
    opt = Optimiser(18)
    if repeat > 1:
        opt.run(pts, 18)  # warm-up
    t_opt = best_us(lambda: opt.run(pts, 18, 50), repeat + 2 if repeat > 1 else 1)
    print("optimiser_us", t_opt)
    print("optimiser_status", opt.status)
    if counts:
        m0 = micropython.mem_total()
        opt.run(pts, 18, 50)
        print("bytes_per_optimiser_run", micropython.mem_total() - m0)

    buf = samples(n_samples)
    det = RestDetector(100, 5)
    detect(det, buf, n_samples)
    t_bare = best_us(lambda: bare(buf, n_samples), repeat)
    t_det = best_us(lambda: detect(det, buf, n_samples), repeat)
    print("bare_us", t_bare)
    print("rest_us", t_det)
    if counts:
        per_sample_bytes(buf, n_samples)
    print("rest_heap_locked_ok", locked_ok(det, buf, n_samples))
    print("segments", det.segments)
    # The wear profile's detector: every axis, the threshold from the noise gauge.
    wear = RestDetector(100, 5, AUTO, ALL_AXES)
    detect(wear, buf, n_samples)
    print("rest_wear_us", best_us(lambda: detect(wear, buf, n_samples), repeat))
    print("rest_wear_heap_locked_ok", locked_ok(wear, buf, n_samples))
    print("rest_wear_threshold", wear.threshold)


def per_sample_bytes(buf, n_samples):
    # Bytes per sample as a slope: one call over n/2 and one over n samples, inside one long
    # segment, so both runs make the same calls.  A call itself may take a frame from the heap
    # (MicroPython does so for functions with many locals, frees it on return, and uses the C
    # stack instead when the heap is locked); that is reported per call.
    long_det = RestDetector(n_samples + 1, 1)
    half = n_samples // 2
    m0 = micropython.mem_total()
    long_det.add_samples(buf, 0, half)
    m1 = micropython.mem_total()
    long_det.reset()
    long_det.add_samples(buf, 0, n_samples)
    m2 = micropython.mem_total()
    print("bytes_half", m1 - m0)
    print("bytes_full", m2 - m1)


def locked_ok(det, buf, n):
    """1 when the detector takes the stream with the heap locked: the strict proof that it
    allocates nothing (any allocation raises MemoryError)."""
    ok = 1
    micropython.heap_lock()
    try:
        detect(det, buf, n)
    except MemoryError:
        ok = 0
    micropython.heap_unlock()
    return ok


if len(sys.argv) > 2:
    with open(sys.argv[1]) as fh:
        main([int(v) for v in fh.read().split()], int(sys.argv[2]), 5)
