"""`minvol`: Bonnet et al. 2009, "MinVolEllipsoid" in Gietzelt 2013: the minimum-volume
ellipsoid enclosing all points, by Khachiyan's algorithm with Todd and Yildirim's away steps
(Gietzelt ref. 13), mapped onto the paper's model through A as `merayo` is.  Khachiyan converges
linearly and slowly near the optimum, so it runs to 1e-3 and the optimum is then polished
exactly: maximise log det K subject to |K (v + o)| <= 1 (the same ellipsoid in the paper's
parameters) by SLSQP on the points near the boundary, until no point is outside.

It always returns a valid ellipsoid, but an *enclosing* one: every point, noise included, lies
inside, so noisy points inflate it (radii too large, scale factors too small, the shape pulled
towards the noisiest points).  This is the weakness Gietzelt reports (Table 4, section 3.6):
exact on noise-free points, the worst of all methods on noisy ones.
"""
from __future__ import annotations

import numpy as np

from accelcal.methods.base import (FitError, check_points, correct, from_ellipsoid, jacobian_along,
                                   method)

TOLERANCE = 1e-3   # Khachiyan's; the polish takes it to numerical precision
MAX_ITERATIONS = 200_000


def khachiyan(P: np.ndarray, tol: float = TOLERANCE, moshtagh: bool = False
              ) -> tuple[np.ndarray, np.ndarray]:
    """(A, c) of the minimum-volume ellipsoid {x : (x - c)^T A (x - c) <= 1} around the rows of P.
    Weights u on the points; each step moves weight to the point furthest outside (or away from
    the point most inside) until every point is within (1 + tol) of the boundary.

    moshtagh=True: plain Khachiyan stopped when a step changes the weights by less than tol
    (norm), as the MATLAB code Gietzelt used (his ref. 14, called with tol = 0.01): it stops far
    from the optimum, which is part of what Gietzelt's Table 4 shows for MinVolEllipsoid."""
    n, d = P.shape
    Q = np.column_stack([P, np.ones(n)]).T            # (d+1) x n, lifted
    u = np.full(n, 1.0 / n)
    for _ in range(MAX_ITERATIONS):
        X = (Q * u) @ Q.T
        m = np.einsum("ij,ij->j", Q, np.linalg.solve(X, Q))   # Mahalanobis of each lifted point
        j = int(np.argmax(m))
        support = u > 0
        k = int(np.flatnonzero(support)[np.argmin(m[support])])
        up, down = m[j] - (d + 1), (d + 1) - m[k]
        if not moshtagh and up <= tol * (d + 1) and down <= tol * (d + 1):
            break
        if moshtagh or up >= down:   # Khachiyan's step towards the furthest point
            step = (m[j] - d - 1) / ((d + 1) * (m[j] - 1))
            u_before = u.copy() if moshtagh else None
            u *= 1 - step
            u[j] += step
            if moshtagh and np.linalg.norm(u - u_before) < tol:
                break
        else:            # away step: take weight off the point most inside
            step = min((d + 1 - m[k]) / ((d + 1) * (m[k] - 1)), u[k] / (1 - u[k]))
            u *= 1 + step
            u[k] -= step
            u[k] = max(u[k], 0.0)
    else:
        raise FitError(f"minvol did not converge in {MAX_ITERATIONS} iterations")
    c = P.T @ u
    A = np.linalg.inv((P.T * u) @ P - np.outer(c, c)) / d
    return A, c


@method("minvol", 9, "Bonnet 2009 MinVolEllipsoid: minimum-volume enclosing ellipsoid (Khachiyan)")
def minvol(v: np.ndarray, tol: float = TOLERANCE, moshtagh: bool = False) -> np.ndarray:
    """moshtagh=True: Khachiyan alone, stopped as Gietzelt's MATLAB code stops (no polish)."""
    v = check_points(v, 9, "minvol")
    A, c = khachiyan(v, tol, moshtagh)
    p = from_ellipsoid(A, c, "minvol")
    return p if moshtagh else polish(v, p)


def polish(v: np.ndarray, p0: np.ndarray, rounds: int = 5) -> np.ndarray:
    """The exact minimum-volume enclosing ellipsoid from a near one: minimise -log det K =
    -sum log k_ii subject to |K (v_i + o)|^2 <= 1, constraints on the points that are near the
    boundary of p0's ellipsoid (the others cannot be active), re-solved with any point found
    outside."""
    near = np.linalg.norm(correct(p0, v), axis=1) >= 0.9

    def inside(p, w):
        a = correct(p, w)
        return 1.0 - np.sum(a * a, axis=1)

    def inside_jac(p, w):
        return -2 * jacobian_along(p, w, correct(p, w))

    from scipy.optimize import minimize   # here: scipy costs 0.4 s to import
    p = p0
    for _ in range(rounds):
        w = v[near]
        res = minimize(lambda x: -np.sum(np.log(x[:3])), p,
                       jac=lambda x: np.r_[-1.0 / x[:3], np.zeros(6)],
                       constraints=[{"type": "ineq", "fun": inside, "jac": inside_jac, "args": (w,)}],
                       bounds=[(1e-6, None)] * 3 + [(None, None)] * 6,
                       method="SLSQP", options={"ftol": 1e-15, "maxiter": 1000})
        p = res.x
        outside = inside(p, v) < -1e-9
        if not outside.any():
            return p
        near |= outside
    raise FitError("minvol: the enclosing ellipsoid did not settle")
