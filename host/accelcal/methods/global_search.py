"""`de`: a global search over the paper's 9-parameter model by differential evolution, the role
LabVIEW's global optimiser plays in Farago 2024 Table 3.

Minimises sum (|K (v + o)| - 1)^2 over the optimiser's fit region (k_ii in [0.5, 2], |k_ij| and
|o| <= 0.5 g) with scipy's differential_evolution, no gradient polish afterwards (a pure global
search, as LabVIEW's), fixed seed so a run is repeatable.  Represents everything the 9-parameter
model can; how close it gets is the population's convergence (about 1e-7 on noise-free points),
not numerical precision.
"""
from __future__ import annotations

import time

import numpy as np

from accelcal.methods.base import FitError, check_points, method

BOUNDS = [(0.5, 2.0)] * 3 + [(-0.5, 0.5)] * 6
SEED = 2024
POPSIZE = 20          # scipy's multiplier: 20 x 9 parameters = 180 members a generation
MAXITER = 4000        # generations at most; it stops sooner when the population converges
REPORT_S = 10.0       # progress: a line at most this often
FIRST_ESTIMATE = 20   # generations timed for the first estimate


def _objective(P: np.ndarray, v: np.ndarray) -> np.ndarray:
    """sum of squared residuals for a population P (9 x S), vectorised over members."""
    u = v[:, :, None] + P[6:9][None, :, :]             # N x 3 x S
    ax = P[0] * u[:, 0]
    ay = P[3] * u[:, 0] + P[1] * u[:, 1]
    az = P[4] * u[:, 0] + P[5] * u[:, 1] + P[2] * u[:, 2]
    r = np.sqrt(ax * ax + ay * ay + az * az) - 1.0
    return np.sum(r * r, axis=0)


@method("de", 9, "differential evolution, global search (LabVIEW's role)")
def de(v: np.ndarray, progress=None) -> np.ndarray:
    """progress(message): the search's size first; after FIRST_ESTIMATE generations the time a
    generation has taken here and so the time left at most, then the same at most every
    REPORT_S.  Measured, not computed: on 30 points a generation took ~6 ms, the objective
    0.1 ms of it (scipy's bookkeeping the rest), and the search ran all 4000."""
    v = check_points(v, 9, "de")
    from scipy.optimize import differential_evolution   # here: scipy costs 0.4 s to import
    step = None
    if progress:
        progress(f"    de: {len(v)} points, up to {MAXITER} generations of {POPSIZE * 9} members "
                 "(it stops sooner once the population converges)")
        start, said, gen = time.perf_counter(), [time.perf_counter()], [0]

        def step(*_args, **_kw):   # scipy's callback, either form; None: go on
            gen[0] += 1
            now = time.perf_counter()
            if gen[0] == FIRST_ESTIMATE or now - said[0] >= REPORT_S:
                said[0] = now
                per = (now - start) / gen[0]
                progress(f"    de: generation {gen[0]} of at most {MAXITER}, {now - start:.0f} s "
                         f"({per * 1e3:.1f} ms each): at most ~{per * (MAXITER - gen[0]):.0f} s "
                         "more")
    res = differential_evolution(_objective, BOUNDS, args=(v,), vectorized=True, seed=SEED,
                                 popsize=POPSIZE, maxiter=MAXITER, tol=1e-14, atol=0,
                                 mutation=(0.5, 1.0), recombination=0.9, polish=False,
                                 updating="deferred", callback=step)
    if not np.all(np.isfinite(res.x)):
        raise FitError("de did not converge")
    return res.x
