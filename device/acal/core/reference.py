# A composed fit's reference conditions: the conditions its effect terms are measured from, the
# middle of the fit points' ranges, so that the effect terms do not trade with the offsets.
# Conditions are flat int32 arrays, bins.COND columns per point (fixed.C_TEMP Q2 degC, C_TIME
# 64 s units, C_SUPPLY mV, ...); the references are the same columns.  Pipeline centres its fit points with
# centre() (its phase _CENTRE); the host reads references() for a fit it reports.
from acal.core import effects
from acal.core.bins import COND
from acal.core.emit import SIGN_SHIFT, viper, ptr32


def references(cond, n, kinds):
    """A composed fit's references over n points' conditions (flat, bins.COND columns a point:
    fixed.C_TEMP ...), a tuple in the columns' order: the middle of each range (floor), so that
    the conditions are centred and the effect terms do not trade with the offsets; for a model
    with a power of time above 1, the earliest time (effects.time_from_first)."""
    return tuple(reference(cond, n, kinds, c) for c in range(COND))


def reference(cond, n, kinds, c):
    """references()' condition c (a column: fixed.C_TEMP ...)."""
    return middle(cond, n, c, lowest(kinds, c), COND)


def lowest(kinds, c):
    """1 when condition c's reference is its lowest value, not its middle: time, for a model
    with a power of time above 1 (effects.time_from_first); else 0."""
    return 1 if c == 1 and effects.time_from_first(kinds) else 0


@viper
def middle(cond, n: int, c: int, lowest: int, k: int) -> int:
    # the middle (floor; lowest: the lowest) of condition c over n points' conditions (an int32
    # array, k = bins.COND per point, passed: a viper loop takes no other module's const; a host
    # may pass a list), 0 for none; viper on ports with emitters
    if n == 0:
        return 0
    p = ptr32(cond)
    w = int(SIGN_SHIFT)
    lo = int(p[c]) << w >> w
    hi = lo
    i = 1
    while i < n:
        v = int(p[k * i + c]) << w >> w
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
        i += 1
    if lowest:
        return lo
    return (lo + hi) >> 1


@viper
def centre(cond, n: int, c: int, lowest: int, k: int) -> int:
    # Condition c of n points (as middle's) made relative to their middle (references()); returns
    # it: the fit's centring (Pipeline phase _CENTRE), viper on ports with emitters
    ref = int(middle(cond, n, c, lowest, k))
    p = ptr32(cond)
    w = int(SIGN_SHIFT)
    i = 0
    while i < n:
        p[k * i + c] = (int(p[k * i + c]) << w >> w) - ref
        i += 1
    return ref
