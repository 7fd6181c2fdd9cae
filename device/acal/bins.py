# Calibration-point selection (Farago 2024, section II-B-1, eq. 10 and figure 6).
#
# Each axis is split into [-1.25, -0.75], [-0.25, 0.25], [0.75, 1.25] g, giving nine subsets
# C_ij (i = x, y, z; j = n, 0, p), subset index 3*i + j.  Each subset holds between min_count
# and max_count points; a rest mean is kept only if it differs enough from every point already
# held (max-norm distance >= `differ`, no square root).  Means with a component beyond 1.25 g or a
# magnitude outside [0.5, 1.5] g are not gravity and are never kept.  A point that lies in several subsets
# (e.g. (1, 0, 0) is in C_xp, C_y0 and C_z0) goes to the one of them holding fewest points.
#
# Two policies once a subset is full:
#   FIRST  - the paper as printed: a full subset takes nothing more (first come, first kept);
#   CENTRE - a new point replaces the held point of that subset farthest from the subset's ideal
#            members (the axis for n/p, the ring's diagonals for 0; see badness) when it is nearer.
#            The selection keeps improving while rest data flows; README "Point selection".
# Points are Q16 g ints; storage is preallocated.
from acal.fixed import POINT_ONE_G

FIRST = 0
CENTRE = 1

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


def subset_of(c, axis):
    """Subset index for a point whose component on `axis` is c (Q16 g), or -1."""
    if -_HI_MID <= c <= _HI_MID:
        return 3 * axis + 1
    if _LO_OUT <= c <= _HI_OUT:
        return 3 * axis + 2
    if -_HI_OUT <= c <= -_LO_OUT:
        return 3 * axis
    return -1


def _abs(v):
    return v if v >= 0 else -v


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
    """The nine subsets of calibration points.

    min_count / max_count: points per subset (paper: 2 and 2 -> 18 points);
    differ: minimum max-norm distance to every held point, Q16 g (default 0.1 g);
    policy: FIRST or CENTRE.
    """

    def __init__(self, min_count=2, max_count=2, differ=DEFAULT_DIFFER, policy=CENTRE):
        if not 1 <= min_count <= max_count:
            raise ValueError("need 1 <= min_count <= max_count")
        self.min_count = min_count
        self.max_count = max_count
        self.differ = differ
        self.policy = policy
        self.counts = [0] * N_SUBSETS
        # Subset s, slot k, component c at xyz[3 * (s * max_count + k) + c].
        self.xyz = [0] * (3 * N_SUBSETS * max_count)
        self.offered = 0
        self.kept = 0
        self.replaced = 0

    def clear(self):
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
        """True when every subset holds at least min_count points."""
        for s in range(N_SUBSETS):
            if self.counts[s] < self.min_count:
                return False
        return True

    def _far_from_all(self, x, y, z, skip):
        # Max-norm distance >= differ from every held point except slot index `skip`.
        d = self.differ
        xyz = self.xyz
        m = self.max_count
        for s in range(N_SUBSETS):
            base = s * m
            for k in range(self.counts[s]):
                slot = base + k
                if slot == skip:
                    continue
                i = 3 * slot
                if -d < x - xyz[i] < d and -d < y - xyz[i + 1] < d and -d < z - xyz[i + 2] < d:
                    return False
        return True

    def _store(self, slot, x, y, z):
        i = 3 * slot
        self.xyz[i] = x
        self.xyz[i + 1] = y
        self.xyz[i + 2] = z

    def offer(self, x, y, z):
        """Offer a rest mean (Q16 g). Returns the subset index it was kept in, or -1."""
        self.offered += 1
        if not (-_HI_OUT <= x <= _HI_OUT and -_HI_OUT <= y <= _HI_OUT and -_HI_OUT <= z <= _HI_OUT):
            return -1
        mag2 = (x >> 4) * (x >> 4) + (y >> 4) * (y >> 4) + (z >> 4) * (z >> 4)
        if mag2 < _MAG2_MIN or mag2 > _MAG2_MAX:
            return -1
        m = self.max_count
        best = -1
        for axis in range(3):
            s = subset_of(x if axis == 0 else (y if axis == 1 else z), axis)
            if s >= 0 and self.counts[s] < m and (best < 0 or self.counts[s] < self.counts[best]):
                best = s
        if best >= 0:
            if not self._far_from_all(x, y, z, -1):
                return -1
            self._store(best * m + self.counts[best], x, y, z)
            self.counts[best] += 1
            self.kept += 1
            return best
        if self.policy != CENTRE:
            return -1
        for axis in range(3):
            c = x if axis == 0 else (y if axis == 1 else z)
            s = subset_of(c, axis)
            if s < 0:
                continue
            worst = -1
            worst_bad = badness(x, y, z, s)
            for k in range(self.counts[s]):
                i = 3 * (s * m + k)
                b = badness(self.xyz[i], self.xyz[i + 1], self.xyz[i + 2], s)
                if b > worst_bad:
                    worst_bad = b
                    worst = k
            if worst >= 0 and self._far_from_all(x, y, z, s * m + worst):
                self._store(s * m + worst, x, y, z)
                self.replaced += 1
                return s
        return -1

    def point(self, s, k):
        """(x, y, z) of slot k of subset s, Q16 g."""
        i = 3 * (s * self.max_count + k)
        return self.xyz[i], self.xyz[i + 1], self.xyz[i + 2]

    def gather(self, out):
        """Copy the held points into the flat int list `out` (x y z per point); return count."""
        n = 0
        for s in range(N_SUBSETS):
            for k in range(self.counts[s]):
                i = 3 * (s * self.max_count + k)
                out[3 * n] = self.xyz[i]
                out[3 * n + 1] = self.xyz[i + 1]
                out[3 * n + 2] = self.xyz[i + 2]
                n += 1
        return n
