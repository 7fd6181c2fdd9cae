"""Floats in g <-> the device's fixed-point integers.  The formats are defined once, in
device/acal/fixed.py: samples Q10 g (SAMPLE_ONE_G), rest points Q16 g (POINT_ONE_G), parameters Q24
(PARAM_ONE)."""
from __future__ import annotations

import numpy as np

from acal import fixed


def g_to_sample(g: np.ndarray) -> np.ndarray:
    """Floats in g -> device samples (Q10 g ints), rounded, clipped to the +-16 g range."""
    q = np.rint(np.asarray(g, dtype=np.float64) * fixed.SAMPLE_ONE_G)
    return np.clip(q, -fixed.SAMPLE_MAX, fixed.SAMPLE_MAX).astype(np.int64)


def g_to_point(g: np.ndarray) -> np.ndarray:
    """Floats in g -> device points (Q16 g ints), rounded."""
    return np.rint(np.asarray(g, dtype=np.float64) * fixed.POINT_ONE_G).astype(np.int64)


def point_to_g(q) -> np.ndarray:
    return np.asarray(q, dtype=np.float64) / fixed.POINT_ONE_G


def sample_to_g(q) -> np.ndarray:
    return np.asarray(q, dtype=np.float64) / fixed.SAMPLE_ONE_G


def params_to_float(p_int) -> np.ndarray:
    return np.asarray(p_int, dtype=np.float64) / fixed.PARAM_ONE


def params_to_int(p: np.ndarray) -> list[int]:
    return [int(v) for v in np.rint(np.asarray(p, dtype=np.float64) * fixed.PARAM_ONE)]
