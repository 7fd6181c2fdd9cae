"""The device optimiser fits composed models (9 parameters + 3 per effect) on points that carry
temperature and time: near the float least-squares fit of the same points, and bit-identical
under MicroPython.  (Bins that gather such points on the device come next.)"""
import numpy as np
import pytest

from accelcal.bridge import runtime
from accelcal import simulate
from accelcal.pipeline.restpoints import RestPoints
from accelcal.pipeline.composed_lsq import fit
from accelcal.model.effects import CATALOGUE, ModelSpec, device_effects
from acal.core.gaussnewton import GaussNewton
from acal.core import effects as deff
from acal.core.fixed import TEMP_Q
from acal.paper.optimiser import OK, Optimiser

# The paper profile's gradient fit runs the catalogue's candidates; the device's generic offsets
# (shapes for declared effects) and the step are fitted by the wear profile's Gauss-Newton
# (below, and tests/pipeline/test_more_effects.py for the step's search).
GRADIENT_EFFECTS = [n for n in device_effects() if CATALOGUE[n].kind not in deff.SHAPES]
GENERIC_EFFECTS = [n for n in device_effects() if CATALOGUE[n].kind in deff.SHAPES
                   and not CATALOGUE[n].change_point]
P_TRUE = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
N, T0, V0, ITER = 36, 28, 3900, 200
REF = {"T0": float(T0), "t0": 0.0, "supply_mv0": float(V0)}


def points(name, seed, days=3, degrees=(22, 36)):
    """N points of a sensor with effect `name`, seen at random temperatures, times and supplies
    (mV, a LiPo's 3.6-4.2 V); aux: each point's dT, dt, dV as the device holds them (COND)."""
    rng = np.random.default_rng(seed)
    e = CATALOGUE[name]
    theta = e.draw(rng)
    a = simulate.unit_points(rng, N)
    temp = rng.integers(degrees[0], degrees[1], N).astype(float)
    t = np.floor(rng.uniform(0, days * 86400, N) / 64) * 64
    supply = rng.integers(3600, 4201, N).astype(float)
    v = e.measure(simulate.uncorrect(P_TRUE, a), theta, temp, t, REF, {"supply_mv": supply})
    v = v + rng.normal(scale=0.0005, size=v.shape)
    pts = np.rint(v * 65536).astype(int).ravel().tolist()
    aux = [x for Ti, ti, Vi in zip(temp, t, supply)
           for x in ((int(Ti) - T0) << TEMP_Q, int(ti) // 64, int(Vi) - V0)]   # Q2 degC
    return e, theta, v, temp, t, pts, aux, supply


def against_lsq(name, p_int, v, temp, t, supply):
    """The device's parameters and the float lsq fit of the same points: (their errors, the
    true 9 parameters' error without the effect, device and lsq effect parameters)."""
    e = CATALOGUE[name]
    dev = np.r_[np.array(p_int[:9]) / 2 ** 24, e.from_int(p_int[9:])]
    spec = ModelSpec((name,))
    cols = {"supply_mv": supply}
    lsq = fit(spec, RestPoints(v, t, temp, np.zeros(N), "points", cols), REF)
    err = [np.mean(np.abs(np.linalg.norm(spec.correct(th, v, temp, t, REF, cols), axis=1) - 1))
           for th in (dev, lsq)]
    base = np.mean(np.abs(np.linalg.norm(spec.correct(np.r_[P_TRUE, 0, 0, 0], v, temp, t, REF, cols),
                                         axis=1) - 1))
    return err, base, dev[9:], lsq[9:]


@pytest.mark.parametrize("name", GRADIENT_EFFECTS)
@pytest.mark.parametrize("seed", [1, 2])
def test_device_fit_of_a_composed_model_is_near_least_squares(name, seed):
    e, theta, v, temp, t, pts, aux, supply = points(name, seed)
    o = Optimiser(N, kinds=(e.kind,))
    assert o.run(pts, N, ITER, aux) == OK
    err, base, dev, lsq = against_lsq(name, o.p, v, temp, t, supply)
    assert err[0] < 1.25 * err[1] + 5e-5, err          # as good as the float optimum...
    assert err[0] < 0.5 * base, (err, base)             # ...and the effect is really fitted
    assert np.abs(dev - lsq).max() < 0.3 * np.abs(theta).max()


@pytest.mark.parametrize("name", GENERIC_EFFECTS)
@pytest.mark.parametrize("seed", [1, 2])
def test_gauss_newton_fits_the_generic_offsets_near_least_squares(name, seed):
    """The default fit (gaussnewton.py) of a generic offset (a declared effect's shape), on
    points over 10 days and +-28 degC (the powers grow past their unit: 6.07 days, 16 degC)."""
    e, theta, v, temp, t, pts, aux, supply = points(name, seed, days=10,
                                                    degrees=(T0 - 28, T0 + 29))
    o = GaussNewton(N, kinds=(e.kind,), reject=False)
    assert o.run(pts, N, 20, aux) == OK
    err, base, dev, lsq = against_lsq(name, o.p, v, temp, t, supply)
    assert err[0] < 1.05 * err[1] + 1e-6, err
    assert err[0] < 0.5 * base, (err, base)
    assert np.abs(dev - lsq).max() < 0.05 * np.abs(theta).max()


RUNNER = r'''
import sys
from acal.paper.optimiser import Optimiser
from acal.core.gaussnewton import GaussNewton
vals = [int(x) for x in open(sys.argv[1]).read().split()]
newton, kind, n, it = vals[0], vals[1], vals[2], vals[3]
pts = vals[4:4 + 3 * n]
aux = vals[4 + 3 * n:]
o = GaussNewton(n, (kind,), False) if newton else Optimiser(n, kinds=(kind,))
st = o.run(pts, n, it, aux)
print(st, o.iterations, o.objective, " ".join(map(str, o.p)))
'''


def test_composed_fit_is_bit_identical_under_micropython(tmp_path):
    """The gradient fit of each candidate effect, the Gauss-Newton fit of each generic offset."""
    script = tmp_path / "fit.py"
    script.write_text(RUNNER)
    for name in GRADIENT_EFFECTS + GENERIC_EFFECTS:
        newton = name in GENERIC_EFFECTS
        e, _, _, _, _, pts, aux, _ = points(name, 3, *((10, (T0 - 28, T0 + 29)) if newton else ()))
        data = tmp_path / f"{name}.txt"
        data.write_text(" ".join(map(str, [int(newton), e.kind, N, 20 if newton else 60, *pts, *aux])))
        o = GaussNewton(N, (e.kind,), False) if newton else Optimiser(N, kinds=(e.kind,))
        st = o.run(pts, N, 20 if newton else 60, aux)
        want = f"{st} {o.iterations} {o.objective} " + " ".join(map(str, o.p))
        assert runtime.run_micropython_script(str(script), str(data)).strip() == want
