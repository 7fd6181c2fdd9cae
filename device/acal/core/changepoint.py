# Where a step (effects.STEP: the offsets jump once, a shock) happened: the change-point search
# of docs/model-discovery.md "More effects", in integers, on the points a fit holds.
#
# The model without the step is fitted first (pipeline.py).  A step d in the offsets from ts on
# moves each later point's residual r = |a|^2 - 1 by about 2 n . d (n: the point's direction),
# so a split k of the time-sorted points is scored by how much an offset step after it would
# explain: the least-squares gain  g_k = b_k^T S_k^-1 b_k  with S_k = sum n n^T and b_k = sum n r
# over the points after the split (the host's composed_lsq.change_point, the same rule in float).
# All splits are scored in one backward pass of running sums; ts is the first time after the
# best split.  At least MIN_SIDE_SHIFT's share of the points (1/8) stays on either side, and a
# split falls between distinct times.
#
# Formats.  n: the point's reading with the other effects removed, Q24 g >> 17 (Q7, |n| <= 2**8
# at 2.048 g); r: Q22 g^2 >> 8, clamped to +-2**13.  Sums over <= 128 points: |S| < 2**23,
# |b| < 2**28.  A split's score: S and b shifted to 9 bits (S', b'), the adjugate A of S'
# (< 2**19), det = S' . A (< 3 * 2**28, positive for a split that pins all three directions:
# one below 2**-8 of the product of the diagonal is skipped as undetermined), A b' (< 2**29.6),
# num = b' . (A b' >> 11) (< 2**29.2); then g = num / det 2**(11 + 2 tb - ts) as a mantissa of 13
# bits and an exponent, compared as such.  Every intermediate stays below 2**30: the search
# allocates nothing on a 32-bit port.
#
# Memory (an RP2040's heap holds the whole app): nothing per point of its own.  The points'
# order in time lives in the finished fit's sort buffer (GaussNewton.srt, scratch once the fit
# has ended), their times are read from the fit's aux, and each point's residual and direction
# are computed from the fit (GaussNewton.point) when the backward pass reaches it.
#
# Sliced like the fit: begin() then step() until it returns True: READ_SLICE points read a
# step, SORT_MOVES units of the sort (a point's insertion begun or a place it moves past; an
# insertion resumes where it stood), SCAN_POINTS points of the backward pass (each one's
# residual and, at a split, its score).  Emulated RP2040, 72 points: 8 points sorted a step took
# up to 6.7 ms (113 moves), 8 scanned 5.7-6.3 ms; a step is now at most ~1 ms
# (docs/model-discovery.md "Discovery on the board").  The same operations in the same
# order as whole passes: the result is the same to the bit.
from acal.core.bins import COND
from acal.core.status import Sliced

MIN_SIDE_SHIFT = 3
READ_SLICE = 8
SORT_MOVES = 16
SCAN_POINTS = 1
R_SHIFT = 8
R_MAX = 1 << 13
N_SHIFT = 17
SCALE_BITS = 9
GUARD_SHIFT = 8
NONE = -1 << 29      # a split not scored

_READ = 0    # the kept points (the phases: their slices' places, acal/core/status.py)
_SORT = 1    # their order in time
_SCAN = 2    # the backward pass
_DONE = 3


