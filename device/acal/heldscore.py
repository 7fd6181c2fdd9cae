# A model's error on the board's held-out points (issue 29; docs/model-discovery.md
# "Held-out points on the board"): what discovery.py's rule compares, in integers.  Each held-out point's
# error is |r|, r = |a|^2 - 1 g^2 of the point with the model's effects removed (model.residual),
# taken in Q16 g^2 (r >> 6) and capped at ERR_CAP so 72 of them sum below 2**30; the held-out
# error is their sum, a block's error the sum over its points.  All storage preallocated.
from acal import model
from acal.bins import COND, int32s
from acal.heldout import CAPACITY
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

ERR_SHIFT = const(6)       # Q22 g^2 -> Q16 g^2
ERR_CAP = const(4194304)   # 64 g^2 in Q16: 72 x 2**22 < 2**30


class HeldScore:
    """Scores models on a heldout.HeldOut: err (per point, Q16 g^2) of the last score, base (of
    the model a candidate must beat)."""

    def __init__(self, capacity=CAPACITY):
        self.w = int32s(3 * capacity)
        self.aux = int32s(COND * capacity)
        self.err = int32s(capacity)
        self.base = int32s(capacity)

    def score(self, p, kinds, h, ref_temp=0, ref_time=0, ref_supply=0, ts=0):
        """The held-out error (Q16 g^2, summed) of parameters p (int32 array, Q24) with effects
        `kinds` on the points of h; -1 when a point lies past the fit's domain."""
        n = h.count
        if not model.load_points(h.xyz, n, self.w):
            return -1
        aux = self.aux
        cond = h.cond
        for i in range(n):
            j = COND * i
            aux[j] = cond[j] - ref_temp
            aux[j + 1] = cond[j + 1] - ref_time
            aux[j + 2] = cond[j + 2] - ref_supply
        w = self.w
        model.points_without_effects(p, w, aux, n, kinds, w, ts)
        total = 0
        for i in range(n):
            r = model.residual(p, w[3 * i], w[3 * i + 1], w[3 * i + 2]) >> ERR_SHIFT
            if r < 0:
                r = -r
            if r > ERR_CAP:
                r = ERR_CAP
            self.err[i] = r
            total += r
        return total

    def keep_as_base(self, n):
        """The last score's errors become the ones candidates are compared with."""
        for i in range(n):
            self.base[i] = self.err[i]

    def better_blocks(self, h):
        """How many held-out blocks have a lower error in the last score than in base (each
        block summed at the first slot holding it: no allocation)."""
        better = 0
        blk = h.block
        for i in range(h.count):
            b = blk[i]
            first = True
            for j in range(i):
                if blk[j] == b:
                    first = False
                    break
            if first:
                before = 0
                after = 0
                for j in range(i, h.count):
                    if blk[j] == b:
                        before += self.base[j]
                        after += self.err[j]
                if after < before:
                    better += 1
        return better
