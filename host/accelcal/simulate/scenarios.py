"""The paper's simulation (Farago 2024, section III-A, eqs. 17-20).

Per scenario: S_i ~ U(0.9, 1.1), T_j ~ U(-0.05, 0.05), O_i ~ U(-0.1, 0.1) g (eq. 17);
p = [S_x, S_y, S_z, S_y T_xy, S_z T_xz, S_z T_yz, O_x, O_y, O_z] (eq. 18).  Ideal points a of unit
magnitude, uniform on the sphere, are turned into what the sensor measures by inverting eqs. 7-9
exactly (eq. 19 as printed has sign slips: its c_iy uses (c_ix - o_x) and its c_iz (c_ix + o_x)
where the inverse of eq. 8/9 needs (c_ix + o_x) in both):
    c_x = a_x / kxx - o_x
    c_y = (a_y - kxy (c_x + o_x)) / kyy - o_y
    c_z = (a_z - kxz (c_x + o_x) - kyz (c_y + o_y)) / kzz - o_z
and noise is added per axis (eq. 20).
"""
from __future__ import annotations

import numpy as np


def random_params(rng: np.random.Generator) -> np.ndarray:
    S = 2 * (rng.random(3) - 0.5) * 0.1 + 1
    T = 2 * (rng.random(3) - 0.5) * 0.05
    O = 2 * (rng.random(3) - 0.5) * 0.1
    return np.array([S[0], S[1], S[2], S[1] * T[0], S[2] * T[1], S[2] * T[2], O[0], O[1], O[2]])


def uncorrect(p: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The exact inverse of eqs. 7-9: the measured v for which K (v + o) = a."""
    kxx, kyy, kzz, kxy, kxz, kyz, ox, oy, oz = p
    cx = a[:, 0] / kxx - ox
    cy = (a[:, 1] - kxy * (cx + ox)) / kyy - oy
    cz = (a[:, 2] - kxz * (cx + ox) - kyz * (cy + oy)) / kzz - oz
    return np.column_stack([cx, cy, cz])


def unit_points(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.normal(size=(n, 3))
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def noise(rng: np.random.Generator, shape, noise_g: float, dist: str = "normal") -> np.ndarray:
    """Per-axis noise: 'normal' with sd noise_g (the paper as printed) or 'uniform' on
    [-noise_g, noise_g] (sd noise_g / sqrt 3), one reading of "standard deviation of +-1 mg"."""
    if dist == "normal":
        return rng.normal(scale=noise_g, size=shape)
    if dist == "uniform":
        return rng.uniform(-noise_g, noise_g, size=shape)
    raise ValueError(f"unknown noise distribution {dist!r}")


def paper_scenario(rng: np.random.Generator, n_points: int, noise_g: float,
                   dist: str = "normal") -> tuple[np.ndarray, np.ndarray]:
    """One scenario: (true parameters, n_points measured rest means in g)."""
    p = random_params(rng)
    v = uncorrect(p, unit_points(rng, n_points))
    return p, v + noise(rng, v.shape, noise_g, dist)
