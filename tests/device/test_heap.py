"""Under the real MicroPython interpreter with the heap locked (any allocation raises), the rest
detectors of both profiles (the paper's one-axis test; every axis with the noise gauge) take
10 000 samples and both fits (the paper's gradient descent, the wear profile's Gauss-Newton with
outlier rejection, 72 points) a full run: they allocate nothing (64-bit port); and on the 32-bit
port (ints past 2^30 are longs there) the per-sample paths and both profiles' fits."""
import numpy as np

from accelcal.bridge import runtime
from conftest import heap_locked

STREAM = r'''
import micropython
from array import array


def stream(n, block):
    """n samples, Q10 g: blocks of `block` alternately at rest (+-4 LSB) and across +-2 g."""
    buf = array("i", [0] * (3 * n))
    s = 1
    for i in range(3 * n):
        s = (s * 1103515245 + 12345) & 0x7FFFFFFF
        buf[i] = (-2097 + (s >> 8) % 4194) if (i // block) % 2 else (1000 + (s >> 8) % 9 - 4)
    return buf


def feed(d, buf, n):  # locals only: a new module global would itself allocate
    start = 0
    while n > 0:
        used = d.add_samples(buf, start, n)
        start += used
        n -= used
'''

SCRIPT = STREAM + r'''
from acal.core.rest import RestDetector
from acal.paper.optimiser import Optimiser
from acal.core.pipeline import Pipeline
from acal.core.rest import ALL_AXES, AUTO
from acal.core.gaussnewton import GaussNewton
from acal.core.profile import WEAR, settings

N = 10000
buf = stream(N, 1500)
det = RestDetector(100, 5)
pipe = Pipeline(100)
pts = []
for k in range(18):
    a = [0, 0, 0]
    a[k % 3] = 65536 if (k // 3) % 2 else -65536
    a[(k + 1) % 3] = 3000 * k
    pts += a
opt = Optimiser(18)
wear_det = RestDetector(100, 5, AUTO, ALL_AXES)
wear_pipe = Pipeline(100, **settings(WEAR))
gpts = []
for k in range(72):
    a = [0, 0, 0]
    a[k % 3] = 65536 if (k // 3) % 2 else -65536
    a[(k + 1) % 3] = 900 * k - 30000
    a[(k + 2) % 3] = 500 * (k % 7)
    gpts += a
gpts = array("i", gpts)   # as the pipeline hands them over (the fit's viper loads read an int array)
gn = GaussNewton(72)


def work():
    feed(det, buf, N)
    pipe.add_samples(buf, 0, N)
    opt.run(pts, 18, 50)
    feed(wear_det, buf, N)
    wear_pipe.add_samples(buf, 0, N)
    gn.run(gpts, 72)


''' + heap_locked('work()', 'det.segments, pipe.rest_count, opt.status, wear_det.segments, '
                                      'gn.status, gn.iterations')


def test_rest_detectors_and_optimisers_allocate_nothing(tmp_path):
    f = tmp_path / "heap.py"
    f.write_text(SCRIPT)
    out = runtime.run_micropython_script(str(f)).split()
    assert out[0] == "OK", out
    assert int(out[1]) == 20  # 10 000 samples in 500-sample segments
    assert int(out[2]) == 10  # the pipeline saw the rest segments (every other 1500 samples)...
    assert int(out[4]) == 20 and int(out[5]) == 0 and int(out[6]) >= 1  # wear: detector, fit


def test_heap_lock_does_detect_allocation(tmp_path):
    # ...and the lock is real: the same harness reports an allocating loop.
    f = tmp_path / "alloc.py"
    f.write_text("import micropython\nmicropython.heap_lock()\ntry:\n    x = [1, 2, 3]\n"
                 "    micropython.heap_unlock()\n    print('OK')\nexcept MemoryError:\n"
                 "    micropython.heap_unlock()\n    print('ALLOCATED')\n")
    assert runtime.run_micropython_script(str(f)).strip() == "ALLOCATED"


