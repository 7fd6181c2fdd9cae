"""What a sensor could have read: the value checks every reader applies where data enters."""
from __future__ import annotations

import numpy as np

from accelcal.errors import InputError

MAX_ABS_G = 256.0          # no wearable accelerometer reads more: a larger value is not a reading
TEMP_RANGE_C = (-100.0, 200.0)
STANDARD_GRAVITY = 9.80665  # m/s^2 per g
# The median |a| of a wearable's readings in g is gravity's, 1 g (still or moving, a wrist's
# samples centre on it); a ~9.81 "g" gravity is not possible on a +-2..16 g sensor.  Beyond
# UNIT_MEDIAN_G the readings are in another unit: m/s^2 near 9.81, else raw counts (1024 per g for
# the LIS3DH's +-2 g high-resolution output right-justified, 256 for an AX3...).
UNIT_MEDIAN_G = 2.0
UNIT_SAMPLE = 1 << 16      # the samples looked at: the first of a recording


def unit_hint(xyz) -> str | None:
    """What the readings xyz ((n, 3), or x, y, z columns) are if not g, with the fix, from their
    median magnitude; None when they look like g (or there are none)."""
    a = np.column_stack([c[:UNIT_SAMPLE] for c in xyz]) if isinstance(xyz, tuple) else \
        np.asarray(xyz)[:UNIT_SAMPLE]
    a = a.astype(np.float64)
    if not len(a):
        return None
    mag = np.sqrt(np.einsum("ij,ij->i", a, a))
    med = float(np.partition(mag, len(mag) // 2)[len(mag) // 2])   # np.median loads numpy.ma
    if med <= UNIT_MEDIAN_G:
        return None
    if 8.0 <= med <= 12.0:
        return (f"the readings' median |a| is {med:.2f}: m/s^2, not g (a {med:.1f} g gravity is "
                f"not possible on a +-2..16 g sensor); divide x, y, z by {STANDARD_GRAVITY}")
    return (f"the readings' median |a| is {med:.4g}, not ~1 g: raw counts (about {med:.0f} per "
            "g?); divide x, y, z by the sensor's counts per g (the LIS3DH at +-2 g, 1 mg/digit: "
            "1000)")


def check_units(source: str, xyz) -> None:
    """InputError (one line: the unit and the fix) for readings not in g (unit_hint)."""
    why = unit_hint(xyz)
    if why:
        raise InputError(f"{source}: {why}")


def check_values(path: str, t, xyz, temp, first: int, last_t: float | None = None,
                 line_offset: int = 2) -> None:
    """Readings a sensor could have given: |x|, |y|, |z| <= MAX_ABS_G, temperatures within
    TEMP_RANGE_C, time never going back (also across chunks: last_t); InputError naming the
    line (first data line = line_offset) otherwise."""
    big = np.abs(xyz) > MAX_ABS_G
    if big.any():
        row = int(np.argmax(big.any(axis=1)))
        hint = unit_hint(xyz)
        raise InputError(f"{path}:{first + row + line_offset}: {xyz[row][big[row]][0]:g} g is not "
                         f"an acceleration a wearable reads (|value| <= {MAX_ABS_G:g} g)"
                         + (f"; {hint}" if hint else ""))
    if temp is not None:
        lo, hi = TEMP_RANGE_C
        off = (temp < lo) | (temp > hi)
        if off.any():
            row = int(np.argmax(off))
            raise InputError(f"{path}:{first + row + line_offset}: temperature {temp[row]:g} degC "
                             f"is outside {lo:g}..{hi:g} degC")
    if len(t):
        back = np.diff(t) < 0
        if back.any():
            row = int(np.argmax(back)) + 1
            raise InputError(f"{path}:{first + row + line_offset}: time goes back ({t[row - 1]:g} "
                             f"s, then {t[row]:g} s)")
        if last_t is not None and t[0] < last_t:
            raise InputError(f"{path}:{first + line_offset}: time goes back ({last_t:g} s, then "
                             f"{t[0]:g} s)")
