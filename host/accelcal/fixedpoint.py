"""Floats in g <-> the device's fixed-point integers.  The formats are defined once, in
device/acal/fixed.py: samples Q10 g (SAMPLE_ONE_G), rest points Q16 g (POINT_ONE_G), parameters Q24
(PARAM_ONE).  And the device's conditions (acal.bins.COND: degC, 64 s units, mV) <-> physical
units, both ways in one place."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acal import effects as deff
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


def device_conditions(temp, t, t0: float, n: int, supply=None) -> np.ndarray:
    """(n, 3) ints: temperature (degC, rounded), time (64 s units from t0) and the board's supply
    (mV, rounded: a recording's SUPPLY_COLUMN), as the device reads them; zeros where a column
    is missing."""
    out = np.zeros((n, 3), dtype=np.int64)
    if temp is not None:
        out[:, 0] = np.rint(temp)
    if t is not None:
        out[:, 1] = np.floor((np.asarray(t) - t0) / deff.DT_UNIT_S)
    if supply is not None:
        out[:, 2] = np.rint(supply)
    return out


@dataclass(frozen=True)
class Conditions:
    """The device's conditions in physical units: temperature (degC), time (s) and the board's
    supply (mV), float64 arrays (0-d for one point's)."""
    temp: np.ndarray
    t: np.ndarray
    supply: np.ndarray


def physical(cond, t0: float) -> Conditions:
    """The device's integer conditions (..., 3: degC, 64 s units from t0, mV) in physical units,
    to the device's resolution (device_conditions' inverse)."""
    c = np.asarray(cond, dtype=np.float64)
    return Conditions(c[..., 0], t0 + c[..., 1] * float(deff.DT_UNIT_S), c[..., 2])


def hours(time_units: int) -> float:
    """A span of the device's time (64 s units) in hours."""
    return time_units * deff.DT_UNIT_S / 3600
