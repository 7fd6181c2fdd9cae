"""`linminvar`: Lotters et al. 1998, "LinMinVarEstimate" in Gietzelt 2013: a linear minimum
variance estimator of eq. 1's centre and radii, applied iteratively from a-priori initial values.

Each pass linearises f_i = sum_j ((v_ij - o_j) / s_j)^2 - 1 = 0 at the current estimate and
solves the linearised system by weighted least squares, each equation weighted by the inverse
of its variance under isotropic measurement noise (1 / |df_i/dv_i|^2: the minimum-variance
linear estimate); it stops when a pass moves the estimate by less than 1e-13.  Initial values:
o = 0 g, s = 1 g (the a-priori knowledge Gietzelt gave it: the nominal centre and radius).

Cannot represent: misalignment (kxy = kxz = kyz = 0 always).
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import FitError, check_points, from_axes, method

MAX_PASSES = 100


@method("linminvar", 6, "Lotters 1998 linear minimum-variance estimator, iterated")
def linminvar(v: np.ndarray, o0=(0.0, 0.0, 0.0), s0=(1.0, 1.0, 1.0)) -> np.ndarray:
    v = check_points(v, 6, "linminvar")
    o = np.array(o0, dtype=np.float64)
    s = np.array(s0, dtype=np.float64)
    for _ in range(MAX_PASSES):
        d = v - o
        f = np.sum((d / s) ** 2, axis=1) - 1.0
        J = np.column_stack([-2 * d / s ** 2, -2 * d ** 2 / s ** 3])   # df/do, df/ds
        w = 1.0 / np.maximum(np.sum((2 * d / s ** 2) ** 2, axis=1), 1e-300)
        Jw = J * w[:, None]
        try:
            step = np.linalg.solve(J.T @ Jw, -Jw.T @ f)
        except np.linalg.LinAlgError:
            raise FitError("linminvar: the linearised system is singular for these points") from None
        o, s = o + step[:3], s + step[3:]
        if not np.all(np.isfinite(step)) or np.any(s <= 0):
            raise FitError("linminvar diverged from its initial values (o = 0 g, s = 1 g)")
        if np.abs(step).max() < 1e-13:
            break
    else:
        if np.abs(step).max() > 1e-9:
            raise FitError(f"linminvar did not settle in {MAX_PASSES} passes")
    return from_axes(o, s)
