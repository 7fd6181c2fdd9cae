"""A composed model on the device app (simulated LIS3DH, CPython): the bins gather points spread
in temperature, the integer fit finds the temp_offset effect, CAL and EFFECT records are logged,
the host replay reproduces them, the stored calibration resumes after a reboot, and the
per-sample apply removes the effect as the float model does (bit-identical and allocation-free
under MicroPython)."""
import os
import sys

import numpy as np
import pytest

from accelcal.bridge import boardlog
from accelcal import simulate
from accelcal.model.effects import CATALOGUE, ModelSpec
from accelcal.simulate.stimulus import write_stimulus
from conftest import run_both

from accelcal.locations import CHIP_DIR  # noqa: E402
sys.path.insert(0, str(CHIP_DIR))
from simboard import SimBoard  # noqa: E402

from acal.logger import log  # noqa: E402
from acal.core.fixed import DIFFERS  # noqa: E402
from acal.core.fixed import C_TEMP, C_TIME, TEMP_Q  # noqa: E402
from acal.logger.app import App, Processor  # noqa: E402
from acal.core.profile import GRADIENT, PAPER, WEAR, WEAR_COMPOSED_MAX_COUNT  # noqa: E402

RATE = 25
TRUTH = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
C_TRUE = np.array([0.0008, -0.0006, 0.0005])  # g/degC: temp_offset, on the LIS3DH's scale
SPEC = ModelSpec.parse("base+temp_offset")
REF = {"T0": 25.0, "t0": 0.0}  # the simulated chip's OUT_ADC3 reads 0 at 25 degC


def stimulus(path, rng, n_rest=160, rest_s=8, move_s=4):
    """Rest at random orientations and temperatures (22-38 degC) between moves."""
    parts, temps = [], []
    e = CATALOGUE["temp_offset"]
    for d in simulate.unit_points(rng, n_rest):
        temp = float(rng.integers(22, 39))
        v = simulate.uncorrect(TRUTH, d[None, :])
        v = e.measure(v, C_TRUE, np.array([temp]), None, REF)[0]
        parts.append(v + rng.normal(scale=0.0016, size=(RATE * rest_s, 3)))
        parts.append(v + rng.normal(scale=0.3, size=(RATE * move_s, 3)))
        temps += [temp] * (RATE * (rest_s + move_s))
    write_stimulus(path, RATE, np.clip(np.concatenate(parts), -1.9, 1.9), np.array(temps))


@pytest.fixture(scope="module", params=[PAPER, WEAR], ids=["paper", "wear"])
def ran(tmp_path_factory, request):
    d = tmp_path_factory.mktemp("composed_app")
    # the paper's fit (200 gradient steps of 13 objective evaluations, one a slice, four slices
    # a block) takes ~18 min of 25 Hz data to finish: a longer day for it
    stimulus(d / "stim.bin", np.random.default_rng(7), n_rest=160 if request.param == WEAR else 400)
    cwd = os.getcwd()
    os.chdir(d)
    try:
        app = App(SimBoard(str(d / "stim.bin")), rate_hz=RATE, capture_bytes=1 << 24,
                  recal_seconds=600, model="base+temp_offset", profile=request.param)
        app.run(10 ** 6)
    finally:
        os.chdir(cwd)
    return d, app


def last_ok(d):
    lg = boardlog.decode(d / "log.bin")
    cals, effs = lg.dicts(log.CAL), lg.dicts(log.EFFECT)
    assert len(cals) == len(effs) >= 2  # one EFFECT per CAL for a one-effect model
    ok = [(c, e) for c, e in zip(cals, effs) if c["status"] == 0]
    assert ok and all(c["index"] == e["index"] for c, e in zip(cals, effs))
    return ok[-1]


def test_the_board_fits_the_effect_in_integers(ran):
    d, app = ran
    c, e = last_ok(d)
    held = app.proc.pipe.bins
    if app.proc.pipe.fit == GRADIENT:  # 4 points per subset, 200 gradient steps
        assert c["points"] == 36 and c["iterations"] == 200 and held.total() == 36
    else:  # the composed bins (14 per subset) less the outliers, Gauss-Newton to convergence
        assert held.max_count == WEAR_COMPOSED_MAX_COUNT
        assert 36 <= c["points"] <= 9 * held.max_count and c["iterations"] <= 20 and held.total() >= 36
    k = np.array([c[n] for n in ("kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz")]) / 2 ** 24
    assert np.abs(k - TRUTH).max() < 0.01
    # c at the board's reference (the held points' middle temperature), in g/degC.
    cfit = CATALOGUE["temp_offset"].from_int([e["p0"], e["p1"], e["p2"]])
    assert np.abs(cfit - C_TRUE).max() < 0.00015, cfit
    assert held.span(C_TEMP) >= DIFFERS[C_TEMP] == 3 << TEMP_Q  # the spread the fit needs (Q2 degC)


def test_replay_reproduces_cal_and_effect_records(ran):
    d, _ = ran
    r = boardlog.replay(d)
    assert r["identical"], r
    assert r["effect"]["board"] == r["cal"]["board"] >= 2


