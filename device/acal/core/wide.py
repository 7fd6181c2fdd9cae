# Products and quotients wider than a small int, computed in small ints.
#
# A 32-bit MicroPython port (RP2040, ESP32) keeps |int| < 2**30 unboxed; a larger intermediate is
# a heap-allocated long.  The default profile's fit (gaussnewton.py, solve.py) needs 50-bit
# products; these helpers give the exact floor of them with every intermediate below 2**30, so
# the fit allocates nothing (tests/device/test_wide.py checks them against CPython's exact ints at the
# edges of their domains; tests/device/test_heap.py runs the fit under heap_lock on the 32-bit port).
#
# Split: a = ah 2**15 + al with ah = a >> 15 and al = a & 0x7fff in [0, 2**15) (floor semantics
# for negative a, as in CPython and MicroPython), so that
#   a b = ah bh 2**30 + (ah bl + al bh) 2**15 + al bl,
# each product < 2**30 when |a|, |b| < 2**29.
#
# mul_shift and div_shift are viper on ports with emitters (acal/core/emit.py): machine-word functions
# of small ints, every intermediate below 2**30 as above (their arguments must be small ints there).
from acal.core.emit import viper


@viper
def mul_shift(a: int, b: int, s: int) -> int:
    """floor(a * b / 2**s), exactly, for |a|, |b| < 2**29 and s >= 16 (any s: from 58 on the
    result is 0 or -1), when the caller knows the result lies below 2**29 in magnitude."""
    ah = a >> 15
    al = a & 0x7FFF
    bh = b >> 15
    bl = b & 0x7FFF
    m = ah * bl + al * bh             # |m| < 2**30
    c = (al * bl) >> 15               # < 2**15
    t = s - 15
    if t >= 15:
        # floor((ah bh 2**15 + m + c) / 2**t) = floor((ah bh + floor((m + c) / 2**15)) / 2**(t-15));
        # that sum is below 2**30 in magnitude, so a shift by 31 gives what any larger one would
        # (0 or -1): the amount kept in 0..31, where every architecture shifts as Python does
        # (Xtensa and RV32 take it mod 32; s >= 62 would be s - 32 there)
        t -= 15
        if t > 31:
            t = 31
        return (ah * bh + (m >> 15) + (((m & 0x7FFF) + c) >> 15)) >> t
    # 1 <= t < 15: ah bh 2**(15-t) is the result less m 2**-t (< 2**29) and c: below 2**30
    return ((ah * bh) << (15 - t)) + (m >> t) + (((m & ((1 << t) - 1)) + c) >> t)


@viper
def div_shift(x: int, d: int, s: int) -> int:
    """floor(x * 2**s / d), exactly, for 0 < d < 2**26, |x| < 2**29 and s >= 0, when the caller
    knows the result lies below 2**29 in magnitude.  Long division, 4 bits a round: the
    remainder stays below d, so remainder << 4 stays below 2**30 (viper on ports with
    emitters, as mul_shift; its // is the floor division of Python's ints)."""
    q = x // d
    r = x - q * d                     # in [0, d)
    while s >= 4:
        r <<= 4
        t = r // d
        r -= t * d
        q = (q << 4) + t
        s -= 4
    if s:
        r <<= s
        q = (q << s) + r // d
    return q
