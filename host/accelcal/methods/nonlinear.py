"""`lsq`: the float optimum of the paper's own model, the role MATLAB's fminunc plays in Farago
2024 Table 3, solved by Levenberg-Marquardt as Lukowicz et al. 2004 ("NonLinear" in Gietzelt 2013).

Minimises sum (|K (v + o)| - 1)^2 over all 9 parameters from p0 (K = I, o = 0: the a-priori
knowledge that the data is in g).  Represents everything the 9-parameter model can.
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import P0, FitError, check_points, correct, jacobian_along, method


def residual_jacobian(p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """d(|a| - 1)/dp for every point (N x 9)."""
    a = correct(p, v)
    return jacobian_along(p, v, a / np.linalg.norm(a, axis=1)[:, None])


@method("lsq", 9, "float least squares, Levenberg-Marquardt (fminunc's role; Lukowicz NonLinear)")
def lsq(v: np.ndarray) -> np.ndarray:
    """Optimal 9-parameter least squares on |K (v + o)| - 1, started at p0."""
    v = check_points(v, 9, "lsq")
    from scipy.optimize import least_squares   # here: scipy costs 0.4 s to import
    res = least_squares(lambda p: np.linalg.norm(correct(p, v), axis=1) - 1.0, P0,
                        jac=lambda p: residual_jacobian(p, v), method="lm",
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    if not np.all(np.isfinite(res.x)) or np.any(res.x[:3] <= 0):
        raise FitError("lsq did not converge to a valid calibration")
    return res.x