def test_stored_composed_calibration_resumes_after_a_reboot(ran, tmp_path):
    d, app = ran
    store = log.CalStore(str(d / "cal_a.bin"), str(d / "cal_b.bin"))
    lg = log.Log(str(tmp_path / "log.bin"))
    proc = Processor(lg, RATE, store=store, model="base+temp_offset")
    assert proc.params == app.proc.params and proc.calibrations == app.proc.calibrations
    c, e = last_ok(d)
    # the reference in Q2 degC: the middle of the held points' whole degrees (the chip's OUT_ADC3,
    # scaled by the Processor), a quarter degree apart when their range is odd
    assert proc.calibration.ref[C_TEMP] == e["ref_temp"] == app.proc.calibration.ref[C_TEMP]
    # one conditions value, the app's, held by the calibration and the pipeline: the chip's
    # whole degrees in Q2
    now = app.proc.now
    assert app.proc.calibration.now is now and app.proc.pipe.now is now and app.now is now
    assert now[C_TEMP] != 0 and now[C_TEMP] % (1 << TEMP_Q) == 0
    temps = [app.proc.pipe.bins.condition(s, k)[0] for s in range(9)
             for k in range(app.proc.pipe.bins.counts[s])]
    assert all(t % (1 << TEMP_Q) == 0 for t in temps)   # whole degrees, held in Q2
    assert proc.calibration.ref[C_TIME] == e["ref_time"] - c["index"] // (64 * RATE)
    # flashed as base: starts uncalibrated, numbering on from the stored calibration
    other = Processor(log.Log(str(tmp_path / "log2.bin")), RATE, store=store)
    assert other.calibrations == app.proc.calibrations
    assert other.params == Processor(log.Log(str(tmp_path / "log3.bin")), RATE).params


def test_per_sample_apply_removes_the_effect_like_the_float_model(ran, rng):
    _, app = ran
    cal = app.proc.calibration
    theta = SPEC.from_int(app.proc.params)
    v = rng.uniform(-1.5, 1.5, (300, 3))
    # quarter degrees (Q2 degC), |dT| within the apply's +-32 degC clamp
    temps = cal.ref[C_TEMP] + rng.integers(-15 << TEMP_Q, (15 << TEMP_Q) + 1, 300)
    got = []
    for (x, y, z), temp in zip(np.rint(v * 1024).astype(int).tolist(), temps.tolist()):
        cal.now[C_TEMP] = temp
        cal.apply(x, y, z)
        got.append((cal.x, cal.y, cal.z))
    q = float(1 << TEMP_Q)
    want = SPEC.correct(theta, np.rint(v * 1024) / 1024, temps / q, None,
                        {"T0": cal.ref[C_TEMP] / q, "t0": 0.0})
    # Q13 out: the parameters' Q14 and the effect's rounding, a step of 0.12 mg
    assert np.abs(np.array(got) / (1 << cal.out_q) - want).max() < 0.0004


APPLY_SCRIPT = r'''
from array import array
from acal.core import effects
from acal.core.calibration import Calibration
from acal.core.fixed import C_TEMP, C_TIME
buf = array("i", [rnd(2097) * 4 for _ in range(3 * 2000)])   # to +-8 g: clamped at 2 g
# the first effects; then a step and two generic offsets (time^4, temperature^4); then at
# +-8 g full scale, without effects (the viper block alone) and with two
for m, (kinds, r) in enumerate((((1, 3, 4), 2),
                                ((effects.STEP, effects.TIME_OFFSET4, effects.TEMP_OFFSET4), 2),
                                ((), 8), ((2, 4), 8))):
    cal = Calibration(kinds, r)
    p = [16777216 + rnd(800000), 16777216 + rnd(800000), 16777216 + rnd(800000),
         rnd(200000), rnd(200000), rnd(200000), rnd(900000), rnd(900000), rnd(900000)]
    for k in kinds:
        p += [rnd(effects.BOUNDS[k]) for _ in range(3)]
    cal.set(p, (30, 5000, 0), 2000)
    for j in range(10):
        cal.now[C_TEMP] = rnd(60) + 30
        cal.now[C_TIME] = 5000 + (rnd(1 << 21) if m != 1 else rnd(1 << 15))
        if micropython:  # MicroPython: a MemoryError if the per-sample path allocates
            micropython.heap_lock()
        cal.apply_samples(buf, 500 * m + 50 * j, 50)
        cal.apply(buf[0], buf[1], buf[2])    # one sample: the same block, on its own buffer
        if micropython:
            micropython.heap_unlock()
        buf[0] = cal.x
print(" ".join([str(v) for v in buf]))
'''


def test_composed_apply_is_allocation_free_and_identical_under_micropython(tmp_path, mp):
    got, host = run_both(APPLY_SCRIPT, tmp_path, mp)   # both ports, the 32-bit one too
    assert got.split() == host.split() and len(got.split()) == 6000
