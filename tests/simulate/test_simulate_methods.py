"""The paper's simulation against known truth, and the Table 3 metric (the methods themselves:
test_methods.py)."""
import numpy as np

from accelcal import methods, simulate


def test_uncorrect_inverts_eqs_7_to_9(rng):
    for _ in range(20):
        p = simulate.random_params(rng)
        a = simulate.unit_points(rng, 100)
        assert np.abs(methods.correct(p, simulate.uncorrect(p, a)) - a).max() < 1e-14


def test_printed_eq19_is_not_the_inverse(rng):
    # Eq. 19 as printed (c_y uses c_x - o_x, c_z uses c_x + o_x): off by ~2 o_x kxy / kyy.
    p = simulate.random_params(rng)
    p[6] = 0.08
    a = simulate.unit_points(rng, 50)
    kxx, kyy, kzz, kxy, kxz, kyz, ox, oy, oz = p
    cx = a[:, 0] / kxx - ox
    cy = (a[:, 1] - (cx - ox) * kxy) / kyy - oy
    printed = methods.correct(p, np.column_stack([cx, cy, simulate.uncorrect(p, a)[:, 2]]))
    assert np.abs(printed[:, 1] - a[:, 1]).max() > 1e-4


def test_parameter_ranges_of_eq17(rng):
    ps = np.array([simulate.random_params(rng) for _ in range(2000)])
    assert (np.abs(ps[:, :3] - 1) <= 0.1).all() and (np.abs(ps[:, 6:]) <= 0.1).all()
    assert (np.abs(ps[:, 3:6]) <= 0.1 * 0.05 + 0.05).all()
    assert np.abs(ps[:, 0].mean() - 1) < 0.01


def test_calibration_error_metric():
    v = np.array([[1.01, 0, 0], [0, 0.98, 0]])
    assert abs(methods.calibration_error_mg(None, v) - 15.0) < 1e-9
