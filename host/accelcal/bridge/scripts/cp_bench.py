# What the device package costs on CircuitPython (the Feather RP2040 firmware on the emulated
# chip; bridge/rp2040.py runs it, studies/cp_bench.py reads it): "key value" lines.
# CircuitPython has no micropython.heap_lock: allocation is counted with the collector off
# (gc.disable(), gc.mem_alloc() before and after).  Times are time.monotonic_ns() differences,
# read outside every counted window (each read allocates a long).  The host puts the fit's 72
# points (Q16 g, flat) in place of PTS, and WHOLE = False where the whole fit's time is not wanted
# (the fit again in one go: 1.3 s of the chip's time).
import gc
import time

gc.collect()
_t0 = time.monotonic_ns()
import acal.logger.app  # noqa: E402
_import_ns = time.monotonic_ns() - _t0

from array import array  # noqa: E402
from acal.logger.app import Processor  # noqa: E402
from acal.core.gaussnewton import GaussNewton  # noqa: E402
from acal.core.calibration import Calibration  # noqa: E402
from acal.core.rest import RestDetector, ALL_AXES, AUTO  # noqa: E402

PTS = None
WHOLE = True
N = 1000
LARGEST = ("base+temp_offset+temp_scale+drift+nonlinear", "base+temp_offset+temp_scale+drift+step")


def report(key, value):
    print(key, value)


def free_after_collect():
    gc.collect()
    return gc.mem_free()


report("free_after_import_app", free_after_collect())
report("import_app_ms", _import_ns // 1000000)

# samples, Q10 g: 200-sample stretches alternately still (+-3 LSB about (0.1, -0.2, 0.97) g) and
# swinging across +-2 g (an LCG), so the detectors open and close segments
buf = array("i", [0] * (3 * N))
_s = 7
for _i in range(3 * N):
    _s = (_s * 1103515245 + 12345) & 0x7FFFFFFF
    if (_i // 600) % 2:
        buf[_i] = (_s >> 8) % 4001 - 2000
    else:
        buf[_i] = (102, -205, 993)[_i % 3] + (_s >> 16) % 7 - 3
out = array("i", [0] * (3 * N))
paper = RestDetector(100, 5)
wear = RestDetector(100, 5, AUTO, ALL_AXES)
cals = []
for _r in (2, 4, 8, 16):  # parameters at the bounds' corner, every full scale
    _c = Calibration(range_g=_r)
    _c.set([20971520, 20971520, 20971520, 2097152, 2097152, 2097152, 4194304, 4194304, 4194304])
    cals.append(_c)
fit = GaussNewton(72)
slices = array("i", [0, 0, 0, 0])   # count, worst ns, bytes in the worst slice, bytes in all
counted = array("i", [0, 0])        # bytes, ns of the last measure()


def feed(det):
    start = 0
    n = N
    while n > 0:
        used = det.add_samples(buf, start, n)
        start += used
        n -= used


def detect_paper():
    feed(paper)


def detect_wear():
    feed(wear)


def apply_all():
    for cal in cals:
        for i in range(3 * N):
            out[i] = buf[i] * 16   # past every full scale too: clamped
        cal.apply_samples(out, 0, N)


def begin_fit():
    fit.begin(PTS, 72)


def control():
    return [0, 0, 0, 0]


def measure(fn):
    gc.collect()
    gc.disable()
    t0 = time.monotonic_ns()
    m = gc.mem_alloc()
    fn()
    used = gc.mem_alloc() - m
    counted[1] = time.monotonic_ns() - t0
    gc.enable()
    counted[0] = used


def fit_in_slices():
    # one gc-off window per slice (as the app runs them), each timed
    while True:
        gc.collect()
        gc.disable()
        t0 = time.monotonic_ns()
        m = gc.mem_alloc()
        done = fit.step()
        used = gc.mem_alloc() - m
        dt = time.monotonic_ns() - t0
        gc.enable()
        slices[0] += 1
        slices[3] += used
        if dt > slices[1]:
            slices[1] = dt
        if used > slices[2]:
            slices[2] = used
        if done:
            return


measure(control)
report("bytes_control_list", counted[0])   # the counting sees an allocation
for name, fn in (("paper", detect_paper), ("wear", detect_wear)):
    measure(fn)
    report("bytes_rest_" + name, counted[0])
    report("rest_%s_ns_per_sample" % name, counted[1] // N)
report("rest_segments", "%d %d" % (paper.segments, wear.segments))
measure(apply_all)
report("bytes_apply", counted[0])
measure(begin_fit)
report("bytes_fit_begin", counted[0])
t_begin = counted[1]
fit_in_slices()
report("fit_wear_slices", slices[0])
report("fit_wear_worst_slice_us", slices[1] // 1000)
report("bytes_fit_worst_slice", slices[2])
report("bytes_fit_all_slices", slices[3])
report("fit_wear_status", "%d %d %d" % (fit.status, fit.iterations, fit.rejected))
report("fit_wear_params", " ".join(str(v) for v in fit.p[:9]))
fit = None
cals = None
if WHOLE:
    _t0 = time.monotonic_ns()
    fit = GaussNewton(72)
    fit.run(PTS, 72)
    report("fit_wear_whole_ms", (time.monotonic_ns() - _t0) // 1000000)
    fit = None
buf = None
out = None
report("free_before_processor", free_after_collect())
for model in LARGEST:
    proc = Processor(None, 100, model=model)
    report("free_with_processor " + model, free_after_collect())
    proc = None
