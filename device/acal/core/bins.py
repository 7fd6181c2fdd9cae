# Calibration-point selection (Farago 2024, section II-B-1, eq. 10 and figure 6).
#
# Each axis is split into [-1.25, -0.75], [-0.25, 0.25], [0.75, 1.25] g: nine subsets C_ij (i = x,
# y, z; j = n, 0, p), index 3*i + j, each holding min_count..max_count points (Q16 g ints,
# preallocated).  A rest mean is kept only if it differs enough from every held point (max-norm
# distance >= `differ`) and is gravity (no component beyond 1.25 g, magnitude in [0.5, 1.5] g).
# A point in several subsets (e.g. (1, 0, 0): C_xp, C_y0, C_z0) goes to the one holding fewest.
# Two policies once a subset is full: FIRST, the paper as printed (a full subset takes nothing
# more); CENTRE, a new point replaces the held point farthest from the subset's ideal members
# (the axis for n/p, the ring's diagonals for 0; badness) when it is nearer: the selection keeps
# improving while rest data flows (docs/method-and-formats.md).
# Composed models (docs/model-discovery.md "Bins for composed models"): an effect's parameters are
# only seen in points that differ in the condition it reads (temperature, time, the supply...).
# With a column's threshold set (set_differ: `differs`, fixed.C_TEMP ...'s order), each slot also
# holds its point's conditions (COND columns), and: a point near a held one in orientation still
# differs from it when a tracked condition differs by its threshold or more; a full subset's first
# half of slots keep well-placed points (CENTRE), the second half spread: a new point replaces the
# spread slot whose replacement most widens the subset's spread (each column's range per its
# threshold, _extremes) by a quarter threshold or more, of equals the newest (keeping a step's or a
# drift's leverage), then the worst placed; else, by CENTRE, a placement slot; no replacement
# narrows the spread; ready() also needs the held points to span each threshold.
from array import array

from acal.core import hemisphere
from acal.core.emit import copy_ints
# COND columns of conditions a point and their least spreads DIFFERS (fixed.py "conditions")
from acal.core.fixed import POINT_ONE_G, C_TIME, COND, DIFFERS


def int32s(n):
    """n zeroed int32 slots: an array takes 4 bytes a slot where a list takes 8 on a 64-bit
    port, in one block (points in Q16 g and conditions - Q2 degC, 64 s units, mV - all fit)."""
    return array("i", bytearray(4 * n))


def conditions(n_points):
    """Zeroed room for n_points' conditions (COND each, fixed.C_TEMP ...).  conditions(1): the
    board's conditions now, one array (Processor.now) that the pipeline and calibration share."""
    return int32s(COND * n_points)

FIRST = 0
CENTRE = 1
# Coverage (the default profile, docs/method-and-formats.md "Profiles"): the n and p subsets take
# points from COVER_LEVEL (not 0.75 g) out, so that a posture a wrist rarely holds still (the arm
# hanging: it sways) is still represented by tilted points, which the CENTRE rule replaces by
# better-placed ones when they come; and the bins are also ready, without nine full subsets, when
# the held points reach past +-COVER_LEVEL on both sides of every axis, at least COVER_SIDE points
# each side, and number at least COVER_POINTS (GGIR's rule is the same with +-0.3 g and one point).
# A real wrist may never lie face down (no point in C_zn): offsets and scales are still pinned by
# points on both sides, misalignment by the tilted ones; the fit's own guard (acal/core/solve.py)
# refuses a set that does not pin every parameter.
COVER_LEVEL = (3 * 65536) // 10  # 0.3 g, Q16
COVER_SIDE = 2
COVER_POINTS = 27

