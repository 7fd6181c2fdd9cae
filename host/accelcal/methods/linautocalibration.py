"""`linauto`: Gietzelt et al. 2013 "LinAutoCalibration" (eqs. 5-17), non-iterative: a linear
sphere fit for the centre, then a linear fit of the per-axis radii (the "non-iterative method"
of Farago 2024 Table 3).

Model a = (v - c) / s mapped to k_ii = 1/s_i, o = -c.  Cannot represent: misalignment (kxy = kxz
= kyz = 0 always).  Its first step assumes equal radii, so unequal scales bias the centre a
little (exact only for equal scales; Gietzelt 3.5: <= 1 % at axes 1:2:3).
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import FitError, check_points, from_axes, method


@method("linauto", 6, "Gietzelt 2013 LinAutoCalibration, non-iterative (Farago's 'non-iterative')")
def linauto(v: np.ndarray) -> np.ndarray:
    v = check_points(v, 6, "linauto")
    # Step 1 (eqs. 9-11): A + B x + C y + D z = -(x^2 + y^2 + z^2) -> centre = -(B, C, D) / 2.
    M = np.column_stack([np.ones(len(v)), v])
    sol, _, rank, _ = np.linalg.lstsq(M, -np.sum(v * v, axis=1), rcond=None)
    if rank < 4:
        raise FitError("linauto: the points do not determine a sphere")
    centre = -sol[1:] / 2.0
    # Step 2 (eqs. 13-17): t_x X + t_y Y + t_z Z = 1, X = (v_x - c_x)^2, ...; s_i = 1/sqrt(t_i).
    X = (v - centre) ** 2
    t, _, rank, _ = np.linalg.lstsq(X, np.ones(len(v)), rcond=None)
    if rank < 3 or np.any(t <= 0):
        raise FitError("linauto: radii are not all positive; the points do not cover the ellipsoid")
    return from_axes(centre, 1.0 / np.sqrt(t))
