# A model's error on the board's held-out points (issue 29; docs/model-discovery.md
# "Held-out points on the board"): what rule.py's rule compares, in integers.  Each held-out point's
# error is |r|, r = |a|^2 - 1 g^2 of the point with the model's effects removed (model.residual),
# taken in Q16 g^2 (r >> 6), capped at ERR_CAP and times the point's weight (the rest means it
# stands for, heldout.WEIGHT_CAP at most: `diagnose` scores a block on every rest point in it),
# so 144 (heldout.CAPACITY) sum below 2**30; the held-out error is their sum, a block's error the
# sum over its points.  All storage preallocated.  A point's effects are removed by the fit's
# viper copy of the table's forms (effects.correct_kinds, model.remove_effects' integers and
# clamps), one call a point.
from acal.core import model
from acal.core.bins import COND, int32s
from acal.core.effects import correct_kinds, MODEL_EFFECTS_MAX
from acal.core.fixed import POINT_TO_PARAM_SHIFT
from acal.discover.heldout import CAPACITY
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

ERR_SHIFT = const(6)       # Q22 g^2 -> Q16 g^2
# 4 g^2 in Q16 (a rest mean's |a|^2 - 1 lies in -0.75 .. 1.25 g^2 before a model's effects):
# CAPACITY x WEIGHT_CAP x ERR_CAP = 144 x 16 x 2**18 < 2**30
ERR_CAP = const(262144)


class HeldScore:
    """Scores models on a heldout.HeldOut: err (per point, Q16 g^2) of the last score, base (of
    the model a candidate must beat).  Sliced as the fit (acal/discover/search.py runs it between FIFO
    reads): begin(), then part() until it returns True, the error in `total`; score() at once."""

    def __init__(self, capacity=CAPACITY):
        self.w = int32s(3)              # a point's reading, its effects removed (correct_kinds)
        self.kind_ids = int32s(MODEL_EFFECTS_MAX)   # begin()'s kinds, correct_kinds' ids
        self.nk = 0
        self.err = int32s(capacity)
        self.base = int32s(capacity)
        self.first = int32s(capacity)   # 1 where a slot is its block's first (mark_slot)
        self.p = None
        self.h = None
        self.ref = [0] * COND   # the fit's references (begin(): copied), the points' columns
        self.rel = int32s(COND)   # a point's conditions minus ref (point())
        self.ts = 0
        self.pos = 0
        self.total = 0
        self.firsts = 0    # blocks mark_slot has met (their first slots), summed by callers
        # mark_slot / compare_slot: a slot's scan over the others, resumed `scan` slots on
        # (-1: not begun), with its block's sums so far
        self.scan = -1
        self.sum_base = 0
        self.sum_err = 0

    def score(self, p, kinds, h, ref=None, ts=0):
        """The held-out error (Q16 g^2, summed) of parameters p (int32 array, Q24) with effects
        `kinds` on the points of h, their conditions taken from the references `ref` (COND
        columns, as the fit's, pipeline.ref; None: zeros) and a step at ts; -1 when a point
        lies past the fit's domain."""
        self.begin(p, kinds, h, ref, ts)
        while not self.part(h.count):
            pass
        return self.total

    def begin(self, p, kinds, h, ref=None, ts=0):
        """Start scoring p with `kinds` on h (score's arguments)."""
        self.p = p
        self.nk = len(kinds)
        for k in range(self.nk):
            self.kind_ids[k] = kinds[k]
        self.h = h
        for c in range(COND):
            self.ref[c] = 0 if ref is None else ref[c]
        self.ts = ts
        self.pos = 0
        self.total = 0

    def part(self, count):
        """Score up to `count` more points; True when every point is scored (or one lay past
        the domain: total -1)."""
        end = self.pos + count
        if end > self.h.count:
            end = self.h.count
        for i in range(self.pos, end):
            r = self.point(i)
            if r < 0:
                self.total = -1
                return True
            self.err[i] = r
            self.total += r
        self.pos = end
        return end == self.h.count

    def point(self, i):
        """Point i's error (Q16 g^2, weighted) under the model begin() set (its step time
        `ts`, which a caller may change between points); -1 when it lies past the domain."""
        h = self.h
        w = self.w
        xyz = h.xyz
        for c in range(3):
            v = xyz[3 * i + c]
            if v >= model.POINT_LIMIT or v < -model.POINT_LIMIT:
                return -1
            w[c] = v << POINT_TO_PARAM_SHIFT
        p = self.p
        if self.nk:
            j = COND * i
            cond = h.cond
            r = self.ref
            d = self.rel
            for c in range(COND):
                d[c] = cond[j + c] - r[c]
            correct_kinds(self.kind_ids, 0, self.nk, p, 9, w, d, 0, self.ts, model.FIT_W_MAX)
        r = model.residual(p, w[0], w[1], w[2]) >> ERR_SHIFT
        if r < 0:
            r = -r
        if r > ERR_CAP:
            r = ERR_CAP
        return r * h.weight[i]

    def keep_as_base(self, n, lo=0):
        """The last score's errors (of slots lo..n-1) become the ones candidates are compared
        with."""
        for i in range(lo, n):
            self.base[i] = self.err[i]

    def better_blocks(self, h):
        """How many held-out blocks have a lower error in the last score than in base (each
        block summed at the first slot holding it: no allocation): mark_slot and compare_slot
        over every slot, each in one call."""
        self.scan = -1
        for i in range(h.count):
            self.mark_slot(h, i, h.count)
        better = 0
        for i in range(h.count):
            better += self.compare_slot(h, i, h.count)
        return better

    def mark_slot(self, h, i, budget):
        """Mark slot i if it is the first of its block (first[i] 1, else 0; counted in
        `firsts`), scanning at most `budget` earlier slots a call (the scan resumes where it
        stood); True once slot i is marked."""
        blk = h.block
        b = blk[i]
        j = self.scan
        if j < 0:
            j = 0
            self.first[i] = 1
        end = j + budget
        if end > i:
            end = i
        while j < end:
            if blk[j] == b:
                self.first[i] = 0
                self.scan = -1
                return True
            j += 1
        if end < i:
            self.scan = end
            return False
        self.firsts += 1
        self.scan = -1
        return True

    def compare_slot(self, h, i, budget):
        """Whether the block whose first slot (mark_slot) is i has a lower error in the last
        score than in base, summing at most `budget` slots of its block's a call (resumed): 1
        once found better, 0 once done otherwise (or i is not a block's first), -1 while not
        done."""
        if not self.first[i]:
            return 0
        blk = h.block
        b = blk[i]
        j = self.scan
        if j < 0:
            j = i
            self.sum_base = 0
            self.sum_err = 0
        end = j + budget
        if end > h.count:
            end = h.count
        while j < end:
            if blk[j] == b:
                self.sum_base += self.base[j]
                self.sum_err += self.err[j]
            j += 1
        if end < h.count:
            self.scan = end
            return -1
        self.scan = -1
        return 1 if self.sum_err < self.sum_base else 0