PER_SAMPLE_32 = STREAM + r'''
from acal.core.rest import RestDetector, ALL_AXES, AUTO
from acal.core.calibration import Calibration

N = 6000
buf = stream(N, 900)
paper = RestDetector(100, 5)
wear = RestDetector(100, 5, AUTO, ALL_AXES)
# parameters at the corner of the bounds that maximises |a| (fixed.py: k 1.25, |k_ij| 0.125,
# |o| 0.25 g), Q24, at every full scale the app accepts
cals = []
for r in (2, 4, 8, 16):
    c = Calibration(range_g=r)
    c.set([20971520, 20971520, 20971520, 2097152, 2097152, 2097152, 4194304, 4194304, 4194304])
    cals.append(c)
# a composed model of every temperature form (dT in Q2 degC: fixed.TEMP_Q), its effects at their
# bounds, at the smallest and largest full scale, read at and past dT's clamp
from acal.core import effects
from acal.core.fixed import C_TEMP
TEMPS = (effects.TEMP_OFFSET, effects.TEMP_OFFSET2, effects.TEMP_SCALE, effects.TEMP_OFFSET4)
composed = []
for r in (2, 16):
    c = Calibration(TEMPS, r)
    c.set([20971520, 20971520, 20971520, 2097152, 2097152, 2097152, 4194304, 4194304, 4194304] +
          [effects.BOUNDS[k] for k in TEMPS for _ in range(3)])
    composed.append(c)
AT = (-1000, -effects.APPLY_DT_MAX, 3, effects.APPLY_DT_MAX, 1000)   # built before the lock
full = array("i", [0] * (3 * N))
for i in range(3 * N):
    full[i] = 16383 if buf[i] > 0 else -16383   # past every full scale: clamped to it
out = array("i", [0] * (3 * N))


def work():
    feed(paper, buf, N)
    feed(wear, buf, N)
    for cal in cals:
        for i in range(3 * N):
            out[i] = full[i]
        cal.apply_samples(out, 0, N)
    for cal in composed:
        for temp in AT:
            cal.now[C_TEMP] = temp
            cal.apply_samples(out, 0, 200, full)


''' + heap_locked('work()', 'paper.segments, wear.segments, out[0]')


def test_per_sample_paths_allocate_nothing_on_the_32_bit_port(tmp_path, mp32):
    """Where ints past 2^30 allocate (the WebAssembly port, as an RP2040): both profiles' rest
    detectors, and the apply at every full scale (2, 4, 8, 16 g) with readings at and past it
    and parameters at the bounds' corner; and a composed model of the four temperature forms
    with temperatures (Q2 degC) at and past their clamp."""
    f = tmp_path / "heap32.py"
    f.write_text(PER_SAMPLE_32)
    out = mp32(str(f)).split()
    assert out[0] == "OK", out
    assert int(out[1]) == int(out[2]) == 12


FIT_32 = r'''
import micropython
from acal.core.gaussnewton import GaussNewton
from acal.core.effects import TEMP_OFFSET, TEMP_SCALE, DRIFT, NONLINEAR, TEMP_OFFSET2, STEP
from acal.core.effects import TIME_OFFSET2, TEMP_OFFSET4, SUPPLY_OFFSET
from acal.core.changepoint import ChangePoint

from array import array
PTS = array("i", %s)   # int32 arrays, as the pipeline hands them over
AUX = array("i", %s)
fits = [(GaussNewton(18), 18, None), (GaussNewton(72), 72, None),
        (GaussNewton(72, (TEMP_OFFSET, TEMP_SCALE, DRIFT, NONLINEAR)), 72, AUX),
        (GaussNewton(72, (TEMP_OFFSET, TEMP_OFFSET2)), 72, AUX),
        (GaussNewton(72, (TIME_OFFSET2, TEMP_OFFSET4, SUPPLY_OFFSET)), 72, AUX)]
search = ChangePoint()
step = GaussNewton(72, (TEMP_OFFSET, STEP))
res = []
for gn, n, aux in fits:
    micropython.heap_lock()
    try:
        gn.run(PTS, n, 20, aux)
        micropython.heap_unlock()
        res.append("%%d:%%d:%%d:%%d" %% (gn.status, gn.iterations, gn.rejected, gn.p[6]))
    except MemoryError:
        micropython.heap_unlock()
        res.append("ALLOCATED")
micropython.heap_lock()
try:    # a step: searched on the four-effect fit's points, then fitted at its time
    search.run(fits[2][0])
    step.ts = search.ts
    step.run(PTS, 72, 20, AUX)
    micropython.heap_unlock()
    res.append("%%d:%%d:%%d:%%d:%%d" %% (search.ts, search.at, step.status, step.iterations, step.p[12]))
except MemoryError:
    micropython.heap_unlock()
    res.append("ALLOCATED")
print(" ".join(res))
'''


