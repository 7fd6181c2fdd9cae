"""`merayo`: Merayo et al. 2000, "MgnCalibration" in Gietzelt 2013: the full ellipsoid, rotation
included, by linear least squares, calibrated through the Cholesky factor (Gietzelt eqs. 2-3).

Fits the quadric a x^2 + b y^2 + c z^2 + 2d xy + 2e xz + 2f yz + 2g x + 2h y + 2i z = 1 (nine
unknowns, linear), then centre c = -M^-1 (g, h, i) and A = M / (1 + c^T M c) so that
(v - c)^T A (v - c) = 1.  Gietzelt calibrates with U (A = U^T U, upper); we map A onto the
lower-triangular K of the paper's model (K^T K = A): the same |a| for every point, so nothing
is lost — the 9-parameter model is the general ellipsoid.  The linear fit minimises an algebraic
error, not |a| - 1: with noise it is slightly biased, and it fails (not positive definite) when
the points do not cover enough directions.  The normalisation "= 1" needs 0 g inside the
ellipsoid, true of data in g.
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import FitError, check_points, from_ellipsoid, method


@method("merayo", 9, "Merayo 2000 MgnCalibration: full ellipsoid by linear LSQ, Cholesky factor")
def merayo(v: np.ndarray) -> np.ndarray:
    v = check_points(v, 9, "merayo")
    x, y, z = v.T
    D = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z])
    q, _, rank, _ = np.linalg.lstsq(D, np.ones(len(v)), rcond=None)
    if rank < 9:
        raise FitError("merayo: the points do not determine a quadric (rank-deficient)")
    a, b, c, d, e, f, g, h, i = q
    M = np.array([[a, d, e], [d, b, f], [e, f, c]])
    try:
        centre = -np.linalg.solve(M, [g, h, i])
    except np.linalg.LinAlgError:
        raise FitError("merayo: the fitted quadric has no centre") from None
    scale = 1.0 + centre @ M @ centre
    if scale <= 0:
        raise FitError("merayo: the fitted quadric is not an ellipsoid")
    return from_ellipsoid(M / scale, centre, "merayo")
