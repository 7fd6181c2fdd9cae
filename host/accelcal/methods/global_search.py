"""`de`: a global search over the paper's 9-parameter model by differential evolution, the role
LabVIEW's global optimiser plays in Farago 2024 Table 3.

Minimises sum (|K (v + o)| - 1)^2 over the optimiser's fit region (k_ii in [0.5, 2], |k_ij| and
|o| <= 0.5 g) with scipy's differential_evolution, no gradient polish afterwards (a pure global
search, as LabVIEW's), fixed seed so a run is repeatable.  Represents everything the 9-parameter
model can; how close it gets is the population's convergence (about 1e-7 on noise-free points),
not numerical precision.
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import FitError, check_points, method

BOUNDS = [(0.5, 2.0)] * 3 + [(-0.5, 0.5)] * 6
SEED = 2024


def _objective(P: np.ndarray, v: np.ndarray) -> np.ndarray:
    """sum of squared residuals for a population P (9 x S), vectorised over members."""
    u = v[:, :, None] + P[6:9][None, :, :]             # N x 3 x S
    ax = P[0] * u[:, 0]
    ay = P[3] * u[:, 0] + P[1] * u[:, 1]
    az = P[4] * u[:, 0] + P[5] * u[:, 1] + P[2] * u[:, 2]
    r = np.sqrt(ax * ax + ay * ay + az * az) - 1.0
    return np.sum(r * r, axis=0)


@method("de", 9, "differential evolution, global search (LabVIEW's role)")
def de(v: np.ndarray) -> np.ndarray:
    v = check_points(v, 9, "de")
    from scipy.optimize import differential_evolution   # here: scipy costs 0.4 s to import
    res = differential_evolution(_objective, BOUNDS, args=(v,), vectorized=True, seed=SEED,
                                 popsize=20, maxiter=4000, tol=1e-14, atol=0, mutation=(0.5, 1.0),
                                 recombination=0.9, polish=False, updating="deferred")
    if not np.all(np.isfinite(res.x)):
        raise FitError("de did not converge")
    return res.x
