"""The default (wear) profile of the device pipeline against independent expectations: the
Gauss-Newton fit reaches the float optimum of its own points (scipy), outliers injected into a
clean set leave the fit and the parameters return to the clean fit's, the sliced fit equals the
one-shot fit bit for bit, the noise gauge's threshold follows the sensor's noise, the bins are
ready on coverage without a face-down point, and CPython and the real MicroPython give the same
integers (random point sets with outliers, recordings with gaps and clipping, composed models)."""
import numpy as np
import pytest
from scipy.optimize import least_squares

from acal.core import bins as dbins
from acal.core import fixed, rest
from acal.paper import optimiser
from acal.core.gaussnewton import GaussNewton
from acal.paper.optimiser import Optimiser
from acal.core.pipeline import Pipeline
from acal.core.profile import WEAR, settings
from accelcal.bridge import runtime
from accelcal.bridge.boardlog import STATUS_NAMES
from accelcal import simulate
from test_runtimes import random_recording


def q16(v):
    return np.round(np.asarray(v) * fixed.POINT_ONE_G).astype(np.int64)


def float_residuals(v, p):
    k = np.array([[p[0], 0, 0], [p[3], p[1], 0], [p[4], p[5], p[2]]])
    a = (v + p[6:9]) @ k.T
    return (a * a).sum(axis=1) - 1.0


def float_objective(v, p_q24):
    """The paper's square-root-free objective, in float, at the device's parameters (Q24)."""
    return float((float_residuals(v, np.asarray(p_q24, float) / 2.0 ** 24) ** 2).sum())