def test_default_fit_allocates_nothing_on_the_32_bit_port(tmp_path, mp32, rng):
    """The default profile's Gauss-Newton fit, with outlier rejection, under heap_lock where
    ints past 2^30 allocate: 18 points, its largest point count (72, the wear profile's 8 per
    subset), a composed model of all four first effects, one with the curved temperature
    response and one of three generic offsets (time^2, temperature^4, the board's supply) over
    72 points with temperatures, times and supplies spread across the clamps, and a step: its time searched (acal/core/changepoint.py) on the four-effect
    fit, then fitted.  Each runs bit-identical to CPython."""
    from acal.core import effects
    from acal.core.gaussnewton import GaussNewton
    from accelcal import simulate
    truth = np.array([1.03, 0.98, 1.01, 0.02, -0.01, 0.015, 0.05, -0.03, 0.04])
    d = rng.normal(size=(72, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    v = simulate.uncorrect(truth, d) + rng.normal(scale=1e-3, size=(72, 3))
    v[5] *= 1.2          # two outliers: rejection runs too
    v[40] *= 0.85
    pts = [int(x) for x in np.round(v * 65536).astype(np.int64).ravel()]
    aux = []
    for i in range(72):
        aux += [int(rng.integers(-160, 161)), int(rng.integers(-300000, 300001)),
                int(rng.integers(-1500, 1501))]     # Q2 degC, 64 s units, mV: past every clamp
    f = tmp_path / "fit32.py"
    f.write_text(FIT_32 % (pts, aux))
    out = mp32(str(f)).split()
    kinds = (effects.TEMP_OFFSET, effects.TEMP_SCALE, effects.DRIFT, effects.NONLINEAR)
    expect = []
    curve = (effects.TEMP_OFFSET, effects.TEMP_OFFSET2)
    generic = (effects.TIME_OFFSET2, effects.TEMP_OFFSET4, effects.SUPPLY_OFFSET)
    fits = []
    for kind, n, a in (((), 18, None), ((), 72, None), (kinds, 72, aux), (curve, 72, aux),
                       (generic, 72, aux)):
        gn = GaussNewton(n, kind)
        gn.run(pts, n, 20, a)
        fits.append(gn)
        expect.append("%d:%d:%d:%d" % (gn.status, gn.iterations, gn.rejected, gn.p[6]))
    from acal.core.changepoint import ChangePoint
    search = ChangePoint()
    assert search.run(fits[2])
    step = GaussNewton(72, (effects.TEMP_OFFSET, effects.STEP))
    step.ts = search.ts
    step.run(pts, 72, 20, aux)
    expect.append("%d:%d:%d:%d:%d" % (search.ts, search.at, step.status, step.iterations, step.p[12]))
    assert out == expect, (out, expect)
    print(expect)
    assert expect[1].startswith("0:") and int(expect[1].split(":")[2]) >= 2


PIPELINE_MEMORY = r'''
import gc
from acal.core.pipeline import Pipeline
from acal.core import profile, effects
import acal.core.changepoint   # its code loads with a step's first pipeline: not the pipeline's own
out = []
for kinds in ((effects.DRIFT,), (effects.STEP,), (effects.DRIFT, effects.STEP),
              (effects.TEMP_OFFSET, effects.TEMP_SCALE, effects.DRIFT, effects.NONLINEAR)):
    gc.collect()
    a = gc.mem_alloc()
    p = Pipeline(10, kinds=kinds, **profile.settings(profile.WEAR, True))
    gc.collect()
    out.append(gc.mem_alloc() - a)
    p = None
print(" ".join(map(str, out)))
'''


def test_a_step_costs_the_board_no_more_memory_than_a_drift(tmp_path):
    """Under MicroPython: a wear-profile pipeline with a step allocates within 1 kB of one with
    a drift (the change-point search keeps nothing per point of its own, acal/core/changepoint.py;
    its first form kept 4 kB of copies, and base+step did not start on the virtual board's
    160 kB heap), and drift + step no more than the four first effects together.  (base+step
    on that heap for two simulated days: tests/device/test_board_step.py, make bench.)"""
    f = tmp_path / "mem.py"
    f.write_text(PIPELINE_MEMORY)
    drift, step, both, four = map(int, runtime.run_micropython_script(str(f)).split())
    print(drift, step, both, four)
    assert step <= drift + 1024 and both <= four, (drift, step, both, four)


PAPER_32 = r"""
import micropython
from acal.paper.optimiser import Optimiser
from acal.core.effects import TEMP_OFFSET, DRIFT

PTS = %s
AUX = %s
fits = [(Optimiser(18), 18, 50, None), (Optimiser(36), 36, 50, None),
        (Optimiser(18, (30, 80, 20)), 18, 50, None),
        (Optimiser(36, kinds=(TEMP_OFFSET, DRIFT)), 36, 20, AUX)]
res = []
for o, n, m, aux in fits:
    micropython.heap_lock()
    try:
        o.run(PTS, n, m, aux)
        micropython.heap_unlock()
        res.append("%%d:%%d:%%d:%%d:%%d" %% (o.status, o.iterations, o.objective_start, o.objective,
                                         o.p[-1]))
    except MemoryError:
        micropython.heap_unlock()
        res.append("ALLOCATED")
print(" ".join(res))
"""


def test_paper_fit_allocates_nothing_on_the_32_bit_port(tmp_path, mp32, rng):
    """The paper profile's gradient descent under heap_lock where ints past 2^30 allocate: its
    objective and update in limbs (acal/paper/objective.py), 18 and 36 points of a sensor inside the
    paper's error ranges, the rates that diverge, and a composed model (temperature offset and
    drift) over 36 points with temperatures and times spread: nothing allocated, each run
    bit-identical to CPython's (objectives read after the lock is off: longs there)."""
    from acal.core import effects
    from acal.paper.optimiser import Optimiser
    from accelcal import simulate
    from accelcal.fixedpoint import g_to_point
    _, v = simulate.paper_scenario(rng, 36, 2e-3)
    pts = [int(c) for c in g_to_point(v).ravel()]
    aux = []
    for i in range(36):
        aux += [int(rng.integers(-80, 81)), int(rng.integers(-3000, 3001)), 0]   # Q2 degC: +-20
    f = tmp_path / "paper32.py"
    f.write_text(PAPER_32 % (pts, aux))
    out = mp32(str(f)).split()
    expect = []
    for o, n, m, a in ((Optimiser(18), 18, 50, None), (Optimiser(36), 36, 50, None),
                       (Optimiser(18, (30, 80, 20)), 18, 50, None),
                       (Optimiser(36, kinds=(effects.TEMP_OFFSET, effects.DRIFT)), 36, 20, aux)):
        o.run(pts, n, m, a)
        expect.append("%d:%d:%d:%d:%d" % (o.status, o.iterations, o.objective_start, o.objective,
                                          o.p[-1]))
    assert out == expect, (out, expect)
    assert [e.split(":")[0] for e in expect] == ["0", "0", "1", "0"]
    assert max(int(e.split(":")[2]) for e in expect) >= 1 << 30   # longs on the port, once read
