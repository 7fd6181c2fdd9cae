"""The paper's simulation and the float reference methods, against known truth."""
import numpy as np
import pytest

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


def test_lsq_recovers_noise_free_truth(rng):
    for _ in range(5):
        p = simulate.random_params(rng)
        v = simulate.uncorrect(p, simulate.unit_points(rng, 18))
        assert np.abs(methods.lsq(v) - p).max() < 1e-9


def test_linauto_recovers_truth_with_equal_scales_and_no_misalignment(rng):
    p = simulate.random_params(rng)
    p[3:6] = 0
    p[1] = p[2] = p[0]
    v = simulate.uncorrect(p, simulate.unit_points(rng, 100))
    assert np.abs(methods.linauto(v) - p).max() < 1e-9


def test_linauto_unequal_scales_bias_the_centre_slightly(rng):
    # Its first step fits a sphere; unequal radii move the centre a little (Gietzelt 3.5: <= 1 %).
    p = simulate.random_params(rng)
    p[3:6] = 0
    v = simulate.uncorrect(p, simulate.unit_points(rng, 100))
    err = np.abs(methods.linauto(v) - p)
    assert 1e-6 < err.max() < 0.01


def test_linauto_cannot_represent_misalignment(rng):
    p = simulate.random_params(rng)
    p[3:6] = [0.05, -0.05, 0.04]
    v = simulate.uncorrect(p, simulate.unit_points(rng, 200))
    est = methods.linauto(v)
    assert (est[3:6] == 0).all()
    assert methods.calibration_error_mg(est, v) > 1.0  # what it cannot model stays as error


@pytest.mark.parametrize("fn", [methods.lsq, methods.linauto])
def test_too_few_points_is_a_fit_error(fn):
    with pytest.raises(methods.FitError):
        fn(np.ones((3, 3)))


def test_calibration_error_metric():
    v = np.array([[1.01, 0, 0], [0, 0.98, 0]])
    assert abs(methods.calibration_error_mg(None, v) - 15.0) < 1e-9
