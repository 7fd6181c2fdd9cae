"""The device's algorithm (forward-difference gradient descent, same h, rates, scaling and
iterations) in float64: not a method users pick, the yardstick the integer optimiser is tested
against."""
from __future__ import annotations

import numpy as np

from acal.core import fixed
from accelcal.methods.base import P0, check_points, correct


def float_device(v: np.ndarray, iterations: int = 50,
                 alphas=(0.3, 0.8, 0.2), scaling: str = "mean") -> tuple[np.ndarray, bool]:
    """scaling="mean" divides the gradient of the summed objective by N (what the device does);
    scaling="sum" uses the plain sum.  Returns (params, diverged)."""
    v = check_points(v, 9, "float_device")
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
