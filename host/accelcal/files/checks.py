"""What a sensor could have read: the value checks every reader applies where data enters."""
from __future__ import annotations

import numpy as np

from accelcal.errors import InputError

MAX_ABS_G = 256.0          # no wearable accelerometer reads more: a larger value is not a reading
TEMP_RANGE_C = (-100.0, 200.0)


def check_values(path: str, t, xyz, temp, first: int, last_t: float | None = None,
                 line_offset: int = 2) -> None:
    """Readings a sensor could have given: |x|, |y|, |z| <= MAX_ABS_G, temperatures within
    TEMP_RANGE_C, time never going back (also across chunks: last_t); InputError naming the
    line (first data line = line_offset) otherwise."""
    big = np.abs(xyz) > MAX_ABS_G
    if big.any():
        row = int(np.argmax(big.any(axis=1)))
        raise InputError(f"{path}:{first + row + line_offset}: {xyz[row][big[row]][0]:g} g is not "
                         f"an acceleration a wearable reads (|value| <= {MAX_ABS_G:g} g)")
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