N_SUBSETS = 9
SUBSET_NAMES = ("xn", "x0", "xp", "yn", "y0", "yp", "zn", "z0", "zp")
_LO_OUT = (3 * POINT_ONE_G) // 4  # 0.75 g
_HI_OUT = (5 * POINT_ONE_G) // 4  # 1.25 g
_HI_MID = POINT_ONE_G // 4        # 0.25 g
DEFAULT_DIFFER = POINT_ONE_G // 10  # 0.1 g
# A rest mean is gravity seen through the sensor errors: |v| within [0.5, 1.5] g, else it is
# not kept (it would be false rest, and it bounds the optimiser's ranges).  Compared in Q24 g^2
# after a 4-bit shift, so the squares stay below 2**30 for points up to +-2 g.
_MAG2_MIN = (POINT_ONE_G >> 5) * (POINT_ONE_G >> 5)      # (0.5 g)^2 in Q24
_MAG2_MAX = 9 * (POINT_ONE_G >> 5) * (POINT_ONE_G >> 5)  # (1.5 g)^2


def gravity(x, y, z):
    """True when a rest mean (Q16 g) may be gravity: every component within 1.25 g and |v|
    within [0.5, 1.5] g (the points the bins and the held-out set keep)."""
    if not (-_HI_OUT <= x <= _HI_OUT and -_HI_OUT <= y <= _HI_OUT and -_HI_OUT <= z <= _HI_OUT):
        return False
    mag2 = (x >> 4) * (x >> 4) + (y >> 4) * (y >> 4) + (z >> 4) * (z >> 4)
    return _MAG2_MIN <= mag2 <= _MAG2_MAX


def subset_of(c, axis, lo_out=_LO_OUT):
    """Subset index for a point whose component on `axis` is c (Q16 g), or -1.  lo_out: the
    inner edge of the n and p subsets (the paper's 0.75 g; COVER_LEVEL with coverage)."""
    if -_HI_MID <= c <= _HI_MID:
        return 3 * axis + 1
    if lo_out <= c <= _HI_OUT:
        return 3 * axis + 2
    if -_HI_OUT <= c <= -lo_out:
        return 3 * axis
    return -1


def _abs(v):
    return v if v >= 0 else -v


def _gcd(x, y):
    while y:
        x, y = y, x % y
    return x


def badness(x, y, z, s):
    """How far a point lies from the ideal members of subset s (Q16 g, smaller is better).

    n/p subsets: the axis itself, | |c_i| - 1 g |.  0 subsets: the diagonals of the ring
    (0, +-0.71, +-0.71) for C_x0, | |c_i| | + | |c_j| - |c_k| |, where the two other axes both
    matter and misalignment is observable (at (0, 1, 0) it is not)."""
    axis = s // 3
    c = x if axis == 0 else (y if axis == 1 else z)
    if s - 3 * axis != 1:
        return _abs(_abs(c) - POINT_ONE_G)
    a = y if axis == 0 else x
    b = y if axis == 2 else z
    return _abs(c) + _abs(_abs(a) - _abs(b))


