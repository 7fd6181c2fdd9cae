# A composed fit's reference conditions: the temperature, time and supply its effect terms are
# measured from (dT, dt, dV), the middle of the fit points' ranges, so that the effect terms do
# not trade with the offsets.  Conditions are flat int32 arrays, bins.COND per point (Q2 degC,
# 64 s units, mV); the references are the same units.  Pipeline centres its fit points with
# centre() (its phase _CENTRE); the host reads references() for a fit it reports.
from acal.core import effects
from acal.core.emit import SIGN_SHIFT, viper, ptr32


def references(cond, n, kinds):
    """A composed fit's reference temperature, time and supply over n points' conditions (flat:
    temp, time, supply per point, bins.COND): the middle of each range (floor), so that dT, dt
    and dV are centred and the effect terms do not trade with the offsets; for a model with a
    power of time above 1, the earliest time (effects.time_from_first)."""
    return reference(cond, n, kinds, 0), reference(cond, n, kinds, 1), reference(cond, n, kinds, 2)


def reference(cond, n, kinds, c):
    """references()' condition c (0 temperature, 1 time, 2 supply)."""
    return middle(cond, n, c, lowest(kinds, c))


def lowest(kinds, c):
    """1 when condition c's reference is its lowest value, not its middle: time, for a model
    with a power of time above 1 (effects.time_from_first); else 0."""
    return 1 if c == 1 and effects.time_from_first(kinds) else 0


@viper
def middle(cond, n: int, c: int, lowest: int) -> int:
    # the middle (floor; lowest: the lowest) of condition c over n points' conditions (an int32
    # array, COND per point, written 3 below: a viper loop takes no other module's const; a host
    # may pass a list), 0 for none; viper on ports with emitters
    if n == 0:
        return 0
    p = ptr32(cond)
    w = int(SIGN_SHIFT)
    lo = int(p[c]) << w >> w
    hi = lo
    i = 1
    while i < n:
        v = int(p[3 * i + c]) << w >> w
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
        i += 1
    if lowest:
        return lo
    return (lo + hi) >> 1


@viper
def centre(cond, n: int, c: int, lowest: int) -> int:
    # Condition c of n points (as middle's) made relative to their middle (references()); returns
    # it: the fit's centring (Pipeline phase _CENTRE), viper on ports with emitters
    ref = int(middle(cond, n, c, lowest))
    p = ptr32(cond)
    w = int(SIGN_SHIFT)
    i = 0
    while i < n:
        p[3 * i + c] = (int(p[3 * i + c]) << w >> w) - ref
        i += 1
    return ref
