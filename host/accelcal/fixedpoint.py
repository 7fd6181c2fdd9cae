"""Floats in g <-> the device's fixed-point integers.  The formats are defined once, in
device/acal/core/fixed.py: samples Q10 g (SAMPLE_ONE_G), rest points Q16 g (POINT_ONE_G), parameters Q24
(PARAM_ONE).  And the device's conditions (acal.core.bins.COND: Q2 degC, 64 s units, mV) <-> physical
units, both ways in one place."""
from __future__ import annotations

from dataclasses import dataclass, make_dataclass

import numpy as np

from acal.core import effects as deff
from acal.core import fixed


def dither(first: int, n: int) -> np.ndarray:
    """The Q10 rounding's dither of samples first..first + n - 1 of a stream, in 2**-14 LSB
    (acal.core.fixed.DITHER_STEP): (i * DITHER_STEP) & DITHER_MASK, int64 (n,)."""
    i = np.arange(first, first + n, dtype=np.int64)
    return (i * fixed.DITHER_STEP) & fixed.DITHER_MASK


# |g| past this is clipped before the conversion to Q24 ints (any value past +-16 g clips alike)
_G_CLIP = 2.0 * fixed.SAMPLE_MAX / fixed.SAMPLE_ONE_G


def to_samples(c, d: np.ndarray, out: np.ndarray) -> None:
    """One axis of floats in g (float32 or float64, converted in its own dtype: scaling by a
    power of two and floor are exact in either) -> Q10 samples into out: floor(g * 2**24) + the
    dither d (2**-14 LSB), >> 14, clipped to +-SAMPLE_MAX (fixed.py: the driver's form)."""
    c = np.asarray(c)
    if not np.issubdtype(c.dtype, np.floating):
        c = c.astype(np.float64)
    v = np.clip(c, -_G_CLIP, _G_CLIP)     # a copy, in the axis's dtype
    np.multiply(v, v.dtype.type(1 << (fixed.SAMPLE_Q + fixed.DITHER_BITS)), out=v)
    np.floor(v, out=v)
    w = v.astype(np.int64)
    w += d
    w >>= fixed.DITHER_BITS
    np.clip(w, -fixed.SAMPLE_MAX, fixed.SAMPLE_MAX, out=w)
    out[...] = w


def g_to_sample(g: np.ndarray, first: int = 0) -> np.ndarray:
    """Floats in g (m x 3) -> device samples (Q10 g ints, int64 m x 3), rounded as the device's
    format is (acal.core.fixed: floor with the dither of each sample's index in its stream, the
    first being first), clipped to the +-16 g range."""
    g = np.asarray(g)
    g2 = g.reshape(len(g), -1) if g.ndim else g.reshape(1, 1)   # rows are samples
    out = np.empty(g2.shape, np.int64)
    d = dither(first, len(g2))
    for j in range(g2.shape[1]):
        to_samples(g2[:, j], d, out[:, j])
    return out.reshape(g.shape)


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


@dataclass(frozen=True)
class Quantity:
    """One quantity the board reads with each point, a device condition (acal.core.bins.COND, in
    QUANTITIES' order).  The device holds it as round(x * 2**q) (the temperature: Q2 degC,
    acal.core.fixed.TEMP_Q) or, for a `step` quantity, floor((x - origin) / step) with the group's
    first time as origin; its place in QUANTITIES is the device's column (DeviceResult's
    ref and span, the bins' differs); `column` is the recording column it is read from, `ref`
    the key a fitted model stores its reference under (None: the column's, column_ref())."""
    name: str
    column: str
    differ: int          # the bins' least spread of it for an effect that follows it
    ref: str | None
    show: tuple          # a span, and the least spread, as a reason states them
    step: int = 1
    # a board column's: the device kind of an offset linear in it (acal.core.effects) and the
    # range its regressor is normalised by (Q24 per that many units)
    kind: int | None = None
    per: int = 1
    q: int = 0           # fraction bits the device keeps (round(x * 2**q))
    unit: str = ""       # a board column's physical unit (its effect's parameter: g per unit)
    # a board column's built-in effect, the offset linear in it that `kind` runs
    # (model/effects.py CATALOGUE makes it, named as the device names the kind):
    # (parameter symbol, report scale, report unit, the physics in a sentence)
    effect: tuple = ()

    def to_physical(self, v):
        """A span or value of the device's integers in physical units, 0 based (a step
        quantity's in its step: seconds for time)."""
        return v * self.step if self.step != 1 else (v / (1 << self.q) if self.q else v)


