"""Every intermediate of the per-sample path stays within +-2**30 (the small-int limit of 32-bit
MicroPython ports) for any in-range input, shown by running the device code on traced ints at
the worst case.  The optimiser goes past 2**30 by design; it stays below 2**62 (unboxed on the
64-bit unix port) on realistic input - README "Integer ranges" gives the account."""
import numpy as np
import pytest

from acal import fixed
from acal.model import Calibration
from acal.optimiser import Optimiser
from acal.rest import RestDetector
from accelcal.ranges import SMALL_INT_LIMIT, Tracer, traced

# The LIS3DH at +-2 g: 12-bit (1 mg), 10-bit (4 mg) and 8-bit (16 mg) digits, all reaching
# -2.048 g .. +2.047 g, in Q10 g (device samples).
FULL_2G = {bits: (round(-2.048 * 1024), round(2.047 * 1024)) for bits in (12, 10, 8)}


def detector_run(samples, length):
    tr = Tracer()
    T = traced(tr)
    det = RestDetector(length, 1, T(123), 0)
    buf = [T(v) for v in samples]
    start, n = 0, len(samples) // 3
    while n > 0:
        used = det.add_samples(buf, start, n)
        start += used
        n -= used
    return tr, det


@pytest.mark.parametrize("value", [FULL_2G[12][0], FULL_2G[12][1], -fixed.SAMPLE_MAX, fixed.SAMPLE_MAX])
def test_rest_detector_longest_segment_at_full_scale(value):
    # The largest sums: the longest segment (65535 samples) pinned at full scale, +-2 g and +-16 g.
    n = fixed.SEGMENT_MAX_SAMPLES
    tr, det = detector_run([value] * (3 * n), n)
    assert det.segments == 1 and det.still
    assert det.mean_x == value << 6
    assert tr.ops >= 3 * n  # the three sums; count and index are bounded by the segment length
    assert tr.max_abs < SMALL_INT_LIMIT


def test_rest_detector_alternating_extremes():
    lo, hi = FULL_2G[12]
    n = 20000
    tr, det = detector_run([lo, hi, lo, hi, lo, hi] * (n // 2), n)
    assert det.spread == hi - lo and not det.still
    assert tr.max_abs < SMALL_INT_LIMIT


def corner_params():
    """Every corner of the parameter bounds (signs of misalignment and offsets, extreme scales)."""
    for kd in (fixed.K_DIAG_MIN, fixed.K_DIAG_MAX):
        for sm in (-1, 1):
            for so in (-1, 1):
                yield [kd] * 3 + [sm * fixed.K_OFF_MAX] * 3 + [so * fixed.O_MAX] * 3


@pytest.mark.parametrize("range_g", [2, 4, 8, 16])
def test_apply_worst_case_at_every_range(range_g):
    # the range's full scale, and the largest Q10 reading anything could hand it (clamped)
    fs = FULL_2G[12][0] * range_g // 2
    for p in corner_params():
        tr = Tracer()
        T = traced(tr)
        cal = Calibration(range_g=range_g)
        cal.set(p)
        cal.k = [T(v) for v in cal.k]
        for lo, hi in ((fs, -fs), (-fixed.SAMPLE_MAX, fixed.SAMPLE_MAX)):
            for x in (lo, hi):
                for y in (lo, hi):
                    for z in (lo, hi):
                        cal.apply(T(x), T(y), T(z))
        assert tr.ops > 0
        assert tr.max_abs < SMALL_INT_LIMIT, (range_g, p)


@pytest.mark.parametrize("range_g", [4, 8, 16])
def test_apply_at_larger_ranges_matches_the_float_model(rng, range_g):
    # Q(14 - e) parameters: within 1.5 LSB plus the coarser format's rounding (2^e / 2 LSB of
    # K and o, times the reading) across the range
    from accelcal.io import params_to_float
    from accelcal.methods import correct
    cal = Calibration(range_g=range_g)
    fs = 2097 * range_g // 2
    for p in corner_params():
        cal.set(p)
        v = rng.integers(-fs, fs, size=(200, 3))
        exp = correct(params_to_float(p), v / 1024) * 1024
        got = []
        for x, y, z in v.tolist():
            cal.apply(x, y, z)
            got.append((cal.x, cal.y, cal.z))
        assert np.abs(np.array(got) - exp).max() <= 1.5 + range_g / 2


def test_apply_rejects_parameters_outside_bounds():
    p = [fixed.PARAM_ONE] * 3 + [0] * 6
    p[0] = fixed.K_DIAG_MAX + 1
    with pytest.raises(ValueError):
        Calibration().set(p)


def test_apply_matches_float_model(rng):
    from accelcal.methods import correct
    from accelcal.io import params_to_float
    cal = Calibration()
    for p in corner_params():
        cal.set(p)
        v = rng.integers(-2097, 2097, size=(200, 3))
        exp = correct(params_to_float(p), v / 1024) * 1024
        got = []
        for x, y, z in v.tolist():
            cal.apply(x, y, z)
            got.append((cal.x, cal.y, cal.z))
        # Q14 parameters and a rounded Q10 result: within 1.5 LSB (1.5 mg) at +-2 g.
        assert np.abs(np.array(got) - exp).max() <= 1.5


def test_optimiser_stays_below_2_62_on_realistic_input(rng):
    """Rest means of a sensor inside the paper's error ranges; the account for 32-bit boards
    (how many values become longs) is printed by `accelcal bench`."""
    from accelcal import simulate
    from accelcal.io import g_to_point
    worst = 0
    for _ in range(20):
        p, v = simulate.paper_scenario(rng, 18, 5e-3)
        tr = Tracer()
        T = traced(tr)
        pts = [T(int(c)) for c in g_to_point(v).ravel()]
        Optimiser(18).run(pts, 18, 50)
        worst = max(worst, tr.max_abs)
        assert tr.big > 0  # the documented cost on 32-bit ports is real, not hypothetical
    assert worst < 1 << 62
