"""Every intermediate of the per-sample path stays within +-2**30 (the small-int limit of 32-bit
MicroPython ports) for any in-range input, shown by running the device code on traced ints at
the worst case: the per-sample path, the paper's objective and gradient descent (in limbs:
acal/paper/objective.py), the default profile's fit (docs/method-and-formats.md "Integer ranges").
And every shift those runs make inside a viper function has its amount in 0..31, where every
architecture gives Python's answer (the shift_amounts fixture; bridge/ranges.py)."""
import itertools
import math

import numpy as np
import pytest

from acal.core import fixed
from acal.core.calibration import Calibration
from acal.core import calibration, rest
from acal.paper import objective
from acal.core.rest import ALL_AXES, RestDetector
from accelcal.bridge.ranges import (SMALL_INT_LIMIT, Int32s, TracedArray, Tracer, traced,
                                     traced_gauss_newton, traced_optimiser, viper_casts)
from acal.core.bins import COND
from conftest import effect_orders


def rel(dT, dt, dV):
    """The relative conditions (now - ref, the columns fixed.C_*) the effect code reads."""
    d = [0] * COND
    d[fixed.C_TEMP], d[fixed.C_TIME], d[fixed.C_SUPPLY] = dT, dt, dV
    return d


@pytest.fixture(autouse=True)
def shift_amounts(monkeypatch):
    """Each Tracer a test makes, checked after it: no viper shift amount outside 0..31 (on Xtensa
    and RV32 the amount is taken mod 32: `a >> 32` is a)."""
    made = []
    init = Tracer.__init__

    def register(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(self)
    monkeypatch.setattr(Tracer, "__init__", register)
    yield made
    wild = sorted({s for tr in made for s in tr.wild_shifts()})
    assert not wild, f"viper shift amounts outside 0..31: {wild}"


# The LIS3DH at +-2 g: 12-bit (1 mg), 10-bit (4 mg) and 8-bit (16 mg) digits, all reaching
# -2.048 g .. +2.047 g, in Q10 g (device samples).
FULL_2G = {bits: (round(-2.048 * 1024), round(2.047 * 1024)) for bits in (12, 10, 8)}


def detector_run(samples, length, axis=0):
    # The scans are viper on the boards (acal/core/emit.py): machine words there, so every value they
    # make is traced here.  int() is viper's cast and the state an int32 array: for the trace
    # the cast passes a traced int through and the state is a list of traced ints.
    tr = Tracer()
    T = traced(tr)
    det = RestDetector(length, 1, T(123), axis)
    det.st = [T(v) for v in det.st]
    buf = [T(v) for v in samples]
    start, n = 0, len(samples) // 3
    rest.int = lambda v: v
    try:
        while n > 0:
            used = det.add_samples(buf, start, n)
            start += used
            n -= used
    finally:
        del rest.int
    return tr, det


@pytest.mark.parametrize("axis", [0, ALL_AXES])
@pytest.mark.parametrize("value", [FULL_2G[12][0], FULL_2G[12][1], -fixed.SAMPLE_MAX, fixed.SAMPLE_MAX])
def test_rest_detector_longest_segment_at_full_scale(value, axis):
    # The largest sums: the longest segment (65535 samples) pinned at full scale, +-2 g and +-16 g.
    n = fixed.SEGMENT_MAX_SAMPLES
    tr, det = detector_run([value] * (3 * n), n, axis)
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
    # the range's full scale, and the largest Q10 reading anything could hand it (clamped);
    # one sample (apply) and a block (apply_samples): one implementation, calibration._apply_block,
    # viper on the boards, so every value it makes is traced (int() is viper's cast, passed
    # through; the buffers lists, so the traced ints stay traced)
    fs = FULL_2G[12][0] * range_g // 2
    for p in corner_params():
        tr = Tracer()
        T = traced(tr)
        cal = Calibration(range_g=range_g)
        cal.set(p)
        cal.k = [T(v) for v in cal.k]
        cal.w = [0, 0, 0]
        calibration.int = lambda v: v
        try:
            for (lo, hi), r in itertools.product(((fs, -fs), (-fixed.SAMPLE_MAX, fixed.SAMPLE_MAX)),
                                                 (0, fixed.APPLY_DITHER_MASK)):
                for x, y, z in itertools.product((lo, hi), repeat=3):
                    cal.dither = T(r)   # the output's dither at both ends
                    cal.apply(T(x), T(y), T(z))
                    one = [cal.x, cal.y, cal.z]
                    buf = [T(x), T(y), T(z)]
                    cal.dither = T(r)
                    cal.apply_samples(buf, 0, 1)
                    assert buf == one
                    # the calibrated sample fits the log's int16 word (fixed.py: |a| <= 28 236)
                    assert max(abs(v) for v in one) <= 28236
        finally:
            del calibration.int
        assert tr.ops > 0
        assert tr.max_abs < SMALL_INT_LIMIT, (range_g, p)


@pytest.mark.parametrize("range_g", [2, 4, 8, 16])
def test_apply_matches_the_float_model(rng, range_g):
    # D = K - I in Q(18 - e), c = K o in Q(28 - e), the result rounded to Q(13 - e) with the
    # output's dither (fixed.py "apply", the base model): in output LSBs, under one step of
    # rounding (its mean the half: the next test), D's half LSB (2^-(19 - e)) times each of
    # three readings of up to 2.048 * 2^e g (3 * 2.048 * 2^(e - 6)), and c's rounding (one LSB
    # of Q(28 - e): 2^-15): < 1.10 LSB at +-2 g (0.13 mg), 1.77 at +-16 g (1.7 mg); K and o in
    # Q14, rounded to the nearest, gave up to 2.6 LSB
    from accelcal.fixedpoint import params_to_float
    from accelcal.methods import correct
    cal = Calibration(range_g=range_g)
    assert cal.out_q == fixed.apply_out_q(range_g) == 13 - fixed.apply_range_shift(range_g)
    fs = 2097 * range_g // 2
    worst = 0.0
    F = fixed
    for _ in range(20):   # anywhere inside the bounds (the corners are exact binary fractions)
        p = [int(v) for v in rng.integers(F.K_DIAG_MIN, F.K_DIAG_MAX + 1, 3)] + \
            [int(v) for v in rng.integers(-F.K_OFF_MAX, F.K_OFF_MAX + 1, 3)] + \
            [int(v) for v in rng.integers(-F.O_MAX, F.O_MAX + 1, 3)]
        cal.set(p)
        v = rng.integers(-fs, fs, size=(200, 3))
        exp = correct(params_to_float(p), v / 1024) * (1 << cal.out_q)
        buf = v.ravel().tolist()
        cal.apply_samples(buf, 0, len(v))
        worst = max(worst, np.abs(np.array(buf).reshape(-1, 3) - exp).max())
    e = fixed.apply_range_shift(range_g)
    assert worst < 1 + 3 * 2.048 * 2.0 ** (e - 6) + 2.0 ** -15, worst
    assert worst > 0.5   # the dither's and the parameters' rounding are seen: not vacuous


@pytest.mark.parametrize("range_g", [2, 16])
def test_a_still_windows_mean_keeps_the_apply_unrounded(rng, range_g):
    # A still window of 50 samples (5 s at 10 Hz) of a few readings: the mean of its calibrated
    # samples is the mean of the apply's sums before the output's rounding (fixed.py "apply":
    # ((x << (18 - e)) + D x + c) / 2**15, here from the Q24 parameters in Python's ints), within
    # 0.12 LSB (0.015 mg at +-2 g), at every posture and parameter: the dither's mean over a run
    # of 50 is the half LSB within its discrepancy (0.058 LSB at most for one fraction, every
    # phase), the readings' +-1 LSB moving the fraction a little more.  Rounded to the nearest,
    # one fraction of an LSB is kept through the window (up to 0.5 LSB, 0.06 mg at +-2 g: the
    # study's seed 5, 1.17x the true model on the written output).
    e = fixed.apply_range_shift(range_g)
    F = fixed
    worst = nearest = 0.0
    cal = Calibration(range_g=range_g)
    for _ in range(40):
        p = [int(v) for v in rng.integers(F.K_DIAG_MIN, F.K_DIAG_MAX + 1, 3)] + \
            [int(v) for v in rng.integers(-F.K_OFF_MAX, F.K_OFF_MAX + 1, 3)] + \
            [int(v) for v in rng.integers(-F.O_MAX, F.O_MAX + 1, 3)]
        cal.set(p)
        g = rng.normal(size=3)
        v = np.rint(g / np.linalg.norm(g) * 1024).astype(int) + rng.integers(-1, 2, (50, 3))
        buf = v.ravel().tolist()
        cal.apply_samples(buf, 0, len(v))
        out = np.array(buf).reshape(-1, 3)
        ds, cs = 6 + e, 19 + e
        d = [(p[i] - ((1 << 24) if i < 3 else 0) + (1 << (ds - 1))) >> ds for i in range(6)]
        o = [p[0] * p[6] >> cs, (p[3] * p[6] >> cs) + (p[1] * p[7] >> cs),
             (p[4] * p[6] >> cs) + (p[5] * p[7] >> cs) + (p[2] * p[8] >> cs)]
        c = [(t + 1) >> 1 for t in o]
        x, y, z = (v[:, j].astype(object) for j in range(3))
        sums = np.array([(x << (18 - e)) + d[0] * x + c[0],
                         (y << (18 - e)) + d[3] * x + d[1] * y + c[1],
                         (z << (18 - e)) + d[4] * x + d[5] * y + d[2] * z + c[2]], dtype=float).T
        exact = sums.mean(axis=0) / 2 ** 15
        worst = max(worst, np.abs(out.mean(axis=0) - exact).max())
        nearest = max(nearest, np.abs(np.floor(sums / 2 ** 15 + 0.5).mean(axis=0) - exact).max())
    assert worst <= 0.12, worst     # measured 0.087 (+-2 g), 0.094 (+-16 g)
    assert nearest > 0.3, nearest   # measured 0.46   # the nearest LSB's bias, which the dither takes out


def test_apply_rejects_parameters_outside_bounds():
    p = [fixed.PARAM_ONE] * 3 + [0] * 6
    p[0] = fixed.K_DIAG_MAX + 1
    with pytest.raises(ValueError):
        Calibration().set(p)


# --- the paper profile's objective and gradient step (acal/paper/objective.py): below 2**30 ----------

def _traced_kernel(T, p, pts, mode, cache):
    from acal.paper.objective import LIMBS
    out = TracedArray(T, 9 * LIMBS)
    with viper_casts():   # viper's cast: the traced int passes
        st = objective.objective_limbs([T(v) for v in pts], len(pts) // 3, out, T(0),
                                       [T(v) for v in p], mode, cache, T(0))
    assert st == 0
    return out


def _signed_corners(widen):
    """Corners of the fit region (widened by h: `widen`), with the points that make |a| largest
    (signs matching each row's) and smallest, at +-16 g (the domain's edge, Q24)."""
    F = fixed
    h = fixed.H_PARAM if widen else 0
    kd = (F.FIT_K_DIAG_MIN, F.FIT_K_DIAG_MAX + h)
    ko = (-F.FIT_K_OFF_MAX - h, F.FIT_K_OFF_MAX + h)
    oo = (-F.FIT_O_MAX - h, F.FIT_O_MAX + h)
    e = 1 << 28
    for p in itertools.product(kd, kd, kd, ko, ko, ko, oo, oo, oo):
        sz = [1 if p[4] > 0 else -1, 1 if p[5] > 0 else -1, 1]
        sy = [1 if p[3] > 0 else -1, 1, 1]
        pts = []
        for sg in (sz, sy, [-sz[0], sz[1], -1], [1, 1, 1], [-1, -1, -1]):
            pts += [e - 1 if c > 0 else -e for c in sg]
        pts += [0, 0, 0]
        yield list(p), pts


def test_paper_objective_stays_small_at_the_domain_corners():
    """objective_limbs at every corner of the fit region widened by h (PLAIN), and from the
    cache at every corner of the fit region (BASE, then the gradient's nine objectives), with
    points at +-16 g per axis in the octants that make |a| largest and smallest: no
    intermediate reaches 2^30; and the sums over 128 of the largest terms neither."""
    from acal.paper.objective import BASE, CACHE, GRADIENT, PLAIN
    tr = Tracer()
    T = traced(tr)
    worst = None
    for widen in (True, False):
        for p, pts in _signed_corners(widen):
            if widen:
                f = objective.from_limbs([int(v) for v in _traced_kernel(T, p, pts, PLAIN, [0])], 0)
                if worst is None or f > worst[0]:
                    worst = (f, p, pts)
            else:
                cache = TracedArray(T, CACHE * len(pts) // 3)
                _traced_kernel(T, p, pts, BASE, cache)
                _traced_kernel(T, p, pts, GRADIENT, cache)
    _, p, pts = worst
    for k in range(0, len(pts), 3):
        _traced_kernel(T, p, pts[k:k + 3] * 128, PLAIN, [0])
    assert tr.ops > 100000 and tr.big == 0, (tr.big, math.log2(tr.max_abs))
    assert tr.max_abs >= 1 << 29      # the bound is near: the proof is not vacuous


def test_paper_objective_shortcuts_stay_small_at_their_edges(rng):
    """Points of every size up to 2.3 g about parameters across the fit region: the shortcuts'
    checks (|a| < 2 g, |a|^2 within 1/4 g^2 of 1) are met and missed by little; traced, from
    the cache too, no intermediate reaches 2^30 (and the values are the formula's:
    tests/device/test_objective.py)."""
    from acal.paper.objective import BASE, CACHE, GRADIENT
    tr = Tracer()
    T = traced(tr)
    F = fixed
    for _ in range(60):
        n = 40
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        v = d * rng.choice([rng.uniform(0.3, 2.3), 1.0], size=(n, 1)) + rng.normal(scale=0.05, size=(n, 3))
        pts = [int(x) for x in np.round(v * (1 << 24)).ravel()]
        p = [int(rng.integers(F.FIT_K_DIAG_MIN, F.FIT_K_DIAG_MAX + 1)) for _ in range(3)] + \
            [int(rng.integers(-F.FIT_K_OFF_MAX, F.FIT_K_OFF_MAX + 1)) for _ in range(3)] + \
            [int(rng.integers(-F.FIT_O_MAX, F.FIT_O_MAX + 1)) for _ in range(3)]
        if _ % 2:
            p = [F.PARAM_ONE + int(x) for x in rng.integers(-(1 << 22), 1 << 22, 3)] + \
                [int(x) for x in rng.integers(-(1 << 21), 1 << 21, 6)]
        cache = TracedArray(T, CACHE * n)
        _traced_kernel(T, p, pts, BASE, cache)
        _traced_kernel(T, p, pts, GRADIENT, cache)
    assert tr.ops > 100000 and tr.big == 0, (tr.big, np.log2(tr.max_abs))


@pytest.mark.parametrize("alphas", [(3, 8, 2), (30, 80, 20)])
def test_paper_optimiser_stays_small(rng, alphas):
    """The paper's whole gradient descent, traced (its int32 arrays as traced lists, viper's
    cast passed through): rest means of sensors inside the paper's error ranges, and hostile
    points (+-16 g, the origin, 3 g) with the rates that diverge: no value of the run reaches
    2^30, so it allocates nothing on a 32-bit port (tests/device/test_heap.py runs it there)."""
    from accelcal import simulate
    from accelcal.fixedpoint import g_to_point
    with viper_casts():
        for trial in range(6):
            tr = Tracer()
            T = traced(tr)
            _, v = simulate.paper_scenario(rng, 18, 5e-3)
            pts = [int(c) for c in g_to_point(v).ravel()]
            if trial % 3 == 2:
                pts[:9] = [(1 << 20) - 1, -(1 << 20), 0, 0, 0, 0, 3 << 16, 3 << 16, -(3 << 16)]
            traced_optimiser(T, 18, alphas).run([T(c) for c in pts], 18, 50)
            assert tr.ops > 10000 and tr.big == 0, (trial, tr.big, np.log2(tr.max_abs))


# --- the default profile's fit: every intermediate below 2**30 -------------------------------

def _fit_corners():
    import itertools
    F = fixed
    kd = (F.FIT_K_DIAG_MIN, F.FIT_K_DIAG_MAX)
    ko = (-F.FIT_K_OFF_MAX, F.FIT_K_OFF_MAX)
    oo = (-F.FIT_O_MAX, F.FIT_O_MAX)
    for p in itertools.product(kd, kd, kd, ko, ko, ko, oo, oo, oo):
        yield list(p)


def test_gauss_newton_rows_stay_small_at_the_fit_region_corners():
    """model.residual and residual_jacobian (the default fit's rows) at every corner of the fit
    region (k_ii 0.5 or 2, |k_ij| and |o| 0.5) and readings at the fit's clamp (+-2.048 g per
    axis) in every octant: no intermediate reaches 2^30."""
    import itertools
    from acal.core import model
    tr = Tracer()
    T = traced(tr)
    w = model.FIT_W_MAX
    d = [0] * 9
    model.int = lambda v: v   # viper's cast (on the boards): the traced parameters pass
    try:
        for p in _fit_corners():
            pt = [T(v) for v in p]
            for u in itertools.product((-w, w), repeat=3):
                model.residual(pt, T(u[0]), T(u[1]), T(u[2]))
                model.residual_jacobian(pt, T(u[0]), T(u[1]), T(u[2]), d)
    finally:
        del model.int
    assert tr.ops > 100000 and tr.big == 0, (tr.big, np.log2(tr.max_abs))


def test_effects_fit_form_stays_small_at_its_clamps():
    """effects.correct_u (the fit's form) for every effect with parameters at 4x their bounds
    (the fit region) and at the Jacobian rows' 2^22, readings at +-2.048 g, dT and dt at and far
    past their clamps; and model.remove_effects over the effects in every order
    (conftest.effect_orders)."""
    import itertools
    from acal.core import effects, model
    tr = Tracer()
    T = traced(tr)
    w = model.FIT_W_MAX
    kinds = tuple(effects.NAMES)
    for kind in kinds:
        for bound in (4 * effects.BOUNDS[kind], (1 << 22) - 1):
            for sgn in itertools.product((-1, 1), repeat=3):
                p = [T(s * bound) for s in sgn]
                for u0 in (-w, w, 0):
                    for dT in (-1000, -effects.APPLY_DT_MAX, -3, 0, 5, effects.APPLY_DT_MAX, 1000):
                        for dt in (-(1 << 28), -effects.FIT_TIME_MAX, 0, effects.FIT_TIME_MAX, 1 << 28):
                            u = [T(u0), T(-u0), T(w)]
                            effects.correct_u(kind, p, 0, u, rel(T(dT), T(dt), T(0)), 0, 0, T(0))
    for order in effect_orders():
        for sgn in (-1, 1):
            p = [0] * 9 + [T(sgn * 4 * effects.BOUNDS[k]) for k in order for _ in range(3)]
            for u0 in (-w, w):
                u = [T(u0), T(-u0), T(u0)]
                model.remove_effects(p, order, u, 0, rel(T(sgn * 1000), T(-sgn * (1 << 28)), T(0)),
                                     0, T(0))
                assert max(abs(int(v)) for v in u) <= w
    assert tr.big == 0, (tr.big, np.log2(tr.max_abs))


def test_solver_stays_small_on_ill_conditioned_systems(rng):
    """acal/core/solve.py on normal equations as the default fit builds them (A = sum d d^T over up
    to 128 rows, each column scaled to |d| < 2^11, so entries reach 2^29) for 9 and 21
    unknowns, condition numbers up to 10^8, right-hand sides from 1 to 2^29 - 1 (the domain's
    edge) and damping from none to MU_MAX: no intermediate reaches 2^30; undamped, with condition numbers up to 10^4,
    it solves them, to 2e-3 of the float solution's size."""
    from acal.core.gaussnewton import MU_MAX
    from acal.core import solve
    from acal.core.solve import Solver
    tr = Tracer()
    T = traced(tr)
    worst = 0.0
    refused = 0
    for n in (9, 21):
        s = Solver(n)
        for trial in range(40):
            rows = int(rng.integers(n + 1, 129))
            q, _ = np.linalg.qr(rng.normal(size=(n, n)))
            decades = rng.uniform(0, 4) if trial % 2 == 0 else rng.uniform(0, 8)
            d = rng.normal(size=(rows, n)) @ (q * np.logspace(0, -decades / 2, n)) @ q.T
            d = np.round(d / np.abs(d).max(axis=0) * 2047).astype(np.int64)
            a = d.T @ d
            # b inside the solver's domain (|b_k| < 2^29), some at its edge: past it the bit
            # length once needed a shift by 32, which never ends on Xtensa and RV32
            b = np.clip(np.round(rng.normal(size=n) * 2.0 ** rng.uniform(0, 29)),
                        1 - (1 << 29), (1 << 29) - 1)
            if trial % 4 == 1:
                b[trial % n] = (1 << 29) - 1 if trial % 8 == 1 else 1 - (1 << 29)
            mu = 0 if trial % 2 == 0 else int(rng.choice([0, 1, 85, MU_MAX]))
            want = np.linalg.solve(a.astype(float), b)
            k = int(20 - np.ceil(np.log2(np.abs(want).max())))   # x ~ 2^20
            x = [0] * n
            s.m = [0] * len(s.m)   # lists for its int32 arrays: the traced ints stay traced
            s.c = [0] * len(s.c)
            s.y = [0] * len(s.y)
            s.s = [0] * len(s.s)
            solve.int = lambda v: v   # viper's cast (solve._eliminate_rows) passes them through
            try:
                ok = s.solve([T(int(v)) for v in a.ravel()], [T(int(v)) for v in b], x, n,
                             T(mu), [T(k)] * n)
            finally:
                del solve.int
            # the scales, plain ints (so their shifts are not traced): in [-11, 3], which keeps
            # the scaled copy's shifts in [-6, 22] (solve._prepare_rows)
            assert all(-11 <= v <= 3 for v in s.s[:n]), list(s.s[:n])
            if trial % 2 == 0 and np.linalg.cond(a) < 1e4:
                assert ok, (n, decades)
                err = np.abs(np.array(x, float) - want * 2.0 ** k).max() / 2.0 ** 20
                worst = max(worst, err)
            refused += not ok
    assert tr.big == 0, (tr.big, np.log2(tr.max_abs))
    assert worst < 2e-3, worst
    assert refused > 0   # the guard does refuse the worst-conditioned


def test_default_fit_stays_small_on_hostile_points(rng):
    """The whole default fit, traced: as many points as it takes (gaussnewton.MAX_POINTS, 128:
    the wear profile's composed bins hold 126, its base bins 72) with outliers at the clamp,
    points past it, a composed model of all four effects with dT and dt past their clamps."""
    from acal.core import effects
    from acal.core.gaussnewton import MAX_POINTS as n
    from accelcal import simulate
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    v = simulate.uncorrect(np.array([1.2, 0.8, 1.1, 0.1, -0.1, 0.1, 0.2, -0.2, 0.2]), d)
    v[:6] = [[16, -16, 16], [2.1, 2.1, 2.1], [0, 0, 0], [-3, 0, 0], [0.5, 0.5, 0.5], [1, 1, 1]]
    pts = [int(c) for c in np.round(v * 65536).astype(np.int64).ravel()]
    aux = [int(x) for x in rng.integers(-(1 << 20), 1 << 20, size=3 * n)]   # dT dt dV (COND)
    aux[0::3] = [int(x) for x in rng.integers(-200, 200, size=n)]
    specific = tuple(k for k in effects.NAMES if k not in effects.SHAPES)
    generic = (effects.STEP, effects.TIME_OFFSET4, effects.TEMP_OFFSET4, effects.SUPPLY_OFFSET)
    for k, a in (((), None), (specific, aux), (generic, aux)):
        tr = Tracer()
        T = traced(tr)
        gn = traced_gauss_newton(T, n, k)   # its int32 arrays as traced lists
        with viper_casts():
            gn.run(Int32s(T(c) for c in pts), n, 20, None if a is None else Int32s(T(c) for c in a))
        assert tr.ops > 10000 and tr.big == 0, (k, tr.big, np.log2(tr.max_abs))


class _HeldFit:
    """What acal/core/changepoint.py reads of a finished fit: points, their times, their residuals."""

    def __init__(self, T, w, r, t):
        self.n_given = len(r)
        self.keep = [1] * len(r)
        self.srt = [0] * len(r)
        self.aux = [T(t[k // 3]) if k % 3 == 1 else T(0) for k in range(3 * len(r))]
        self._w, self._r, self._T = w, r, T

    def point(self, i, w):
        for c in range(3):
            w[c] = self._T(self._w[i][c])
        return self._T(self._r[i])


def test_change_point_search_stays_small_at_the_worst_case(rng):
    """The step's search (acal/core/changepoint.py) over 128 points at +-2.048 g per axis (the fit's
    clamp), residuals at and past their clamp, all of one sign or alternating, directions all
    alike (a singular split, skipped), on the axes, or random: no intermediate reaches 2^30; and
    a step put in noisy residuals is found as well as the host's float search finds it."""
    from acal.core import model
    from acal.core.changepoint import ChangePoint
    from accelcal.pipeline.composed_lsq import change_point
    tr = Tracer()
    T = traced(tr)
    w = model.FIT_W_MAX
    big_r = 1 << 31                      # past any residual the fit makes (Q22 g^2)
    n = 128
    t = sorted(int(x) for x in rng.integers(-(1 << 20), 1 << 20, n))
    cases = []
    for sign in (1, -1):
        cases.append(([(w, w, w)] * n, [sign * big_r] * n))
        cases.append(([(w, w, w)] * n, [big_r * (-1) ** i for i in range(n)]))
        axes = [tuple(w * sign * (c == i % 3) for c in range(3)) for i in range(n)]
        cases.append((axes, [sign * big_r] * n))
        corners = [tuple(int(c) for c in rng.choice([-w, w], 3)) for _ in range(n)]
        cases.append((corners, [int(x) for x in rng.choice([-big_r, big_r], n)]))
    for pts, r in cases:
        ChangePoint().run(_HeldFit(T, pts, r, t))
    assert tr.ops > 10000 and tr.big == 0, (tr.big, np.log2(tr.max_abs))
    # a step in the residuals after point 80, seen through random directions: found there
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    jump = np.array([0.004, -0.003, 0.002])
    res = 2 * (d @ jump) * (np.arange(n) >= 80) + rng.normal(scale=2e-4, size=n)
    pts = [tuple(int(c) for c in row) for row in np.round(d * (1 << 24))]
    cp = ChangePoint()
    assert cp.run(_HeldFit(int, pts, [int(x) for x in np.round(res * (1 << 22))], t))
    # the float search of the host (composed_lsq.change_point) on the same points finds the step;
    # the device's split is one of the same worth, in float, to 1 % (its sums keep 9 bits)
    k = int(np.searchsorted(t, change_point(res, d, np.array(t, dtype=float))))

    def gain(k):
        S, b = d[k:].T @ d[k:], d[k:].T @ res[k:]
        return b @ np.linalg.solve(S, b)
    assert abs(k - 80) <= 1 and cp.ts == t[cp.at], (cp.at, k)
    assert gain(cp.at) >= 0.99 * gain(k), (cp.at, k, gain(cp.at), gain(k))


def test_discovery_scores_and_rule_stay_small_at_the_worst_case():
    """The board's own discovery (acal/discover/search.py, score.py, rule.py): a full held-out
    set (144 points at +-1.25 g per axis, past what gravity() keeps, each standing for
    heldout.WEIGHT_CAP rest means, conditions far past the fit's clamps) scored with parameters
    at the fit region's corners and effects at 4x their bounds (every point's error at ERR_CAP),
    its blocks compared, the rule on errors at search.ERR_MAX and every block count the sign
    test takes, and the conditions' ranges: no intermediate reaches 2^30."""
    from acal.discover import search, rule, heldout, score
    from acal.core import effects
    from acal.core.bins import COND
    tr = Tracer()
    T = traced(tr)
    h = heldout.HeldOut()
    g125 = 5 * (1 << 16) // 4
    for i in range(h.capacity):      # 144 points in 72 blocks, each its own posture
        h.offer(g125 * (-1) ** i, -g125, g125 * (-1) ** (i >> 1), (0, (2 * (i >> 1) + 1) * 113, 0))
    assert h.count == h.capacity
    for name in ("xyz", "cond", "block", "weight"):
        setattr(h, name, [T(v) for v in getattr(h, name)])
    for i in range(h.count):
        h.weight[i] = T(heldout.WEIGHT_CAP)
        h.cond[COND * i: COND * i + COND] = [T((-1) ** i * 1000), T((1 << 28) * (-1) ** i),
                                             T((-1) ** i * 65535)]
    s = score.HeldScore()
    for name in ("w", "err", "base", "first"):
        setattr(s, name, [T(0)] * len(getattr(s, name)))
    kinds = search.KINDS[search.PAIR]
    totals = []
    with viper_casts():
        for k, o in ((fixed.FIT_K_DIAG_MAX, fixed.FIT_O_MAX), (fixed.FIT_K_DIAG_MIN, -fixed.FIT_O_MAX)):
            for sgn in (-1, 1):
                p = [T(k)] * 3 + [T(sgn * fixed.FIT_K_OFF_MAX)] * 3 + [T(o)] * 3 + \
                    [T(sgn * 4 * effects.BOUNDS[kd]) for kd in kinds for _ in range(3)]
                total = s.score(p, kinds, h, (T(-1000), T(-(1 << 28)), T(65535)), T(1 << 28))
                totals.append(int(total))
                s.keep_as_base(h.count)
                assert s.better_blocks(h) == 0
    assert max(totals) == h.count * heldout.WEIGHT_CAP * score.ERR_CAP   # every point capped
    e = T(search.ERR_MAX)
    assert rule.names(e, T(0), T(72), T(72)) and rule.plain_preferred(e, e)
    for blocks in range(1, rule.SIGN_BLOCKS + 2):
        for better in range(blocks + 1):
            rule.clear(T(better), T(blocks))
    for c in range(COND):
        assert search._range(h.cond, h.count, c) > 0
    assert tr.ops > 10000 and tr.big == 0, (tr.big, np.log2(tr.max_abs))


# --- shift amounts at the edges of the documented domains (issue 49) -------------------------

def test_viper_shifts_stay_below_32_over_whole_domains():
    """The three viper functions whose shift amounts once passed 31 for inputs their callers never
    make but their documentation allows, traced over the whole of it and against CPython's exact
    integers: wide.mul_shift with s up to 100 (s >= 62 shifted by 32 or more),
    normal_sums.grow_columns with scales grown by up to 20 bits (the diagonal by 2g up to 40),
    solve._rhs_shift with |b| up to 2^31 - 1 (from 2^28 its bit length shifted by 32, an endless
    loop on Xtensa and RV32).  The shift_amounts fixture fails the test on any amount past 31."""
    from acal.core import normal_sums, solve
    from acal.core.wide import mul_shift
    tr = Tracer()
    T = traced(tr)
    lim = (1 << 29) - 1
    for s in (16, 30, 31, 45, 46, 47, 58, 61, 62, 63, 64, 77, 78, 100):
        for a, b in itertools.product((lim, -lim, 1, -1, 0x7FFF, -(1 << 15), 0), repeat=2):
            assert mul_shift(T(a), T(b), T(s)) == (a * b) >> s, (a, b, s)
    n = 4
    grown = [0, 20, 16, 15]            # 2g: 0, 40, 32, 30
    sums = [(-1) ** i * ((1 << 30) - 1 - 977 * i) for i in range(n * n)]
    high = [(1 << 21) - 3, -(1 << 21) + 5, 123457, -1]
    low = [511, 0, 300, 17]
    ta = [T(v) for v in sums]
    th = [T(v) for v in high]
    tl = [T(v) for v in low]
    with viper_casts():
        normal_sums.grow_columns(ta, th, tl, [T(g) for g in grown], n, 0)
    want = list(sums)
    for k, g in enumerate(grown):
        for j in range(n):
            if j != k:
                at = k * n + j if j < k else j * n + k
                want[at] >>= g
        want[k * n + k] >>= 2 * g
    assert [int(v) for v in ta] == want
    for k, g in enumerate(grown):      # b = high 2^9 + low, shifted down by g, low in [0, 512)
        assert int(th[k]) * 512 + int(tl[k]) == (high[k] * 512 + low[k]) >> g and 0 <= tl[k] < 512
    for b, sc in (([(1 << 31) - 1, 0, -5], [0, 0, 0]), ([0, -(1 << 28)], [3, -9]),
                  ([(1 << 29) - 1, -(1 << 29) + 1], [-4, 2]), ([0, 0], [0, 0]), ([1 << 27], [0])):
        want = max([abs(v).bit_length() - s - 19 for v, s in zip(b, sc) if v] or [0])
        with viper_casts():
            got = solve._rhs_shift([T(v) for v in b], [T(s) for s in sc], len(b), 0)
        assert got == want, (b, sc)
    # and two whose computed amounts the fits' traces do not reach: rhs_from_limbs's e past 9
    # (|high| >= 2^27; e <= 13 for any int32) and div_shift's last 1-3 bits
    for high in ([(1 << 31) - 1, -(1 << 31) + 1, 5], [(1 << 27) + 3, -7, 0], [1 << 17, 0, -1]):
        low = [511, 0, 256]
        r = [T(0)] * 3
        with viper_casts():
            e = normal_sums.rhs_from_limbs([T(v) for v in high], [T(v) for v in low], r, 3, 0)
        assert e == max(0, max(abs(v).bit_length() for v in high) - 18)
        assert [int(v) for v in r] == [-((h * 512 + lo) >> e) for h, lo in zip(high, low)]
    from acal.core.wide import div_shift
    for x, d, s in ((lim, (1 << 26) - 1, 3), (-lim, 3, 1), (12345, 7, 30), (-1, 1, 27)):
        assert div_shift(T(x), T(d), T(s)) == (x << s) // d
    assert tr.shifts and max(hi for _, hi, _ in tr.shifts.values()) == 31   # the bound is met


def test_fifo_conversion_stays_small_at_every_code(monkeypatch):
    """lis3dh.fifo_codes_q10 (viper on the boards) at +-16 g in HR mode, the largest product,
    over every 10-bit code: every value below 2**30, its shifts within 0..31."""
    from acal.core.fixed import SAMPLE_MAX
    from acal.logger import lis3dh
    tr = Tracer()
    T = traced(tr)
    monkeypatch.setattr(lis3dh, "int", lambda v: v, raising=False)   # viper's cast
    data = []
    for r in range(-512, 512):
        v = (r << 6) & 0xFFFF | 63
        data += [T(v & 0xFF), T(v >> 8)]
    out = [0] * 1024
    lis3dh.fifo_codes_q10(data, T(0), T(1024), out, T(0), T(3), T(12 * 16777), T(SAMPLE_MAX),
                          T(16383))   # the largest dither
    assert out[0] == -SAMPLE_MAX and out[-1] == SAMPLE_MAX
    assert tr.ops > 10000 and tr.big == 0, (tr.big, np.log2(tr.max_abs))
    assert tr.max_abs > 1 << 29     # the worst case is reached: 4099 x 201324
