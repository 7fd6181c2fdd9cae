# `accelcal bench`: Bins.offer's time a call, under the MicroPython unix port or on the emulated
# RP2040 (host/accelcal/studies/bench_chip.py runs it on both; studies/bench_circuitpython.py on
# CircuitPython).  A script of its own, so that its bytecode and arrays leave mp_paths_bench.py's
# heap figures as they were.  argv (the unix port): the repeats; on the chip main(1) is appended.
# Prints "bins_offer_us_per_1000": full bins of the wear profile's size (8 a subset, 72 points)
# with all three conditions tracked, as a discovering board's, N_OFFER rest means after the
# N_OFFER that filled them, near the axes at spread conditions (an LCG), the best of the repeats.
import sys
import time
from array import array

N_OFFER = 200

# CircuitPython has no ticks_us: monotonic_ns, whose read allocates a long (nothing here counts bytes)
ticks = getattr(time, "ticks_us", None) or (lambda: time.monotonic_ns() // 1000)


def us(t0):
    t = ticks()
    return time.ticks_diff(t, t0) if hasattr(time, "ticks_diff") else t - t0


def rest_means(n):
    """n rest means and their conditions, flat: x y z (Q16 g) temp (Q2 degC) time (64 s) mV."""
    pts = array("i", bytearray(4 * 6 * n))
    s = 12345
    for i in range(n):
        for c in range(6):
            s = (s * 1103515245 + 12345) & 0x7FFFFFFF
            pts[6 * i + c] = s >> 8
        r = pts[6 * i]
        for c in range(3):      # one axis near +-1 g, the others within +-0.15 g
            pts[6 * i + c] = (pts[6 * i + c] % 20000) - 10000
        pts[6 * i + r % 3] = (1 if r & 8 else -1) * (55000 + (r >> 4) % 20000)
        pts[6 * i + 3] = 80 + pts[6 * i + 3] % 80      # 20-40 degC, Q2
        pts[6 * i + 4] = 7 * i
        pts[6 * i + 5] = 3900 + pts[6 * i + 5] % 300    # mV
    return pts


def main(repeat):
    from acal.core import bins
    b = bins.Bins(2, 8, policy=bins.CENTRE, coverage=True, differs=bins.DIFFERS)
    pts = rest_means(2 * N_OFFER)
    c = bins.conditions(1)   # the conditions now, written as the board writes them
    for i in range(N_OFFER):
        j = 6 * i
        c[0], c[1], c[2] = pts[j + 3], pts[j + 4], pts[j + 5]
        b.offer(pts[j], pts[j + 1], pts[j + 2], c)
    best = 1 << 40
    for _ in range(repeat):
        t0 = ticks()
        for i in range(N_OFFER, 2 * N_OFFER):
            j = 6 * i
            c[0] = pts[j + 3]
            c[1] = pts[j + 4]
            c[2] = pts[j + 5]
            b.offer(pts[j], pts[j + 1], pts[j + 2], c)
        best = min(best, us(t0))
    print("bins_offer_us_per_1000", best * 1000 // N_OFFER)


if len(sys.argv) > 1:
    main(int(sys.argv[1]))
