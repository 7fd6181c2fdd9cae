"""The composed model in float: least squares of | |a| - 1 g | over rest points for base+effects
(scipy), the reference the effects are measured from, and `calibrate --method lsq` of a composed
model.  The float twin of the device's composed fit (device/acal/gaussnewton.py), and the fit
diagnose scores its candidates with."""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from accelcal.errors import InputError
from accelcal.methods import calibration_error_mg
from accelcal.model.effects import CATALOGUE, ModelSpec
from accelcal.pipeline.results import CalibrationResult
from accelcal.pipeline.restpoints import RestPoints, check_coverage, rest_points, usable


def check_model(spec: ModelSpec, p: RestPoints) -> None:
    """Exit-2 reasons for a model the data cannot support."""
    try:
        spec.check_data(p.temp, p.t, p.source)
    except ValueError as e:
        raise InputError(str(e)) from None


def prepare(path: str, model: str) -> tuple[ModelSpec, RestPoints]:
    """The model spec and the file's usable rest points, or a one-line reason why not."""
    try:
        spec = ModelSpec.parse(model)
    except ValueError as e:
        raise InputError(str(e)) from None
    p = usable(rest_points(path))
    check_coverage(p)
    check_model(spec, p)
    return spec, p


def refs(p: RestPoints) -> dict:
    """The effects' reference: mean temperature rounded to a whole degC (the device's resolution:
    a saved lsq model applies there exactly), first time."""
    return {"T0": float(np.round(np.mean(p.temp))) if p.temp is not None else 0.0,
            "t0": float(p.t.min())}


def fit(spec: ModelSpec, p: RestPoints, ref: dict) -> np.ndarray:
    """Float least squares of | |a| - 1 | over the points for a composed model."""
    n_eff = len(spec.effects)
    x0 = np.r_[1, 1, 1, 0, 0, 0, 0, 0, 0, np.zeros(3 * n_eff)]
    lo = np.r_[[0.5] * 3, [-0.5] * 3, [-0.5] * 3]
    hi = np.r_[[2.0] * 3, [0.5] * 3, [0.5] * 3]
    for name in spec.effects:
        b = CATALOGUE[name].bound
        lo, hi = np.r_[lo, [-b] * 3], np.r_[hi, [b] * 3]
    temp = p.temp if p.temp is not None else np.zeros(len(p.t))

    def resid(th):
        return np.linalg.norm(spec.correct(th, p.v, temp, p.t, ref), axis=1) - 1.0
    return least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", method="trf").x


def residuals(spec, theta, p, ref):
    temp = p.temp if p.temp is not None else np.zeros(len(p.t))
    a = spec.correct(theta, p.v, temp, p.t, ref)
    return a, np.linalg.norm(a, axis=1) - 1.0


def calibrate_model(path: str, model: str) -> CalibrationResult:
    """`calibrate --model SPEC --method lsq`: the composed model fitted (float) on every usable
    rest point of the file; error before/after on the same points."""
    spec, p = prepare(path, model)
    ref = refs(p)
    theta = fit(spec, p, ref)
    a, r = residuals(spec, theta, p, ref)
    p_int = spec.to_int(theta)  # the device's integers (device/acal/effects.py)
    return CalibrationResult(model=str(spec), method="lsq", status="calibrated",
                             params=dict(zip(spec.param_names, theta.tolist())),
                             params_int=dict(zip(spec.param_names, p_int)), reference=ref,
                             rest_points=len(p), points=len(p), iterations=None,
                             error_before_mg=calibration_error_mg(None, p.v),
                             error_after_mg=float(np.mean(np.abs(r)) * 1e3))
