"""Reference calibration methods in float64 (numpy/scipy), fitted on the same points as the device.

* lsq      - the optimal 9-parameter least squares on |K (v + o)| - 1 g (Levenberg-Marquardt):
             the role MATLAB's fminunc plays in Farago 2024 Table 3.
* linauto  - Gietzelt et al. 2013, "LinAutoCalibration": a linear sphere fit for the centre, then
             a linear fit of the per-axis radii.  Model a = (v - c) / s: it cannot represent
             misalignment (kxy = kxz = kyz = 0 always), and its first step assumes equal radii,
             so unequal scales bias the centre slightly (exact only for equal scales).
* float_device - the device's algorithm (forward-difference gradient descent, same h, rates,
             scaling and iterations) in float64: the yardstick the integer optimiser must track.

All take points as an (N, 3) array in g and return the 9 parameters in the order of eq. 6.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from acal import fixed

P0 = np.array([1, 1, 1, 0, 0, 0, 0, 0, 0], dtype=np.float64)


class FitError(Exception):
    """A method could not fit these points; the message says why in one line."""


def k_matrix(p: np.ndarray) -> np.ndarray:
    return np.array([[p[0], 0, 0], [p[3], p[1], 0], [p[4], p[5], p[2]]], dtype=np.float64)


def correct(p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Eqs. 7-9 in float: a = K (v + o) for every row of v (N x 3, g)."""
    p = np.asarray(p, dtype=np.float64)
    return (np.asarray(v, dtype=np.float64) + p[6:9]) @ k_matrix(p).T


def calibration_error_mg(p: np.ndarray | None, v: np.ndarray) -> float:
    """Mean over rest points of | |a| - 1 g |, in mg (Farago Table 3; GGIR's calibration error).
    p=None gives the error before calibration."""
    a = np.asarray(v, dtype=np.float64) if p is None else correct(p, v)
    if len(a) == 0:
        return float("nan")
    return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1.0)) * 1000.0)


def _check(v: np.ndarray, need: int, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    if len(v) < need:
        raise FitError(f"{name} needs at least {need} points, got {len(v)}")
    return v


def lsq(v: np.ndarray) -> np.ndarray:
    """Optimal 9-parameter least squares on |K (v + o)| - 1, started at p0."""
    v = _check(v, 9, "lsq")

    def residual(p):
        return np.linalg.norm(correct(p, v), axis=1) - 1.0

    def jac(p):
        u = v + p[6:9]
        a = u @ k_matrix(p).T
        r = np.linalg.norm(a, axis=1)[:, None]
        d = a / r  # d|a|/da
        J = np.empty((len(v), 9))
        J[:, 0] = d[:, 0] * u[:, 0]
        J[:, 1] = d[:, 1] * u[:, 1]
        J[:, 2] = d[:, 2] * u[:, 2]
        J[:, 3] = d[:, 1] * u[:, 0]
        J[:, 4] = d[:, 2] * u[:, 0]
        J[:, 5] = d[:, 2] * u[:, 1]
        K = k_matrix(p)
        J[:, 6:9] = d @ K
        return J

    res = least_squares(residual, P0, jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if not np.all(np.isfinite(res.x)):
        raise FitError("lsq did not converge")
    return res.x


def linauto(v: np.ndarray) -> np.ndarray:
    """Gietzelt 2013 LinAutoCalibration (eqs. 6-17), mapped to kii = 1/s_i, o = -c, no misalignment."""
    v = _check(v, 4, "linauto")
    # Step 1: sphere x^2+y^2+z^2 + B x + C y + D z + A = 0 by linear least squares -> centre.
    M = np.column_stack([v, np.ones(len(v))])
    rhs = -np.sum(v * v, axis=1)
    sol, _, rank, _ = np.linalg.lstsq(M, rhs, rcond=None)
    if rank < 4:
        raise FitError("linauto: points are degenerate (they do not span a sphere)")
    centre = -sol[:3] / 2.0
    # Step 2: t_x X + t_y Y + t_z Z = 1 with X = (v_x - c_x)^2 ...; s_i = 1 / sqrt(t_i).
    X = (v - centre) ** 2
    t, _, rank, _ = np.linalg.lstsq(X, np.ones(len(v)), rcond=None)
    if rank < 3 or np.any(t <= 0):
        raise FitError("linauto: radii are not all positive; points do not cover the ellipsoid")
    k = np.sqrt(t)
    return np.array([k[0], k[1], k[2], 0, 0, 0, -centre[0], -centre[1], -centre[2]])


def float_device(v: np.ndarray, iterations: int = 50,
                 alphas=(0.3, 0.8, 0.2), scaling: str = "mean") -> tuple[np.ndarray, bool]:
    """The device optimiser's algorithm in float64: same p0, h = 2**-17, rates, iterations.

    scaling="mean" divides the gradient of the summed objective by N (what the device does);
    scaling="sum" uses the plain sum.  Returns (params, diverged)."""
    v = _check(v, 9, "float_device")
    n = len(v)
    h = 2.0 ** -fixed.H_SHIFT
    alpha = np.repeat(np.asarray(alphas, dtype=np.float64), 3)
    div = n if scaling == "mean" else 1

    def f(p):
        a = correct(p, v)
        r = np.sum(a * a, axis=1) - 1.0
        return float(np.sum(r * r))

    p = P0.copy()
    f0 = f(p)
    start = f0
    for _ in range(iterations):
        g = np.empty(9)
        for i in range(9):
            q = p.copy()
            q[i] += h
            g[i] = (f(q) - f0) / h
        p = p - alpha * g / div
        if not np.all(np.isfinite(p)) or np.any(np.abs(p - P0) > 0.5):
            return p, True
        f0 = f(p)
    return p, f0 > start


def fisher_bound(p_true: np.ndarray, v: np.ndarray, noise_g: float) -> np.ndarray:
    """Cramer-Rao bound on the mean absolute error of each parameter for these points, with
    isotropic Gaussian noise of sd noise_g per axis: sqrt(2/pi) * sqrt(diag(sigma^2 (J^T J)^-1)),
    J the Jacobian of |a| - 1 at the truth (the radial noise component has sd noise_g)."""
    v = np.asarray(v, dtype=np.float64)
    eps = 1e-7
    base = np.linalg.norm(correct(p_true, v), axis=1)
    J = np.empty((len(v), 9))
    for i in range(9):
        q = np.array(p_true, dtype=np.float64)
        q[i] += eps
        J[:, i] = (np.linalg.norm(correct(q, v), axis=1) - base) / eps
    cov = noise_g ** 2 * np.linalg.pinv(J.T @ J)
    return np.sqrt(2 / np.pi) * np.sqrt(np.clip(np.diag(cov), 0, None))


METHODS = {"lsq": lsq, "linauto": linauto}
