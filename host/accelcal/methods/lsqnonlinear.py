"""`campolo`: Campolo et al. 2006, "LsqNonLinear" in Gietzelt 2013: eq. 1's centre and radii by
non-linear least squares from Campolo's initial-value rule (Gietzelt eq. 4).

Initial values: the centre is the mean of the points, every radius the mean distance from it
(eq. 4).  Error of fit: |(v - o) / s| - 1 per point, solved by the trust-region-reflective
method of MATLAB's lsqnonlin (Coleman and Li, Gietzelt ref. 18).  On points biased to one
direction (a wrist at rest) the mean is far from the centre and the solver has further to go.

Cannot represent: misalignment (kxy = kxz = kyz = 0 always).
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import FitError, check_points, from_axes, method


def initial_values(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Campolo's rule (Gietzelt eq. 4): centre = mean, radius = mean distance to it."""
    o = v.mean(axis=0)
    r = np.mean(np.linalg.norm(v - o, axis=1))
    return o, np.full(3, r)


@method("campolo", 6, "Campolo 2006 LsqNonLinear: eq. 1 by trust-region LSQ, eq. 4 initial values")
def campolo(v: np.ndarray) -> np.ndarray:
    v = check_points(v, 6, "campolo")
    o, s = initial_values(v)

    def resid(x):
        return np.linalg.norm((v - x[:3]) / x[3:], axis=1) - 1.0

    def jac(x):
        d = (v - x[:3]) / x[3:]
        n = np.linalg.norm(d, axis=1)[:, None]
        g = d / n                                   # d|d|/dd
        return np.column_stack([-g / x[3:], -g * d / x[3:]])

    from scipy.optimize import least_squares   # here: scipy costs 0.4 s to import
    res = least_squares(resid, np.r_[o, s], jac=jac, method="trf", xtol=1e-15, ftol=1e-15,
                        gtol=1e-15, max_nfev=2000)
    if not np.all(np.isfinite(res.x)) or np.any(res.x[3:] <= 0):
        raise FitError("campolo did not converge to positive radii")
    return from_axes(res.x[:3], res.x[3:])
