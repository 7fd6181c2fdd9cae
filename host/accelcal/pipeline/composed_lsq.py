"""The composed model in float: least squares of | |a| - 1 g | over rest points for base+effects
(scipy), the reference the effects are measured from, and `calibrate --method lsq` of a composed
model.  The float twin of the device's composed fit (device/acal/core/gaussnewton.py), and the fit
diagnose scores its candidates with."""
from __future__ import annotations

import numpy as np

from acal.core.fixed import TEMP_Q

from accelcal.errors import InputError, ModelUnsupported
from accelcal.methods import calibration_error_mg
from accelcal.model.effects import ModelSpec, column_ref
from accelcal.pipeline.results import CalibrationResult
from accelcal.pipeline.restpoints import RestPoints, check_coverage, rest_points, usable


def check_model(spec: ModelSpec, p: RestPoints) -> None:
    """Exit-2 reasons for a model the data cannot support."""
    try:
        spec.check_data(p.temp, p.t, p.source, p.cols)
    except ValueError as e:
        raise ModelUnsupported(str(e)) from None


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


def refs(p: RestPoints, spec: ModelSpec | None = None) -> dict:
    """The effects' reference: mean temperature rounded to the device's resolution (Q2 degC,
    acal.core.fixed.TEMP_Q: a saved lsq model applies there exactly), first time, and the mean of each
    recording column spec's effects follow."""
    one = 1 << TEMP_Q
    out = {"T0": float(np.round(np.mean(p.temp) * one) / one) if p.temp is not None else 0.0,
           "t0": float(p.t.min())}
    for c in (spec.columns if spec is not None else ()):
        out[column_ref(c)] = float(np.mean(p.cols[c]))
    return out


def fit(spec: ModelSpec, p: RestPoints, ref: dict, start: np.ndarray | None = None) -> np.ndarray:
    """Float least squares of | |a| - 1 | over the points for a composed model.  start: the
    fitted parameters of the model without its last effect (that effect starts at 0), where the
    caller has them: the same optimum, reached in fewer steps."""
    n_eff = len(spec.effects)
    x0 = np.r_[1, 1, 1, 0, 0, 0, 0, 0, 0, np.zeros(3 * n_eff)]
    lo = np.r_[[0.5] * 3, [-0.5] * 3, [-0.5] * 3]
    hi = np.r_[[2.0] * 3, [0.5] * 3, [0.5] * 3]
    for e in spec.parts:
        b = e.bound
        lo, hi = np.r_[lo, [-b] * 3], np.r_[hi, [b] * 3]
    if start is not None:
        x0[:len(start)] = start
        x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))
    temp = p.temp if p.temp is not None else np.zeros(len(p.t))

    def resid(th):
        return np.linalg.norm(spec.correct(th, p.v, temp, p.t, ref, p.cols), axis=1) - 1.0
    from scipy.optimize import least_squares   # here: scipy costs 0.4 s to import
    return least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", method="trf").x


MIN_SIDE = 0.1   # a step's time leaves at least this share of the points on either side


def change_point(r: np.ndarray, n: np.ndarray, t: np.ndarray) -> float:
    """Where one offset step best explains residuals r (| |a| - 1 |, g) of points with unit
    directions n (N, 3) at times t: for a step d from ts on, r ~ n . d after ts (first order),
    so every split k of the time-sorted points is scored by the least-squares reduction
    b_k^T S_k^-1 b_k, with S_k = sum n n^T and b_k = sum n r over the points after it - all splits
    at once from reverse cumulative sums.  Returns ts halfway between the two points of the best
    split (MIN_SIDE of the points kept on each side)."""
    order = np.argsort(t, kind="stable")
    r, n, t = r[order], n[order], t[order]
    outer = np.einsum("ni,nj->nij", n, n)
    S = np.cumsum(outer[::-1], axis=0)[::-1]             # S[k]: points k.. N-1
    b = np.cumsum((n * r[:, None])[::-1], axis=0)[::-1]
    lo, hi = max(1, int(MIN_SIDE * len(t))), min(len(t) - 1, int((1 - MIN_SIDE) * len(t)))
    ks = np.arange(lo, hi)
    ks = ks[t[ks] > t[ks - 1]]                           # a split between distinct times
    if not len(ks):
        raise InputError("a step needs rest points at more than a few distinct times")
    Sk = S[ks] + 1e-9 * np.eye(3)
    gain = np.einsum("ki,ki->k", b[ks], np.linalg.solve(Sk, b[ks][:, :, None])[:, :, 0])
    k = int(ks[np.argmax(gain)])
    return float(0.5 * (t[k - 1] + t[k]))


def fit_with_reference(spec: ModelSpec, p: RestPoints, ref: dict,
                       rest_theta: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """fit(), first finding what the reference lacks: a step's time (change_point on the
    residuals of the model without the step), then the whole model at that time.  rest_theta:
    the fitted parameters of spec without its last effect, where the caller has them (diagnose's
    candidates): the fit starts there, and a step that is that last effect searches its time on
    that model's residuals."""
    missing = [c for c in spec.columns if column_ref(c) not in ref]
    if missing:   # a column effect added to a model fitted without it (diagnose's candidates)
        ref = {**ref, **{column_ref(c): float(np.mean(p.cols[c])) for c in missing}}
    name = spec.change_point
    if name is not None and "ts" not in ref:
        rest = spec.without(name)
        th = rest_theta if rest_theta is not None and spec.effects[-1] == name else fit(rest, p, ref)
        a, r = residuals(rest, th, p, ref)
        n = a / np.linalg.norm(a, axis=1)[:, None]
        ref = {**ref, "ts": change_point(r, n, p.t)}
    return fit(spec, p, ref, rest_theta), ref


def residuals(spec, theta, p, ref):
    temp = p.temp if p.temp is not None else np.zeros(len(p.t))
    a = spec.correct(theta, p.v, temp, p.t, ref, p.cols)
    return a, np.linalg.norm(a, axis=1) - 1.0


def calibrate_model(path: str, model: str) -> CalibrationResult:
    """`calibrate --model SPEC --method lsq`: the composed model fitted (float) on every usable
    rest point of the file; error before/after on the same points."""
    spec, p = prepare(path, model)
    theta, ref = fit_with_reference(spec, p, refs(p, spec))
    a, r = residuals(spec, theta, p, ref)
    p_int = spec.to_int(theta)  # the device's integers (device/acal/core/effects.py)
    return CalibrationResult(model=str(spec), method="lsq", status="calibrated",
                             params=dict(zip(spec.param_names, theta.tolist())),
                             params_int=dict(zip(spec.param_names, p_int)), reference=ref,
                             rest_points=len(p), points=len(p), iterations=None,
                             error_before_mg=calibration_error_mg(None, p.v),
                             error_after_mg=float(np.mean(np.abs(r)) * 1e3))
