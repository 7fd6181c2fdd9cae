"""What every calibration method shares: the 9-parameter correction all of them are scored with
(Farago 2024 eqs. 7-9), the checks that turn degenerate input into a one-line reason, and the
mapping of a full ellipsoid (Gietzelt 2013 eqs. 2-3) onto that correction.

Every method takes rest points as an (N, 3) float array in g and returns the 9 parameters in the
order of eq. 6: kxx, kyy, kzz, kxy, kxz, kyz, ox, oy, oz, with a = K (v + o), K lower triangular.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

P0 = np.array([1, 1, 1, 0, 0, 0, 0, 0, 0], dtype=np.float64)


class FitError(Exception):
    """A method could not fit these points; the message says why in one line."""


@dataclass(frozen=True)
class Method:
    name: str              # the --method name
    fit: Callable          # (N, 3) g -> 9 parameters
    n_params: int          # parameters it estimates (6: eq. 1; 9: the full ellipsoid)
    role: str              # where it comes from, one line for tables and --help

    def __call__(self, v, **kw):
        """The fit; kw: what the fit takes beyond the points (de: progress)."""
        return self.fit(v, **kw)


REGISTRY: dict[str, Method] = {}


def method(name: str, n_params: int, role: str):
    """Register a fit function as `--method NAME`."""
    def wrap(fn):
        REGISTRY[name] = Method(name, fn, n_params, role)
        return fn
    return wrap


def k_matrix(p: np.ndarray) -> np.ndarray:
    return np.array([[p[0], 0, 0], [p[3], p[1], 0], [p[4], p[5], p[2]]], dtype=np.float64)


def correct(p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Eqs. 7-9 in float: a = K (v + o) for every row of v (N x 3, g)."""
    p = np.asarray(p, dtype=np.float64)
    return (np.asarray(v, dtype=np.float64) + p[6:9]) @ k_matrix(p).T


def jacobian_along(p: np.ndarray, v: np.ndarray, d: np.ndarray) -> np.ndarray:
    """d_i . da_i/dp for every point (N x 9), a = K (v + o): with d = a/|a| the Jacobian of |a|,
    with d = a half that of |a|^2."""
    u = v + p[6:9]
    J = np.empty((len(v), 9))
    J[:, 0] = d[:, 0] * u[:, 0]
    J[:, 1] = d[:, 1] * u[:, 1]
    J[:, 2] = d[:, 2] * u[:, 2]
    J[:, 3] = d[:, 1] * u[:, 0]
    J[:, 4] = d[:, 2] * u[:, 0]
    J[:, 5] = d[:, 2] * u[:, 1]
    J[:, 6:9] = d @ k_matrix(p)
    return J


def calibration_error_mg(p: np.ndarray | None, v: np.ndarray) -> float:
    """Mean over rest points of | |a| - 1 g |, in mg (Farago Table 3; GGIR's calibration error).
    p=None gives the error before calibration."""
    a = np.asarray(v, dtype=np.float64) if p is None else correct(p, v)
    if len(a) == 0:
        return float("nan")
    return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1.0)) * 1000.0)


def check_points(v, need: int, name: str) -> np.ndarray:
    """The points as (N, 3) float64, or FitError naming what makes them unusable for a method
    that estimates `need` parameters (coverage_reason)."""
    v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
    why = coverage_reason(v, need, name)
    if why:
        raise FitError(why)
    return v


# what the coverage rule says of one-sided points, here and for the device's bins (whose test is
# acal/core/hemisphere.py, the same rule in integers)
ONE_HEMISPHERE = ("cover one hemisphere only (all lie on one side of a plane through 0 g: one "
                  "orientation, or a device that never turned over); the other side is needed")


def coverage_reason(v: np.ndarray, need: int = 9, name: str = "a calibration") -> str | None:
    """Why points (N, 3) g cannot pin `need` parameters, or None: too few, not finite, collinear,
    coplanar, or all on one side of a plane through 0 g (one hemisphere: the centre is then an
    extrapolation).  The one coverage rule: every float method checks it, and compare and
    diagnose ask it of the points they fit (and hand the device) and of those they score."""
    if len(v) < need:
        return f"{name} estimates {need} parameters and needs at least {need} points, got {len(v)}"
    if not np.isfinite(v).all():
        return f"{name}: points contain NaN or infinite values"
    sv = np.linalg.svd(v - v.mean(axis=0), compute_uv=False)
    if sv[1] <= 1e-9 * max(sv[0], 1e-300):
        return (f"{name}: the {len(v)} points are collinear; an ellipsoid needs points in all "
                "directions")
    if sv[2] <= 1e-9 * sv[0]:
        return f"{name}: the {len(v)} points lie in one plane; an ellipsoid needs points off it"
    if one_side_margin(v) > 1e-9:
        return f"{name}: the {len(v)} points {ONE_HEMISPHERE}"
    return None


def one_side_margin(v: np.ndarray) -> float:
    """max over directions d (|d|_inf <= 1) of min_i d.v_i: > 0 exactly when every point lies
    strictly on one side of some plane through the origin.  A 4-variable linear programme."""
    from scipy.optimize import linprog
    n = len(v)
    res = linprog(c=[0, 0, 0, -1], A_ub=np.column_stack([-v, np.ones(n)]), b_ub=np.zeros(n),
                  bounds=[(-1, 1)] * 3 + [(None, 1e3)], method="highs")
    return float(-res.fun) if res.status == 0 else 0.0


def lower_factor(A: np.ndarray) -> np.ndarray:
    """The lower-triangular K with positive diagonal and K^T K = A (A symmetric positive
    definite): Cholesky of A with the axes reversed.  |K x| = |U x| for the paper's upper factor
    U (A = U^T U): the two differ by a rotation, which magnitudes cannot see."""
    J = np.eye(3)[::-1]
    L = np.linalg.cholesky(J @ A @ J)   # J A J = L L^T
    return (J @ L @ J).T                 # A = (J L J)(J L J)^T = K^T K, K = (J L J)^T lower


def from_ellipsoid(A: np.ndarray, centre: np.ndarray, name: str) -> np.ndarray:
    """Parameters of the ellipsoid (v - c)^T A (v - c) = 1 (Gietzelt eq. 2) as eq. 6:
    K = lower_factor(A), o = -c.  Exact: the 9-parameter model is the general ellipsoid."""
    A = (A + A.T) / 2
    if not np.all(np.isfinite(A)) or np.linalg.eigvalsh(A).min() <= 0:
        raise FitError(f"{name}: the fitted quadric is not an ellipsoid (its matrix is not "
                       "positive definite); the points do not cover enough directions")
    K = lower_factor(A)
    return np.array([K[0, 0], K[1, 1], K[2, 2], K[1, 0], K[2, 0], K[2, 1],
                     -centre[0], -centre[1], -centre[2]], dtype=np.float64)


def from_axes(centre: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Parameters of the axis-aligned ellipsoid of eq. 1 (centre o, radii s): k_ii = 1/s_i,
    no misalignment, o = -centre."""
    return np.r_[1.0 / np.asarray(radii, dtype=np.float64), 0, 0, 0, -np.asarray(centre)]


def upper_factor(p: np.ndarray) -> np.ndarray:
    """Gietzelt's U (eq. 3, A = U^T U, upper triangular) for parameters p: the form in which
    MgnCalibration and MinVolEllipsoid report scale (Table 4's starred values)."""
    K = k_matrix(p)
    return np.linalg.cholesky(K.T @ K).T


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
