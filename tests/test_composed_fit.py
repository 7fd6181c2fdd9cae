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
from acal.optimiser import OK, Optimiser

P_TRUE = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
N, T0, ITER = 36, 28, 200


def points(name, seed):
    rng = np.random.default_rng(seed)
    e = CATALOGUE[name]
    theta = e.draw(rng)
    a = simulate.unit_points(rng, N)
    temp = rng.integers(22, 36, N).astype(float)
    t = np.floor(rng.uniform(0, 3 * 86400, N) / 64) * 64
    v = e.measure(simulate.uncorrect(P_TRUE, a), theta, temp, t, {"T0": T0, "t0": 0.0})
    v = v + rng.normal(scale=0.0005, size=v.shape)
    pts = np.rint(v * 65536).astype(int).ravel().tolist()
    aux = [x for Ti, ti in zip(temp, t) for x in (int(Ti) - T0, int(ti) // 64)]
    return e, theta, v, temp, t, pts, aux


@pytest.mark.parametrize("name", device_effects())
@pytest.mark.parametrize("seed", [1, 2])
def test_device_fit_of_a_composed_model_is_near_least_squares(name, seed):
    e, theta, v, temp, t, pts, aux = points(name, seed)
    o = Optimiser(N, kinds=(e.kind,))
    assert o.run(pts, N, ITER, aux) == OK
    dev = np.r_[np.array(o.p[:9]) / 2 ** 24, e.from_int(o.p[9:])]
    spec = ModelSpec((name,))
    ref = {"T0": float(T0), "t0": 0.0}
    lsq = fit(spec, RestPoints(v, t, temp, np.zeros(N), "points"), ref)
    err = [np.mean(np.abs(np.linalg.norm(spec.correct(th, v, temp, t, ref), axis=1) - 1)) for th in (dev, lsq)]
    base = np.mean(np.abs(np.linalg.norm(spec.correct(np.r_[P_TRUE, 0, 0, 0], v, temp, t, ref), axis=1) - 1))
    assert err[0] < 1.25 * err[1] + 5e-5, err          # as good as the float optimum...
    assert err[0] < 0.5 * base, (err, base)             # ...and the effect is really fitted
    assert np.abs(dev[9:] - lsq[9:]).max() < 0.3 * np.abs(theta).max()


RUNNER = r'''
import sys
from acal.optimiser import Optimiser
vals = [int(x) for x in open(sys.argv[1]).read().split()]
kind, n, it = vals[0], vals[1], vals[2]
pts = vals[3:3 + 3 * n]
aux = vals[3 + 3 * n:]
o = Optimiser(n, kinds=(kind,))
st = o.run(pts, n, it, aux)
print(st, o.iterations, o.objective, " ".join(map(str, o.p)))
'''


def test_composed_fit_is_bit_identical_under_micropython(tmp_path):
    script = tmp_path / "fit.py"
    script.write_text(RUNNER)
    for name in device_effects():
        e, _, _, _, _, pts, aux = points(name, 3)
        data = tmp_path / f"{name}.txt"
        data.write_text(" ".join(map(str, [e.kind, N, 60, *pts, *aux])))
        o = Optimiser(N, kinds=(e.kind,))
        st = o.run(pts, N, 60, aux)
        want = f"{st} {o.iterations} {o.objective} " + " ".join(map(str, o.p))
        assert runtime.run_micropython_script(str(script), str(data)).strip() == want
