# `accelcal bench`: the fit's slices timed under MicroPython
# (docs/method-and-formats.md "Sliced fit").  Runs in
# the MicroPython unix port (and CPython: time.perf_counter_ns stands in for ticks_us).
# For each case: the pipeline's fit from begin_fit() to its end, one fit_step() at a time, RUNS
# times (begin_fit, which gathers the points, timed as the first slice); prints "name slices worst_us total_us status bytes" (worst: the longest slice, each
# slice's time the shortest of the runs; total: the shortest run; bytes: heap allocated by the
# first whole fit, the collector held off: on a 32-bit port every int past 2**30 would be one;
# the fits keep every value below it, so 0 there).
# On the emulated RP2040 (studies/bench_chip.py sends this text): one run, as the emulator is
# deterministic; under CircuitPython too (studies/bench_circuitpython.py), its slices timed to
# the millisecond.
import gc
import sys
import time
from array import array

from acal.core import effects
from acal.core.pipeline import Pipeline
from acal.core.fixed import C_TEMP, C_TIME
from acal.core.profile import PAPER, WEAR, settings

try:
    ticks = time.ticks_us
    diff = time.ticks_diff
except AttributeError:
    try:   # CircuitPython: its ms counter (wraps at 2**29), as the app's clock there: no allocation
        from supervisor import ticks_ms as ticks   # (monotonic_ns would be counted as a fit's bytes)

        def diff(a, b):
            return ((a - b) & 0x1FFFFFFF) * 1000
    except ImportError:   # CPython
        def ticks():
            return time.perf_counter_ns() // 1000

        def diff(a, b):
            return a - b

_seed = [4321]


def rnd(m):
    _seed[0] = (_seed[0] * 1103515245 + 12345) & 0x7FFFFFFF
    return (_seed[0] >> 8) % (2 * m + 1) - m


def isqrt(v):
    x = v
    y = (x + 1) // 2
    while y < x:
        x = y
        y = (x + v // x) // 2
    return x


def point(one, temp=20):
    # a random direction of length `one` read by one sensor: +2, -2, +1 % scale, offsets of
    # +40, -25, +55 mg, a temperature offset of 0.5, -0.3, 0.4 mg/degC from 20 degC and +-1 mg
    # of noise (a sensor the composed models fit, not noise they chase out of their bounds)
    while True:
        x = rnd(1000)
        y = rnd(1000)
        z = rnd(1000)
        n2 = x * x + y * y + z * z
        if 10000 < n2 <= 1000000:
            break
    n = isqrt(n2)
    dT = temp - 20
    return ((x * one // n) * 102 // 100 + (40000 + 500 * dT + rnd(1000)) * one // 1000000,
            (y * one // n) * 98 // 100 + (-25000 - 300 * dT + rnd(1000)) * one // 1000000,
            (z * one // n) * 101 // 100 + (55000 + 400 * dT + rnd(1000)) * one // 1000000)


CHIP = sys.platform in ("rp2", "RP2040")   # MicroPython's, CircuitPython's
RUNS = 1 if CHIP else 3
_best = array("i", [0] * (2000 if CHIP else 8000))   # slices: < 1000 in every case


def case(name, prof, kinds):
    # The fit is deterministic: run it RUNS times from the same points and keep each slice's
    # shortest time, so that an interruption of the process in one run does not count.
    total_best = 0
    used = 0
    status = 0
    slices = 0
    for run in range(RUNS):
        _seed[0] = 4321
        s = settings(prof, bool(kinds))   # a composed model: its own bins (126 points, wear)
        pipe = Pipeline(100, kinds=kinds, **s)
        for i in range(4000):
            pipe.now[C_TEMP] = 20 + (i % 17)
            pipe.now[C_TIME] = i
            x, y, z = point(65536, pipe.now[C_TEMP])
            pipe.offer(x, y, z)
            if pipe.bins.total() >= 9 * pipe.bins.max_count:
                break
        gc.collect()
        gc.disable()
        m0 = gc.mem_alloc()
        total = 0
        slices = 0
        done = False
        while True:
            t0 = ticks()
            if slices:
                done = pipe.fit_step()
            else:   # begin_fit (gathering the points) counted as the first slice
                pipe.begin_fit()
            dt = diff(ticks(), t0)
            total += dt
            if slices < len(_best) and (run == 0 or dt < _best[slices]):
                _best[slices] = dt
            slices += 1
            if done:
                break
        if run == 0:
            used = gc.mem_alloc() - m0
        gc.enable()
        status = pipe.optimiser.status
        if run == 0 or total < total_best:
            total_best = total
    worst = 0
    for i in range(min(slices, len(_best))):
        if _best[i] > worst:
            worst = _best[i]
    print(name, slices, worst, total_best, status, used)


case("paper_base", PAPER, ())
case("wear_base", WEAR, ())
case("wear_temp_offset", WEAR, (effects.TEMP_OFFSET,))
case("wear_four_effects", WEAR, (effects.TEMP_OFFSET, effects.TEMP_SCALE, effects.DRIFT,
                                  effects.NONLINEAR))
