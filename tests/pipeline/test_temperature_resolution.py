"""The device's temperature condition is finer than a degree (Q2 degC, acal.core.fixed.TEMP_Q): a
recording's sub-degree temperatures reach the bins, the fit and its reference as quarter degrees,
and a curved temperature response fitted on them lands closer to the simulated truth than the
same points read in whole degrees (docs/model-discovery.md "Curves")."""
import numpy as np
import pytest

import accelcal
from acal.core.fixed import TEMP_Q
from accelcal import simulate
from accelcal.fixedpoint import device_conditions, physical
from accelcal.model.effects import CATALOGUE, ModelSpec

P_TRUE = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
MODEL = "base+temp_offset+temp_offset2"
REF = {"T0": 25.0, "t0": 0.0}      # the curve's vertex, as the simulator's effects have it


def test_sub_degree_temperatures_become_quarter_degrees():
    temp = np.array([24.9, 25.12, 25.13, 33.374, -3.3])
    cond = device_conditions(temp, np.zeros(5), 0.0, 5)
    assert cond[:, 0].tolist() == [round(x * (1 << TEMP_Q)) for x in temp]
    # back to degC to the device's resolution, a quarter degree
    assert np.abs(physical(cond, 0.0).temp - temp).max() <= 0.125


def _points(path, v, temp, t):
    rows = "\n".join(",".join(f"{c:.6f}" for c in r) + f",{T:.2f},{s:.0f}"
                     for r, T, s in zip(v, temp, t))
    path.write_text("x,y,z,temp,t\n" + rows + "\n")
    return str(path)


def _error_mg(rec, a, v, temp, t):
    """Mean |corrected - true| (mg) of a fit over points at their exact temperatures."""
    spec = ModelSpec.parse(MODEL)
    theta = spec.from_int([rec["params_int"][n] for n in spec.param_names])
    got = spec.correct(theta, v, temp, t, rec["reference"])
    return float(np.mean(np.linalg.norm(got - a, axis=1)) * 1e3)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_curve_fitted_on_quarter_degrees_is_closer_to_the_truth(tmp_path, seed):
    """Rest points of a sensor whose zero-g level curves about 25 degC, seen at 22-38 degC in
    0.01 degC steps (the simulated chip's): the device's fit of the curve on them scores closer
    to the truth (every point corrected at its exact temperature) than its fit of the same points
    with the temperatures rounded to whole degrees."""
    rng = np.random.default_rng(seed)
    n = 3000
    c = np.array([0.0006, -0.0005, 0.0004])            # g/degC
    e = np.array([0.00018, -0.00015, 0.00012])         # g/degC^2
    a = simulate.unit_points(rng, n)
    temp = np.round(rng.uniform(22.0, 38.0, n), 2)
    t = np.sort(rng.uniform(0, 3 * 86400, n))
    v = simulate.uncorrect(P_TRUE, a)
    v = CATALOGUE["temp_offset2"].measure(v, e, temp, t, REF)
    v = CATALOGUE["temp_offset"].measure(v, c, temp, t, REF)
    v = v + rng.normal(scale=0.0003, size=v.shape)
    fine = accelcal.calibrate(_points(tmp_path / "fine.csv", v, temp, t), model=MODEL)
    whole = accelcal.calibrate(_points(tmp_path / "whole.csv", v, np.rint(temp), t), model=MODEL)
    assert fine["status"] == whole["status"] == "calibrated"
    # the reference is the held points' middle temperature, in quarter degrees
    assert (fine["reference"]["T0"] * (1 << TEMP_Q)) % 1 == 0
    # a truth-scored comparison on fresh points across the range, at their exact temperatures
    b = simulate.unit_points(rng, 2000)
    temp2 = np.round(rng.uniform(22.0, 38.0, 2000), 2)
    w = simulate.uncorrect(P_TRUE, b)
    w = CATALOGUE["temp_offset2"].measure(w, e, temp2, t[:1], REF)
    w = CATALOGUE["temp_offset"].measure(w, c, temp2, t[:1], REF)
    err_fine = _error_mg(fine, b, w, temp2, np.zeros(2000))
    err_whole = _error_mg(whole, b, w, temp2, np.zeros(2000))
    print(seed, err_fine, err_whole)
    assert err_fine < err_whole, (err_fine, err_whole)