def float_optimum(v):
    """The float minimiser of the paper's square-root-free objective sum((|a|^2 - 1)^2)."""
    def res(p):
        return float_residuals(v, p)
    r = least_squares(res, [1, 1, 1, 0, 0, 0, 0, 0, 0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return r.x, float((r.fun ** 2).sum())


def test_fit_reaches_the_float_optimum_of_its_points(rng):
    ratios, gaps = [], []
    for _ in range(40):
        _, v = simulate.paper_scenario(rng, 72, float(rng.choice([1e-3, 5e-3])))
        q = q16(v)
        gn = GaussNewton(72, reject=False)
        assert gn.run(q.ravel().tolist(), 72) == optimiser.OK
        p_float, f_float = float_optimum(q / fixed.POINT_ONE_G)
        ratios.append(float_objective(q / fixed.POINT_ONE_G, gn.p) / f_float)
        # the device's own objective (Q24 g^4, floored) says the same to its resolution
        assert abs(gn.objective / 2.0 ** gn.OBJ_Q - f_float) <= 1e-3 * f_float + 72 * 2.0 ** -24
        gaps.append(np.abs(np.array(gn.p) / 2.0 ** 24 - p_float).max())
        assert gn.iterations <= 8
    assert max(ratios) < 1.001, max(ratios)          # target: within 1.02x
    assert max(gaps) < 5e-6, max(gaps)               # parameters to ~100 Q24 LSB


def test_paper_gradient_descent_stops_short_where_gauss_newton_does_not(rng):
    # Wrist-like coverage: points in posture clusters (wearer.POSTURES' directions), few near
    # the axes -> ill-conditioned; 50 steps of the paper's descent leave the objective well
    # above the optimum (2-3.5x on these seeds), Gauss-Newton reaches it.
    centres = np.array([[0, 0, 1], [0, 1, 0.1], [0.1, -0.9, 0.4], [-0.2, 0.5, -0.8],
                        [-0.35, 0.85, 0.35], [0.85, 0.3, 0.4], [-0.7, 0.3, 0.6], [0.1, 0.3, -0.95]])
    d = centres[rng.integers(0, 8, 72)] + rng.normal(scale=0.12, size=(72, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    truth = np.array([1.03, 0.98, 1.01, 0.02, -0.01, 0.015, 0.05, -0.03, 0.04])
    v = simulate.uncorrect(truth, d) + rng.normal(scale=1e-3, size=(72, 3))
    pts = q16(v).ravel().tolist()
    _, f_float = float_optimum(q16(v) / fixed.POINT_ONE_G)
    gd = Optimiser(72)
    gd.run(pts, 72, 50)
    gn = GaussNewton(72, reject=False)
    gn.run(pts, 72)
    assert float_objective(q16(v) / fixed.POINT_ONE_G, gn.p) / f_float < 1.001
    assert gd.objective / 2.0 ** fixed.OBJ_Q / f_float > 1.5


def test_outliers_leave_the_fit_and_the_parameters_return(rng):
    truth = np.array([1.02, 0.97, 1.01, 0.01, -0.02, 0.01, 0.04, -0.05, 0.03])
    d = simulate.unit_points(rng, 64)
    clean = simulate.uncorrect(truth, d) + rng.normal(scale=5e-4, size=(64, 3))
    # motion that passed a rest test: |v| 3-10 % off gravity
    bad = simulate.uncorrect(truth, simulate.unit_points(rng, 8)) * rng.uniform(1.03, 1.10, (8, 1))
    both = np.vstack([clean, bad])
    order = rng.permutation(72)
    gn = GaussNewton(72)
    assert gn.run(q16(both[order]).ravel().tolist(), 72) == optimiser.OK
    kept = np.array(gn.keep[:72], bool)
    injected = order >= 64
    assert not kept[injected].any()                     # every motion point rejected
    assert kept[~injected].sum() >= 62                  # and hardly a clean one
    ref = GaussNewton(64, reject=False)
    ref.run(q16(clean).ravel().tolist(), 64)
    with_outliers = GaussNewton(72, reject=False)
    with_outliers.run(q16(both).ravel().tolist(), 72)
    p, p_clean, p_bad = (np.array(o.p) / 2.0 ** 24 for o in (gn, ref, with_outliers))
    assert np.abs(p - p_clean).max() < 2e-4             # within the noise of the clean fit
    assert np.abs(p_bad - p_clean).max() > 5e-3         # which the outliers had moved


def test_sliced_fit_equals_one_shot_and_the_bins_lose_the_outliers(rng):
    truth = np.array([1.02, 0.97, 1.01, 0.01, -0.02, 0.01, 0.04, -0.05, 0.03])
    pts = simulate.uncorrect(truth, simulate.unit_points(rng, 300)) + rng.normal(scale=5e-4, size=(300, 3))
    pts[::37] *= 1.06  # outliers
    s = settings(WEAR)
    pipes = [Pipeline(100, **s) for _ in range(2)]
    for pipe in pipes:
        for x, y, z in q16(pts).tolist():
            pipe.offer(x, y, z)
        assert pipe.ready()
    one = pipes[0]
    status = one.calibrate()
    sliced = pipes[1]
    sliced.begin_fit()
    steps = 1
    extra = q16(simulate.uncorrect(truth, simulate.unit_points(rng, 40))).tolist()
    while not sliced.fit_step():
        if extra:  # the bins go on taking rest means while the fit runs on its own copy
            sliced.offer(*extra.pop())
        steps += 1
    assert steps > 20
    a, b = one.optimiser, sliced.optimiser
    assert (b.status, b.iterations, b.objective, b.p, b.keep) == (status, a.iterations, a.objective, a.p, a.keep)
    assert a.rejected >= 1
    held = {tuple(one.bins.point(s_, k)) for s_ in range(9) for k in range(one.bins.counts[s_])}
    rejected = {tuple(one.points[3 * i:3 * i + 3]) for i in range(a.n_given) if not a.keep[i]}
    assert rejected and not (held & rejected)


def test_noise_gauge_threshold_follows_the_noise(rng):
    # Still segments at the LIS3DH's noise at two rates, with motion between: the threshold
    # settles just above the still segments' spread and far below the motion's.
    for rate, sd_g in ((10, 0.0005), (100, 0.0016)):
        det = rest.RestDetector(rate, 5, rest.AUTO, rest.ALL_AXES)
        n = 5 * rate
        spreads = []
        for k in range(200):
            sd = sd_g if k % 3 else 0.03
            seg = np.round((np.array([0, 0, 1.0]) + rng.normal(scale=sd, size=(n, 3))) * 1024).astype(int)
            for x, y, z in seg.tolist():
                if det.add(x, y, z):
                    if sd == sd_g:
                        spreads.append(det.spread)
        quiet = np.percentile(spreads, 99.5)
        assert quiet < det.threshold <= 2 * quiet + rest.NOISE_ADD + 2, (rate, det.threshold, quiet)
        assert det.threshold < 0.03 * 1024


def test_coverage_readies_the_bins_without_a_face_down_point(rng):
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    d = d[d[:, 2] > -0.6]               # never face down (as a real wrist recording)
    b = dbins.Bins(2, 8, coverage=True)
    paper = dbins.Bins(2, 2)
    for x, y, z in q16(d).tolist():
        b.offer(x, y, z)
        paper.offer(x, y, z)
    assert paper.counts[6] == 0 and not paper.ready()   # the paper's C_zn never fills
    assert b.covered() and b.ready()
    assert min(b.counts) >= 2
    few = dbins.Bins(2, 8, coverage=True)   # one side of x missing: not covered
    for x, y, z in q16(d[d[:, 0] > -0.2]).tolist():
        few.offer(x, y, z)
    assert not few.covered()


def test_undetermined_parameters_are_refused(rng):
    # Every point with x = +1 g: scale and offset of x cannot be told apart.
    d = rng.normal(size=(40, 3)) * [0, 1, 1]
    d[:, 0] = 1.0
    d /= np.linalg.norm(d, axis=1)[:, None]
    d[:, 0] = np.abs(d[:, 0])
    gn = GaussNewton(40, reject=False)
    v = d.copy()
    v[:, 0] = 0.9  # one x value only
    assert gn.run(q16(v).ravel().tolist(), 40) == optimiser.UNDETERMINED


def wear_config(**kw):
    return runtime.Config.for_profile("wear", **kw)


def test_points_identical_under_micropython(rng, mp):
    groups = []
    for i in range(16):
        n = int(rng.integers(20, 400))
        _, v = simulate.paper_scenario(rng, n, float(rng.choice([1e-3, 5e-3])))
        v[rng.integers(0, n, n // 20)] *= rng.uniform(1.02, 1.1)  # outliers
        groups.append(runtime.Group(f"d{i}", points=v))
    cfg = wear_config()
    a = runtime.run(groups, cfg, "cpython")
    b = runtime.run(groups, cfg, mp)
    assert a == b
    assert sum(r.status == 0 for r in a) >= 10
    assert sum(r.kept is not None and 0 in r.kept for r in a) >= 3  # rejections compared too


def test_recordings_identical_under_micropython(rng, mp):
    groups = []
    for i in range(3):
        xyz, gaps = random_recording(rng, 120, 25)
        groups.append(runtime.Group(f"r{i}", samples=xyz, gaps=gaps))
    cfg = wear_config(rate_hz=25, seconds=2)
    a = runtime.run(groups, cfg, "cpython")
    b = runtime.run(groups, cfg, mp)
    assert a == b
    assert sum(len(r.rest_int) for r in a) > 50
    assert all(r.threshold for r in a)  # the gauge measured the noise


def test_composed_points_identical_under_micropython(rng, mp):
    truth = np.array([1.02, 0.97, 1.01, 0.01, -0.02, 0.01, 0.04, -0.05, 0.03])
    n = 600
    d = simulate.unit_points(rng, n)
    temp = rng.uniform(20, 36, n)
    v = simulate.uncorrect(truth, d) + 0.0008 * (temp - 28)[:, None] + rng.normal(scale=5e-4, size=(n, 3))
    g = runtime.Group("c", points=v, temp=temp, t=np.arange(n) * 300.0)
    from acal.core import effects
    cfg = wear_config(composed=True, kinds=(effects.TEMP_OFFSET,))
    a = runtime.run([g], cfg, "cpython")
    b = runtime.run([g], cfg, mp)
    assert a == b
    assert a[0].status == optimiser.OK
    c = np.array(a[0].params_int[9:12]) / (16 * 2.0 ** 24)  # g/degC
    assert np.abs(c - 0.0008).max() < 1e-4


@pytest.mark.parametrize("name", ["temp_offset", "temp_scale", "drift", "nonlinear"])
def test_composed_gauss_newton_reaches_the_float_optimum(name):
    # The points of tests/device/test_composed_fit.py (72 of them): the fit's objective within 1.02x of
    # the float minimiser of the same square-root-free objective, the effect found.
    from accelcal.model.effects import ModelSpec
    from test_composed_fit import points, T0
    import test_composed_fit as tcf
    old = tcf.N
    tcf.N = 72
    try:
        e, theta, v, temp, t, pts, aux, _ = points(name, 4)
    finally:
        tcf.N = old
    gn = GaussNewton(72, kinds=(e.kind,), reject=False)
    assert gn.run(pts, 72, 20, aux) == optimiser.OK
    spec = ModelSpec((name,))
    ref = {"T0": float(T0), "t0": 0.0}
    q = np.array(pts, float).reshape(-1, 3) / fixed.POINT_ONE_G
    # the device's regressors: Q2 degC from T0, 64 s units
    temp_i, t_i = np.array(aux[0::3]) / 4 + T0, np.array(aux[1::3]) * 64.0

    def res(th):
        a = spec.correct(th, q, temp_i.astype(float), t_i, ref)
        return (a * a).sum(axis=1) - 1.0
    x0 = np.r_[1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    best = least_squares(res, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    f_float = float((best.fun ** 2).sum())
    dev = np.r_[np.array(gn.p[:9]) / 2.0 ** 24, e.from_int(gn.p[9:])]
    assert gn.objective / 2.0 ** gn.OBJ_Q / f_float < 1.02
    assert np.abs(dev[9:] - theta).max() < 0.2 * np.abs(theta).max()


def test_paper_simulation_parameter_errors_equal_lsq_on_the_same_points():
    # Farago's Table 2 simulation through the wear profile: its errors are lsq's on the points
    # it kept (the paper profile's 50 gradient steps stop short: 1.2x at 1 mg, README Table 2)
    from accelcal.studies.paper import run_table2
    r = run_table2(scenarios=30, noise_mg=1, profile="wear")
    assert r.failed == 0
    assert abs(r.mean().sum() / r.mean("lsq").sum() - 1) < 0.01
    assert r.mean().sum() < 1.15 * r.mean("bound").sum()


def test_a_composed_fit_that_fails_keeps_the_base_calibration(rng):
    # drift with every point seen at the same time: its parameters are not determined, the
    # composed fit fails, and the pipeline keeps the base fit of the same points (effects zero)
    from acal.core import effects
    truth = np.array([1.02, 0.97, 1.01, 0.01, -0.02, 0.01, 0.04, -0.05, 0.03])
    pts = simulate.uncorrect(truth, simulate.unit_points(rng, 300)) + rng.normal(scale=5e-4, size=(300, 3))
    pipe = Pipeline(100, kinds=(effects.DRIFT,), **settings(WEAR))
    for x, y, z in q16(pts).tolist():
        pipe.offer(x, y, z)
    status = pipe.calibrate()
    assert status == optimiser.BASE_KEPT_FAILED and optimiser.usable(status)
    b = pipe.base_fit
    assert b.status == optimiser.OK
    assert list(pipe.optimiser.p[:9]) == list(b.p[:9]) and list(pipe.optimiser.p[9:]) == [0, 0, 0]
    assert np.abs(np.array(b.p) / 2.0 ** 24 - truth).max() < 2e-3   # and it is a good one
    assert "base calibration kept" in STATUS_NAMES[status]