QUANTITIES = (
    Quantity("temp", "temp", fixed.DIFFERS[fixed.C_TEMP], "T0",
             ("{:g} degC of temperature", "{:g}"), q=fixed.TEMP_Q),
    Quantity("time", "t", fixed.DIFFERS[fixed.C_TIME], "t0", ("{:.1f} h", "{:g} h"),
             step=deff.DT_UNIT_S),
    # the board's supply in mV (acal.core.effects.SUPPLY_OFFSET): a recording column the board reads
    Quantity("supply", "supply_mv", fixed.DIFFERS[fixed.C_SUPPLY], None,
             ("{} mV of supply_mv", "{}"), kind=deff.SUPPLY_OFFSET,
             per=fixed.SOURCES[fixed.SOURCE_SUPPLY][2], unit="mV",
             effect=("v", 1e6, "mg/V",
                     "The zero-g level follows the supply: the readout's reference is not fully "
                     "ratiometric, so rest readings shift as the battery runs down - a trend in "
                     "the board's supply (mV), which repeats with every charge, not in time.")),
)
# the ones read from a recording's further columns (not t and temp, which every file may have)
COLUMN_QUANTITIES = tuple(q for q in QUANTITIES if q.ref is None)
Conditions = make_dataclass("Conditions", [q.name for q in QUANTITIES], frozen=True)
Conditions.__doc__ = """The device's conditions in physical units (QUANTITIES: degC, s, mV),
float64 arrays (0-d for one point's)."""


def board_columns(cols: dict) -> dict:
    """The recording columns (by name) the board also reads, by their quantity's name."""
    return {q.name: cols[q.column] for q in COLUMN_QUANTITIES if q.column in cols}


def device_conditions(temp, t, t0: float, n: int, **columns) -> np.ndarray:
    """(n, COND) ints as the device reads them (QUANTITIES): temperature (Q2 degC, rounded), time
    (64 s units from t0) and the board's columns by quantity name (board_columns: the supply,
    mV rounded); zeros where one is missing."""
    given = {"temp": temp, "time": t, **columns}
    out = np.zeros((n, len(QUANTITIES)), dtype=np.int64)
    for i, q in enumerate(QUANTITIES):
        x = given.get(q.name)
        if x is None:
            continue
        out[:, i] = (np.floor((np.asarray(x) - t0) / q.step) if q.step != 1
                     else np.rint(np.asarray(x, dtype=np.float64) * (1 << q.q)))
    return out


def physical(cond, t0: float):
    """The device's integer conditions (..., COND) in physical units, to the device's resolution
    (device_conditions' inverse): Conditions."""
    c = np.asarray(cond, dtype=np.float64)
    return Conditions(**{q.name: t0 + c[..., i] * float(q.step) if q.step != 1
                         else c[..., i] / (1 << q.q) for i, q in enumerate(QUANTITIES)})


def span_reason(q: Quantity, span: int) -> str | None:
    """Why a span of q the device's bins hold is too small for an effect that follows it, or
    None."""
    if span >= q.differ:
        return None
    show = hours if q.step != 1 else q.to_physical
    return (f"the held points span {q.show[0].format(show(span))}, the fit needs >= "
            f"{q.show[1].format(show(q.differ))}")


def seconds(time_units: int) -> int:
    """A span of the device's time (64 s units) in seconds."""
    return time_units * deff.DT_UNIT_S


def hours(time_units: int) -> float:
    """A span of the device's time (64 s units) in hours."""
    return seconds(time_units) / 3600