class ChangePoint(Sliced):
    """After the search: found (True when a split was scored), ts (the time of the first point
    after the best split, as the points' dt), at (the number of points before it)."""

    def __init__(self):
        self.s = [0] * 6          # S: xx yy zz xy xz yz
        self.b = [0] * 3
        self.w = [0, 0, 0]
        self.order = None         # the fit's sort buffer, while a search runs
        self.m = 0
        self.pos = 0
        self.j = -1               # where a paused insertion stands (-1: none under way)
        self.v = 0                # the point it inserts, and its time
        self.tv = 0
        self.sliced()
        self.fit = None
        self.found = False
        self.ts = 0
        self.at = 0
        self.best_m = 0
        self.best_e = NONE

    def begin(self, fit):
        """Search on the points a finished fit (gaussnewton.GaussNewton, the model without the
        step) kept, at its parameters."""
        self.fit = fit
        self.order = fit.srt
        self.m = 0
        self.pos = 0
        self.j = -1
        self.found = False
        self.best_m = 0
        self.best_e = NONE
        self.phase = _READ

    def run(self, fit):
        self.begin(fit)
        self.finish()
        return self.found

    def time_before(self):
        """After a search that found a split: the time (the points' dt) of the last point
        before it, the lower end of the gap in which the fit points leave the step's time free
        (any time after it, up to ts, fits them alike).  Read before the fit's sort buffer is
        used again."""
        return self._time(self.at - 1)

    def _time(self, k):
        return self.fit.aux[COND * self.order[k] + 1]

    def _read(self):
        fit = self.fit
        end = self.pos + READ_SLICE
        if end > fit.n_given:
            end = fit.n_given
        for i in range(self.pos, end):
            if fit.keep[i]:
                self.order[self.m] = i
                self.m += 1
        self.pos = end
        if end == fit.n_given:
            self.pos = 1
            self.phase = _SORT

    def _sort(self):
        # insertion sort of order by time (stable: equal times keep order), SORT_MOVES units a
        # step: an insertion paused mid-way holds its point in v (order[j + 1] is its hole)
        order = self.order
        aux = self.fit.aux
        i = self.pos
        j = self.j
        v = self.v
        tv = self.tv
        budget = SORT_MOVES
        while i < self.m:
            if j < 0:
                if budget == 0:
                    break
                budget -= 1
                v = order[i]
                tv = aux[COND * v + 1]
                j = i - 1
            while j >= 0 and aux[COND * order[j] + 1] > tv:
                if budget == 0:
                    self.pos = i
                    self.j = j
                    self.v = v
                    self.tv = tv
                    return
                budget -= 1
                order[j + 1] = order[j]
                j -= 1
            order[j + 1] = v
            j = -1
            i += 1
        self.pos = i
        self.j = -1
        if i >= self.m:
            for c in range(6):
                self.s[c] = 0
            for c in range(3):
                self.b[c] = 0
            self.pos = self.m - 1
            self.phase = _SCAN

    def _scan(self):
        # splits k = pos, pos - 1, ...: the points k.. m-1 after the split
        lo = self.m >> MIN_SIDE_SHIFT
        if lo < 1:
            lo = 1
        hi = self.m - lo
        stop = self.pos - SCAN_POINTS
        if stop < lo - 1:
            stop = lo - 1
        k = self.pos
        while k > stop:
            self._add(self.order[k])
            if k < hi and self._time(k) > self._time(k - 1):
                self._score(k)
            k -= 1
        self.pos = k
        if k < lo:
            self.phase = _DONE

    def _add(self, i):
        # point i of the fit: its residual and direction, into the running sums.  w is the
        # direction, then the sums, then the residual's; and a = a + t, not a += t (two stack
        # slots more): a frame of over 11 words comes from the heap on every call, a point
        # (docs/method-and-formats.md "Frames")
        w = self.w
        r = self.fit.point(i, w) >> R_SHIFT
        if r > R_MAX:
            r = R_MAX
        elif r < -R_MAX:
            r = -R_MAX
        x = w[0] >> N_SHIFT
        y = w[1] >> N_SHIFT
        z = w[2] >> N_SHIFT
        w = self.s
        w[0] = w[0] + x * x
        w[1] = w[1] + y * y
        w[2] = w[2] + z * z
        w[3] = w[3] + x * y
        w[4] = w[4] + x * z
        w[5] = w[5] + y * z
        w = self.b
        w[0] = w[0] + x * r
        w[1] = w[1] + y * r
        w[2] = w[2] + z * r

    def _score(self, k):
        s = self.s
        b = self.b
        ss = _shift_to(max(s[0], s[1], s[2]), SCALE_BITS)
        bs = _shift_to(max(abs(b[0]), abs(b[1]), abs(b[2])), SCALE_BITS)
        xx = s[0] >> ss
        yy = s[1] >> ss
        zz = s[2] >> ss
        xy = s[3] >> ss
        xz = s[4] >> ss
        yz = s[5] >> ss
        bx = b[0] >> bs
        by = b[1] >> bs
        bz = b[2] >> bs
        a00 = yy * zz - yz * yz
        a11 = xx * zz - xz * xz
        a22 = xx * yy - xy * xy
        a01 = xz * yz - xy * zz
        a02 = xy * yz - xz * yy
        a12 = xy * xz - xx * yz
        det = xx * a00 + xy * a01 + xz * a02
        if det <= 0 or det < ((xx * yy) * zz) >> GUARD_SHIFT:
            return
        yx = a00 * bx + a01 * by + a02 * bz
        yy_ = a01 * bx + a11 * by + a12 * bz
        yz_ = a02 * bx + a12 * by + a22 * bz
        num = bx * (yx >> 11) + by * (yy_ >> 11) + bz * (yz_ >> 11)
        if num <= 0:
            return
        # num / det as a 13-bit mantissa and an exponent
        e = 11 + 2 * bs - ss
        while num < (1 << 28):
            num <<= 1
            e -= 1
        while det >= (1 << 15):   # num / det = num / (2 det'): the exponent falls
            det >>= 1
            e -= 1
        while det < (1 << 14):
            det <<= 1
            e += 1
        m = num // det           # [2**13, 2**15)
        while m >= (1 << 14):
            m >>= 1
            e += 1
        if e > self.best_e or (e == self.best_e and m > self.best_m):
            self.best_e = e
            self.best_m = m
            self.found = True
            self.ts = self._time(k)
            self.at = k

    # the phases' slices, in phase order (acal/core/status.py): the class's one tuple of plain
    # functions, so an instance holds no bound method for them (only a reference to this)
    SLICES = (_read, _sort, _scan)


def _shift_to(v, bits):
    # the smallest s >= 0 with v >> s < 2**bits (v >= 0)
    s = 0
    while (v >> s) >= (1 << bits):
        s += 1
    return s
