# An adopted step's time placed among the held-out points of its gap, scored leave-one-out
# (issue 29; docs/model-discovery.md "Against the true sensor model").  A shock that falls in a
# held-out block lies between two fit points, and the fit cannot tell where: only the held-out
# points in between can place it.  acal/discover/search.py owns one StepPlace and drives it a slice
# per step: begin(), then step() until it returns True.  Nothing is allocated per step.  The
# host's diagnose.place_step is the same rule in floats (its error | |a| - 1 |, its time halfway
# between the split's neighbours): tests/pipeline/test_step_placement.py ties the two.
# Formats: errors score.py's (Q16 g^2, weighted); times the pipeline's (64 s units, relative
# to its ref_time).  Ranges: a gap point's error <= WEIGHT_CAP x ERR_CAP = 2**22, GAP_MAX of
# them < 2**27, and the step's error (<= discover.ERR_MAX < 2**23) less and plus such sums
# stays within +-2**28 (search.py saturates the placed errors as its others).
from acal.core.bins import COND, int32s
from acal.core.status import Sliced
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

# At most GAP_MAX gap points are taken, the latest before the fitted time (a gap spans a
# held-out block or two: 8 points each on a full set).  The dropped ones stay unstepped (their
# errors in `outside`); the latest dropped time is kept so that no split falls between a dropped
# point and a kept one of the same time (the calibration would step the dropped one).
GAP_MAX = const(32)

_GATHER = 0     # the gap's held-out points gathered and scored either side of the step
_PLACE = 1      # the step's time placed among them, and each scored leave-one-out
_DONE = 2


class StepPlace(Sliced):
    """After begin() and step() until True: step_time (the placed time; the fitted time when
    no gap point moved it), n (the gap's points), placed_loo (the held-out error with each gap
    point scored at the time the others place: the points that place a time must not judge
    it) and placed_insample (every gap point at step_time); -1: not placed."""

    def __init__(self):
        # the gap's held-out points: times (sorted), errors with the step before and after them
        self.time = int32s(GAP_MAX)
        self.stepped = int32s(GAP_MAX)
        self.unstepped = int32s(GAP_MAX)
        self.n = 0
        self.lo = 0            # the gap's lower end (the last fit point's time)
        self.hi = 0            # its upper end (the fitted step time)
        self.dropped = 0       # the latest dropped gap point's time (lo: none dropped)
        self.err = 0           # the step's held-out error, every point at the fitted time
        self.score = None
        self.held = None
        self.ref_time = 0
        self.sliced()   # the phases' slices (acal/core/status.py)
        self.pos = 0
        self.scan = 0          # held-out slots scanned a gathering step
        self.loo = 0           # the gap's leave-one-out errors summed so far
        self.stepped_sum = 0
        self.outside = 0       # the step's error off the gap
        self.best_cost = 0     # the lowest split's error (_best)
        self.step_time = 0
        self.placed_loo = -1
        self.placed_insample = -1

    def clear(self):
        """Nothing placed (a model without an adopted step)."""
        self.n = 0
        self.placed_loo = -1
        self.placed_insample = -1
        self.phase = _DONE

    def begin(self, score, held, ref_time, lo, hi, err, scan):
        """Start placing: score (score.HeldScore) begun on the step model at the fitted
        time hi, lo the last fit point's time before it, err the step's held-out error, scan
        the held-out slots a gathering step may scan."""
        self.clear()
        self.scan = scan
        self.score = score
        self.held = held
        self.ref_time = ref_time
        self.lo = lo
        self.dropped = lo
        self.hi = hi
        self.err = err
        self.step_time = hi
        self.pos = 0
        self.phase = _GATHER

    def _gather(self):
        # the held-out points in the gap (lo < time < hi), kept sorted by time, each scored
        # with the step before and after it: at most `scan` slots and one point scored a step
        h = self.held
        s = self.score
        cond = h.cond
        ref = self.ref_time
        lo = self.lo
        hi = self.hi
        end = self.pos + self.scan
        if end > h.count:
            end = h.count
        j = self.pos
        while j < end:
            t = cond[COND * j + 1] - ref
            j += 1
            if lo < t < hi:
                s.ts = t
                stepped = s.point(j - 1)
                s.ts = t + 1
                unstepped = s.point(j - 1)
                if stepped < 0 or unstepped < 0:   # past the domain: not placed
                    self.step_time = hi
                    self.phase = _DONE
                    return
                self._insert(t, stepped, unstepped)
                break
        self.pos = j
        if j < h.count:
            return
        self.pos = -1
        self.phase = _PLACE if self.n > 0 else _DONE

    def _insert(self, t, stepped, unstepped):
        # a gap point by time (of equal times, after); past GAP_MAX the earliest drops
        tm = self.time
        st = self.stepped
        un = self.unstepped
        n = self.n
        k = n
        while k > 0 and tm[k - 1] > t:
            k -= 1
        if n == GAP_MAX:
            if k == 0:
                if t > self.dropped:
                    self.dropped = t
                return
            if tm[0] > self.dropped:
                self.dropped = tm[0]
            for m in range(1, k):
                tm[m - 1] = tm[m]
                st[m - 1] = st[m]
                un[m - 1] = un[m]
            k -= 1
        else:
            for m in range(n, k, -1):
                tm[m] = tm[m - 1]
                st[m] = st[m - 1]
                un[m] = un[m - 1]
            self.n = n + 1
        tm[k] = t
        st[k] = stepped
        un[k] = unstepped

    def _best(self, left):
        # the split of the gap's points (but `left`, -1: none) that leaves them the lowest
        # error, between distinct times (of equal errors, the later): the number of points
        # before it; its error in best_cost.  From every point after the split (stepped_sum)
        # each split moves one point before it.  Before them all only when no dropped point
        # shares the first one's time (the dropped points stay before every split).
        n = self.n
        tm = self.time
        st = self.stepped
        un = self.unstepped
        cost = self.stepped_sum
        if left >= 0:
            cost -= st[left]
        best = cost
        at = 0
        open_ = tm[0] > self.dropped   # a split before them all is between distinct times
        for k in range(1, n + 1):
            if k - 1 != left:
                cost += un[k - 1] - st[k - 1]
            if (k == n or tm[k - 1] < tm[k]) and (cost <= best or not open_):
                best = cost
                at = k
                open_ = True
        self.best_cost = best
        return at

    def _place(self):
        # first the placed time (in-sample), then gap point pos scored at the split the others
        # place, one point a step
        k = self.pos
        n = self.n
        if k < 0:
            st = self.stepped
            un = self.unstepped
            ss = 0
            us = 0
            for m in range(n):
                ss += st[m]
                us += un[m]
            self.stepped_sum = ss
            self.outside = self.err - us   # the step's error off the gap
            at = self._best(-1)
            self.step_time = self.hi if at == n else self.time[at]
            self.placed_insample = self.outside + self.best_cost
            self.loo = 0
            self.pos = 0
            return
        at = self._best(k)
        self.loo += self.stepped[k] if k >= at else self.unstepped[k]
        self.pos = k + 1
        if self.pos < n:
            return
        self.placed_loo = self.outside + self.loo
        self.phase = _DONE

    # the phases' slices, in phase order (acal/core/status.py): the class's one tuple of plain
    # functions, so an instance holds no bound method for them (only a reference to this)
    SLICES = (_gather, _place)