class Bins:
    """The nine subsets of calibration points.  min_count / max_count: points per subset (paper:
    2 and 2 -> 18 points); differ: minimum max-norm distance to every held point, Q16 g (default
    0.1 g); policy: FIRST or CENTRE; differs: None, or a threshold per condition column
    (DIFFERS' order; 0: untracked), the spreads a composed model needs (see above); room: slots a
    subset has, when more than max_count (a discovering board's: acal/discover/plug.py)."""

    def __init__(self, min_count=2, max_count=2, differ=DEFAULT_DIFFER, policy=CENTRE,
                 differs=None, coverage=False, room=0):
        if not 1 <= min_count <= max_count:
            raise ValueError("need 1 <= min_count <= max_count")
        self.coverage = coverage
        self.lo_out = COVER_LEVEL if coverage else _LO_OUT
        self.min_count = min_count
        self.max_count = max_count
        self.differ = differ
        self.policy = policy
        self.differs = [0] * COND   # the conditions' thresholds (set_differ), COND's order
        self._w = [0] * COND        # the spread's weights (set_differ)
        self._ex = [0] * (6 * COND)  # a subset's extremes, 6 a column (_extremes)
        self.c = conditions(1)      # an offered point's conditions (offer)
        self.set_differ(self.differs if differs is None else differs)
        self.need_span = True   # False: ready() does not wait for the spreads (acal/discover/search.py)
        self.counts = [0] * N_SUBSETS
        n = N_SUBSETS * (room if room > max_count else max_count)
        # Subset s, slot k, component c at xyz[3 * (s * max_count + k) + c].
        self.xyz = int32s(3 * n)
        # The conditions of slot k of subset s at cond[COND * (s * max_count + k) + column]
        self.cond = conditions(n)
        self.offered = 0
        self.kept = 0
        self.replaced = 0
        self.changes = 0      # held points changed (ready()'s cache key)
        self.ready_at = -1
        self.ready_now = False

    def clear(self):
        self.changes += 1
        for s in range(N_SUBSETS):
            self.counts[s] = 0
        self.offered = 0
        self.kept = 0
        self.replaced = 0

    def total(self):
        t = 0
        for s in range(N_SUBSETS):
            t += self.counts[s]
        return t

    def ready(self):
        """True when every subset holds at least min_count points, or with `coverage` when the
        held points cover every axis (covered()), and with `coverage` never on points all on
        one side of a plane through 0 g (hemisphere.py); and, for a composed model, when the held
        points span each condition's threshold (differs).  The answer is kept until the
        held points change (the app asks once a block: 222 us of bytecode on an RP2040)."""
        if self.ready_at != self.changes:
            self.ready_now = self._ready()
            self.ready_at = self.changes
        return self.ready_now

    def _ready(self):
        full = True
        for s in range(N_SUBSETS):
            if self.counts[s] < self.min_count:
                full = False
        if self.coverage:   # the wear profile: never on one hemisphere's points
            if not (full or self._axes_covered()) or hemisphere.held(self.xyz, self.counts,
                                                                     self.max_count):
                return False
        elif not full:
            return False
        if not self.need_span:
            return True
        for c in range(COND):
            if self.span(c) < self.differs[c]:
                return False
        return True

    def covered(self):
        """True when at least COVER_POINTS points are held, on every axis at least COVER_SIDE
        of them lie beyond +COVER_LEVEL and COVER_SIDE beyond -COVER_LEVEL, and they are not
        all on one side of a plane through 0 g (hemisphere.py: the float methods' rule)."""
        return self._axes_covered() and not hemisphere.held(self.xyz, self.counts,
                                                             self.max_count)

    def _axes_covered(self):
        if self.total() < COVER_POINTS:
            return False
        m = self.max_count
        for axis in range(3):
            pos = 0
            neg = 0
            for s in range(N_SUBSETS):
                for k in range(self.counts[s]):
                    c = self.xyz[3 * (s * m + k) + axis]
                    if c >= COVER_LEVEL:
                        pos += 1
                    elif c <= -COVER_LEVEL:
                        neg += 1
            if pos < COVER_SIDE or neg < COVER_SIDE:
                return False
        return True

    def remove(self, x, y, z):
        """Remove a held point equal to (x, y, z) (Q16 g), if any (an outlier to the fit): its
        slot takes new points again.  Returns True if one was."""
        m = self.max_count
        for s in range(N_SUBSETS):
            n = self.counts[s]
            for k in range(n):
                i = 3 * (s * m + k)
                if self.xyz[i] == x and self.xyz[i + 1] == y and self.xyz[i + 2] == z:
                    for j in range(k + 1, n):  # the later slots move down one
                        i = 3 * (s * m + j)
                        self._store(s * m + j - 1, self.xyz[i], self.xyz[i + 1], self.xyz[i + 2],
                                    self.cond, COND * (s * m + j))
                    self.counts[s] = n - 1
                    self.changes += 1
                    return True
        return False

    def span(self, c):
        """Range of condition c (a column: fixed.C_TEMP ...) over every held point."""
        lo = hi = 0
        first = True
        m = self.max_count
        for s in range(N_SUBSETS):
            for k in range(self.counts[s]):
                v = self.cond[COND * (s * m + k) + c]
                if first or v < lo:
                    lo = v
                if first or v > hi:
                    hi = v
                first = False
        return hi - lo

    def _extremes(self, s):
        # Per tracked column c, subset s's lowest condition, the next (of the other slots; None:
        # none), the lowest's slot, and the same for the highest, in self._ex[6 c:6 c + 6]; returns
        # the subset's spread score as it is (offer's, whose loop reads _ex: a call a slot would
        # take a heap frame a slot).  The score: each column's range per its threshold times the
        # thresholds' product over their common divisor (set_differ's weights: 225, 4, 27), < 2**30
        # at 125 degC, 2**20 time units, 65 V (tests/device/test_bins.py).
        m, cond, ex = self.max_count, self.cond, self._ex   # (three: no tuple made)
        w, n, now = self._w, self.counts[s], 0
        for c in range(COND):
            if not w[c]:
                continue
            lo1 = hi1 = lo2 = hi2 = None
            lk = hk = -1
            j = COND * s * m + c
            for k in range(n):
                v = cond[j]
                if lo1 is None or v < lo1:
                    lo2, lo1, lk = lo1, v, k
                elif lo2 is None or v < lo2:
                    lo2 = v
                if hi1 is None or v > hi1:
                    hi2, hi1, hk = hi1, v, k
                elif hi2 is None or v > hi2:
                    hi2 = v
                j += COND
            b = 6 * c
            ex[b], ex[b + 1], ex[b + 2] = lo1, lo2, lk
            ex[b + 3], ex[b + 4], ex[b + 5] = hi1, hi2, hk
            now += (hi1 - lo1) * w[c]
        return now

    def set_differ(self, differs):
        """Set the thresholds, one a column (COND of them, 0: untracked; only so): the spread
        weights follow here, not per offer."""
        prod = 1
        for c in range(COND):
            self.differs[c] = differs[c]
            prod *= differs[c] or 1
        g = 0
        for c in range(COND):
            g = _gcd(g, prod // (differs[c] or 1))
        for c in range(COND):   # untracked: held values count no more (an adoption that ends
            d = differs[c]      # the discovery stops tracking)
            self._w[c] = (prod // d) // g if d else 0
        self.tracked = any(self._w)
        self._w_gain = (prod // g) >> 2 or 1  # a quarter threshold (3 degC: 0.75)

    def _far_from_all(self, x, y, z, src, skip):
        # max-norm distance >= differ from every held point but slot `skip`, or far in a
        # tracked condition (src[0:COND] the point's)
        d = self.differ
        differs = self.differs
        xyz = self.xyz
        cond = self.cond
        m = self.max_count
        for s in range(N_SUBSETS):
            base = s * m
            for k in range(self.counts[s]):
                slot = base + k
                if slot == skip:
                    continue
                i = 3 * slot
                if -d < x - xyz[i] < d and -d < y - xyz[i + 1] < d and -d < z - xyz[i + 2] < d:
                    j = COND * slot
                    for c in range(COND):
                        dc = differs[c]
                        if dc and not -dc < src[c] - cond[j + c] < dc:
                            break   # far in a tracked condition
                    else:
                        return False
        return True

    def _store(self, slot, x, y, z, src, o):
        self.changes += 1   # every change of the held points passes here or clear()
        i = 3 * slot
        self.xyz[i] = x
        self.xyz[i + 1] = y
        self.xyz[i + 2] = z
        j = COND * slot
        cond = self.cond
        for c in range(COND):
            cond[j + c] = src[o + c]

    def offer(self, x, y, z, cond=None):
        """Offer a rest mean (Q16 g) seen at the conditions `cond` (conditions(1)'s columns:
        fixed.C_TEMP ...; each ignored unless tracked; None: none).  Returns the subset index
        it was kept in, or -1."""
        self.offered += 1
        c = self.c   # the point's conditions, the untracked zeroed (cond itself untouched)
        for i in range(COND):
            c[i] = cond[i] if cond is not None and self.differs[i] else 0
        if not gravity(x, y, z):
            return -1
        m = self.max_count
        best = -1
        for axis in range(3):
            s = subset_of(x if axis == 0 else (y if axis == 1 else z), axis, self.lo_out)
            if s >= 0 and self.counts[s] < m and (best < 0 or self.counts[s] < self.counts[best]):
                best = s
        if best >= 0:
            if not self._far_from_all(x, y, z, c, -1):
                return -1
            self._store(best * m + self.counts[best], x, y, z, c, 0)
            self.counts[best] += 1
            self.kept += 1
            return best
        if self.policy != CENTRE:
            return -1
        tracked = self.tracked
        w, ex = self._w, self._ex
        gain = self._w_gain
        for axis in range(3):
            s = subset_of(x if axis == 0 else (y if axis == 1 else z), axis, self.lo_out)
            if s < 0:
                continue
            now = self._extremes(s) if tracked else 0   # the subset's spread as it is
            widest = -1
            widest_spread = now + gain - 1
            widest_bad = -1
            widest_time = 0
            worst = -1
            worst_bad = badness(x, y, z, s)
            for k in range(self.counts[s]):
                spread = 0   # with slot k holding the point instead (_extremes)
                for j in range(COND if tracked else 0):
                    wc = w[j]
                    if wc:
                        v = c[j]
                        b = 6 * j
                        lo = ex[b + 1] if k == ex[b + 2] else ex[b]
                        hi = ex[b + 4] if k == ex[b + 5] else ex[b + 3]
                        if lo is None or v < lo:
                            lo = v
                        if hi is None or v > hi:
                            hi = v
                        spread += (hi - lo) * wc
                if spread < now:
                    continue  # would narrow the spread the effects need
                i = 3 * (s * m + k)
                b = badness(self.xyz[i], self.xyz[i + 1], self.xyz[i + 2], s)
                if tracked and k >= (m >> 1):
                    # A spread slot: the widest; of equals the newest, then the worst placed
                    t = self.cond[COND * (s * m + k) + C_TIME]
                    if spread > widest_spread or (widest >= 0 and spread == widest_spread and (
                            t > widest_time or (t == widest_time and b > widest_bad))):
                        widest_spread = spread
                        widest_bad = b
                        widest_time = t
                        widest = k
                elif b > worst_bad:  # a placement slot: CENTRE
                    worst_bad = b
                    worst = k
            k = widest if widest >= 0 else worst
            if k >= 0 and self._far_from_all(x, y, z, c, s * m + k):
                self._store(s * m + k, x, y, z, c, 0)
                self.replaced += 1
                return s
        return -1

    def point(self, s, k):
        """(x, y, z) of slot k of subset s, Q16 g."""
        i = 3 * (s * self.max_count + k)
        return self.xyz[i], self.xyz[i + 1], self.xyz[i + 2]

    def condition(self, s, k):
        """The conditions of slot k of subset s, a tuple in the columns' order (fixed.C_TEMP ...)."""
        j = COND * (s * self.max_count + k)
        return tuple(self.cond[j + c] for c in range(COND))

    def gather(self, out, cond=None):
        """Copy the held points into the flat int32 array `out` (x y z per point) and, if given,
        their conditions into `cond` (COND per point); return the count.  (A
        host may pass lists: emit.copy_ints is viper only on a board.)"""
        n = 0
        m = self.max_count
        for s in range(N_SUBSETS):   # a subset's points lie in consecutive slots
            k = self.counts[s]
            copy_ints(self.xyz, 3 * s * m, out, 3 * n, 3 * k)
            if cond is not None:
                copy_ints(self.cond, COND * s * m, cond, COND * n, COND * k)
            n += k
        return n
