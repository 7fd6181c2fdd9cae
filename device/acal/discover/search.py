# The board's own model discovery (issue 29; docs/model-discovery.md "Discovery on the board"):
# after a usable calibration of the paper's model (the wear profile's fit), each candidate effect
# of the catalogue the board can run is fitted on the same gathered fit points, from the base
# fit's parameters, scored on the held-out rest points (heldout.py, score.py) and the
# choice made as `diagnose` makes it (rule.py: best, adopted).
#
# Sliced as the fit: begin() then step() until it returns True, each step one slice of a
# candidate's fit (gaussnewton.py's), its testability or begin, a step's change-point search
# (changepoint.py), the scoring of one candidate, or (the step) a slice of its time's placing
# among the held-out points of its gap (stepplace.py), before the choice.  Nothing is allocated
# per candidate or per score: one GaussNewton sized for the largest candidate (9 + 6
# parameters) is re-kinded for each (the candidates' effect tuples are made once: here, and per
# base effect for a second round), and the results go to preallocated int32 arrays.
# Formats: errors score.py's (Q16 g^2, summed), saturated at ERR_MAX so that rule.py's products
# (100 x an error, 15 x an error) stay below 2**30 (score.py's reach 144 x 2**22); params Q24.
from acal.discover import rule
from acal.core import effects
from acal.core.bins import COND, DIFFERS, int32s
from acal.core.fixed import N_PARAMS, C_TIME
from acal.core.gaussnewton import GaussNewton
from acal.discover.score import HeldScore
from acal.discover.stepplace import StepPlace
from acal.core.status import OK
from acal.core.status import Sliced
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

# The candidates, as `diagnose` tries them (host/accelcal/model/effects.py, candidate=True):
# the single effects the board runs, the step last of them (its change-point search runs
# first), then the curve with its straight part, tried together (diagnose's curves(),
# docs/model-discovery.md "Curves"), from the straight part's fit.
KINDS = ((effects.TEMP_OFFSET,), (effects.TEMP_SCALE,), (effects.DRIFT,),
         (effects.NONLINEAR,), (effects.TEMP_OFFSET2,), (effects.SUPPLY_OFFSET,),
         (effects.STEP,), (effects.TEMP_OFFSET, effects.TEMP_OFFSET2))
N_SINGLE = const(7)          # the single effects, among which rule.best chooses
PAIR = const(7)              # the curve with its straight part
N_CANDIDATES = const(8)
N_ALL = const(15)            # N_PARAMS + 6: the largest candidate's parameters
# The model's limit: one GaussNewton of N_ALL = 9 + 6 parameters holds two 3-parameter effects.
# A board that has adopted one single effect A tries A + B for every other single effect B
# (its later discoveries: `round` 2); the curve pair is at the limit already.
MAX_EFFECTS = const(2)
MIN_HELD = const(30)         # held-out points needed (diagnose: >= 30 each half)
# Held-out blocks needed before a board tries (a day of wear: 6 odd 2-hour blocks).  A board
# tries again after each calibration, and nobody confirms what it adopts: it adopts an effect
# only on clear evidence (rule.clear), where `diagnose` also names weak evidence for a
# person to confirm on a longer recording.
MIN_BLOCKS = const(6)
UNTESTABLE = const(-1)
ERR_MAX = const(8388607)     # 2**23 - 1: 100 x ERR_MAX < 2**30 (a mean of 1.8 g^2 a point)

# Per step, so that no step outlasts the fit's own (emulated RP2040: the base fit's longest
# slice 1.1 ms; 8 points scored took 5.7 ms, 4 slots compared 4.0 ms; docs/model-discovery.md
# "Discovery on the board"):
SCORE_POINTS = const(1)      # held-out points scored (2 took 2.23-2.42 ms as run, 1 1.29)
BLOCK_SCAN = const(48)       # held-out slots scanned to mark or compare one slot's block (a
# whole pass of CAPACITY took 2.35 and 2.45 ms)

# the phases: their slices' places in the table (acal/core/status.py; _DONE is their count)
_BASE = 0       # the base model scored on the held-out points
_FIT = 1        # candidate i's fit, a slice a step
_SEARCH = 2     # a step's change-point search on the base fit
_SCORE = 3      # candidate i scored
_BLOCKS = 4     # the held-out blocks counted
_BETTER = 5     # candidate i's blocks compared with the base model's
_PLACE = 6      # the step: its time placed among its gap's held-out points (stepplace)
_NEXT = 7       # candidate i's testability (a pass over the fit points' conditions) a step
_BEGIN = 8      # candidate i's fit begun (a step of its own: 1.3 ms on an RP2040, as testable)
_DONE = 9


def adoptable(kinds):
    """True when the discovery can adopt the model of these effects: a candidate of its first
    round, or a single effect with another after it (its second)."""
    if kinds in KINDS:
        return True
    return (len(kinds) == MAX_EFFECTS and kinds[0] != kinds[1]
            and (kinds[0],) in KINDS[:N_SINGLE] and (kinds[1],) in KINDS[:N_SINGLE])


def more(kinds):
    """True when a model of these effects has room for one more that the discovery tries: a
    single effect (not the curve pair, at the limit already)."""
    return len(kinds) < MAX_EFFECTS and (kinds == () or kinds in KINDS[:N_SINGLE])


def testable(kind, cond, n):
    """True when n fit points' conditions (flat, COND apiece) span what the candidate's
    regressor needs (bins.py's thresholds, which `diagnose` asks too; a reading's effect needs
    none): pipeline.spanned's question of the bins' points, through the same
    effects.condition_of and bins.DIFFERS, here of a flat array (the bins' slots are not)."""
    c = effects.condition_of(kind)
    return c < 0 or _range(cond, n, c) >= DIFFERS[c]


class Discover(Sliced):
    """After a run (begin(), step() until True): before (the base model's held-out error),
    errs[i] (candidate i's, -1 not testable), betters[i], blocks, chosen (the index
    rule.best gives, or PAIR as diagnose prefers the curve; -1: none testable), adopted
    (True when the rule names it), kind (its effects.model_code, 0: none; kind_ids: every
    candidate's), params (its parameters, Q24) and step_time (a step's).

    The step's time is placed, before the choice, among the held-out points that fall between
    the fit points on either side of it (stepplace.py: the fit leaves it free there; the shock
    may lie anywhere in a held-out block): its errs entry is then placed_loo, the held-out error
    with each gap point scored at a time placed from the others (leave-one-out: the points that
    place a time must not judge it), step_unplaced the fit's time's, placed_insample every gap
    point at the placed time (-1: not placed), gap_n the points; its betters stay the fit's
    time's.  fitted_time is the chosen step's fit time, step_time the placed one."""

    def __init__(self, max_points, held):
        self.held = held
        self.fit = GaussNewton(max_points, KINDS[PAIR], True)   # sized for the largest
        # a second such fit: take() hands the adopted one to the pipeline and the discovery
        # goes on (its second round) with this one
        self.spare = GaussNewton(max_points, KINDS[PAIR], True)
        self.kinds = KINDS          # the candidates' effect tuples (a second round's: _pairs)
        self.base = ()              # the effects of the model the candidates add one to
        self.new_ids = int32s(N_CANDIDATES)   # the effect each candidate adds (0: none)
        self.start = int32s(N_ALL)            # a second round's start: the base model's fit
        self.new_at = N_PARAMS      # where the added effect's parameters begin
        self.round = 0
        self.pairs = None           # the second round's tuples, made once per base effect
        self.pairs_base = 0
        self.score = HeldScore(held.capacity)
        from acal.core.changepoint import ChangePoint   # the step's search: nothing per point
        self.search = ChangePoint()
        self.kind_ids = int32s(N_CANDIDATES)
        self.errs = int32s(N_CANDIDATES)
        self.betters = int32s(N_CANDIDATES)
        self.fits = int32s(4 * N_CANDIDATES)   # per candidate: iterations, points kept,
        # objective at the start and at the end (the fit's, Q24 g^4 saturated below 2**30)
        self.all_params = int32s(N_CANDIDATES * N_ALL)
        self.ts = int32s(N_CANDIDATES)
        self.params = int32s(N_ALL)
        self.sliced()   # the phases' slices
        self.i = 0
        self.pos = 0           # where a sliced score or block comparison stands
        self.pipe = None
        self.before = 0
        self.blocks = 0
        self.chosen = -1
        self.adopted = False
        self.kind = 0
        self.step_time = 0
        self.fitted_time = 0
        self.place = StepPlace()   # the step's time among its gap's held-out points
        self.gap_lo = 0        # the gap's lower end: the last fit point's time before the step
        self.gap_n = 0
        self.placed_loo = -1
        self.placed_insample = -1
        self.step_unplaced = -1

    def begin(self, pipe):
        """Start on a pipeline whose base fit has just ended usable: its gathered points and
        conditions (relative to pipe.ref_*), its fit's parameters."""
        self.pipe = pipe
        self._candidates(pipe.kinds)
        self.i = 0
        self.pos = 0
        self.chosen = -1
        self.adopted = False
        self.kind = 0
        self.before = 0
        self.blocks = 0
        self.gap_n = 0
        self.placed_loo = -1
        self.placed_insample = -1
        self.step_unplaced = -1
        self.score.scan = -1
        for i in range(N_CANDIDATES):
            self.errs[i] = UNTESTABLE
            self.betters[i] = 0
        self.phase = _BASE

    def _candidates(self, base):
        # the candidates adding one effect to the pipeline's model: the first round's on the
        # paper's model, else `base` + each other single effect (not a second step), their
        # tuples made once per base effect (the one allocation of a second round)
        self.base = base
        self.round = 1 + len(base)
        self.new_at = N_PARAMS + 3 * len(base)
        if not base:
            self.kinds = KINDS
        else:
            if self.pairs is None or self.pairs_base != base[0]:
                self.pairs = [None] * N_CANDIDATES
                for i in range(N_SINGLE):
                    if KINDS[i][0] != base[0]:
                        self.pairs[i] = (base[0], KINDS[i][0])
                self.pairs_base = base[0]
            self.kinds = self.pairs
        for i in range(N_CANDIDATES):
            k = self.kinds[i]
            self.kind_ids[i] = 0 if k is None else effects.model_code(k)
            self.new_ids[i] = 0 if k is None else k[len(base)]

    def _fit_slice(self):
        if self.fit.step():
            self._fitted()

    def _search_slice(self):
        if self.search.step():
            self._searched()

    def _score_base(self):
        # the base model's held-out error, SCORE_POINTS a step
        s = self.score
        h = self.held
        if self.pos == 0:
            if h.count < MIN_HELD:
                self.phase = _DONE
                return
            pipe = self.pipe
            s.begin(pipe.optimiser.p, self.base, h, pipe.ref, pipe.step_time)
            self.pos = 1
        if not s.part(SCORE_POINTS):
            return
        self.before = _saturated(s.total)
        if self.before <= 0:
            self.phase = _DONE
            return
        s.firsts = 0
        self.pos = 0
        self.phase = _BLOCKS

    def _count_blocks(self):
        # the base errors kept and the blocks' first slots marked, BLOCK_SCAN slots scanned a
        # step
        s = self.score
        i = self.pos
        if s.scan < 0:
            s.keep_as_base(i + 1, i)
        if not s.mark_slot(self.held, i, BLOCK_SCAN):
            return
        self.pos = i + 1
        if self.pos < self.held.count:
            return
        self.blocks = s.firsts
        if self.blocks < MIN_BLOCKS:
            self.phase = _DONE
            return
        self._next(0)

    def _next(self, i):   # candidate i next, in steps of its own (_try, _begin_fit)
        self.i = i
        self.phase = _NEXT

    def _try(self):
        # one candidate's testability a step (the absent skipped), or the choice when none is left
        pipe = self.pipe
        i = self.i
        while i < N_CANDIDATES and self.new_ids[i] == 0:
            i += 1
        self.i = i
        if i == N_CANDIDATES:
            self._choose()
            return
        if not testable(self.new_ids[i], pipe.aux, pipe.n_fit):
            self.i = i + 1
            return
        fit = self.fit
        _rekind(fit, self.kinds[i])
        fit.ts = pipe.step_time if effects.STEP in self.base else 0
        if self.new_ids[i] == effects.STEP:
            self.search.begin(pipe.optimiser)
            self.phase = _SEARCH
            return
        self.phase = _BEGIN

    def _begin_fit(self):
        pipe = self.pipe
        self.fit.begin(pipe.points, pipe.n_fit, pipe.iterations, pipe.aux, self._start())
        if self.i == PAIR and self.errs[0] != UNTESTABLE:   # from the straight part's fit
            for k in range(N_PARAMS, N_PARAMS + 3):
                self.fit.p[k] = self.all_params[k]
        self.phase = _FIT

    def _searched(self):
        if not self.search.found:
            self._next(self.i + 1)
            return
        self.fit.ts = self.search.ts
        self.gap_lo = self.search.time_before()   # now: the sort buffer is the base fit's
        self.phase = _BEGIN

    def _start(self):
        # the candidates' start: the base model's fit (the paper's: its 9 parameters, the
        # effect's at zero; a second round's: its own, the added effect's at zero)
        p = self.pipe.optimiser.p
        if not self.base:
            return p
        st = self.start
        for k in range(N_ALL):
            st[k] = p[k] if k < self.new_at else 0
        return st

    def _fitted(self):
        # candidate i's fit has ended: kept and scored when it is OK
        fit = self.fit
        i = self.i
        if fit.status != OK:
            self._next(i + 1)
            return
        f = 4 * i
        self.fits[f] = fit.iterations
        self.fits[f + 1] = fit.n
        self.fits[f + 2] = fit.objective_start
        self.fits[f + 3] = fit.objective
        for k in range(N_ALL):
            self.all_params[N_ALL * i + k] = fit.p[k]
        self.ts[i] = fit.ts
        pipe = self.pipe
        self.score.begin(fit.p, fit.kinds, self.held, pipe.ref, fit.ts)
        self.phase = _SCORE

    def _score_candidate(self):
        # candidate i's held-out error, SCORE_POINTS a step
        if not self.score.part(SCORE_POINTS):
            return
        e = _saturated(self.score.total)
        self.errs[self.i] = e
        if e < 0:
            self._next(self.i + 1)
            return
        self.pos = 0
        self.phase = _BETTER

    def _compare_blocks(self):
        # the blocks candidate i is better in, BLOCK_SCAN slots scanned a step
        better = self.score.compare_slot(self.held, self.pos, BLOCK_SCAN)
        if better < 0:
            return
        self.betters[self.i] += better
        self.pos += 1
        if self.pos < self.held.count:
            return
        i = self.i
        if self.new_ids[i] != effects.STEP:
            self._next(i + 1)
            return
        # the step's time placed among the held-out points of its gap before the choice, so
        # that the step is chosen (or not) on its placed error, as diagnose chooses
        pipe = self.pipe
        self.score.begin(self.fit.p, self.fit.kinds, self.held, pipe.ref, self.ts[i])
        self.place.begin(self.score, self.held, pipe.ref[C_TIME], self.gap_lo, self.ts[i],
                         self.errs[i], BLOCK_SCAN)
        self.phase = _PLACE

    def _choose(self):
        i = rule.best(self.kind_ids, self.errs, N_SINGLE)
        named = (rule.adopted(self.before, self.errs, self.betters, self.blocks, i)
                 and rule.clear(self.betters[i], self.blocks))
        if rule.adopted(self.before, self.errs, self.betters, self.blocks, PAIR) and \
                rule.clear(self.betters[PAIR], self.blocks) and self.errs[PAIR] >= 0 and \
                (not named or not rule.plain_preferred(self.errs[PAIR], self.errs[i])):
            i = PAIR      # diagnose: the curve unless the best single comes within 1.5x
            named = True
        self.chosen = i
        self.adopted = named
        if i >= 0:
            for k in range(N_ALL):
                self.params[k] = self.all_params[N_ALL * i + k]
            self.fitted_time = self.ts[i]
            self.step_time = self.place.step_time if self.new_ids[i] == effects.STEP else self.ts[i]
            if self.adopted:
                self.kind = self.kind_ids[i]
        self.phase = _DONE

    def _place(self):
        # a slice of the step's placing; when placed, its time and errors (saturated), and the
        # step's held-out error becomes its placed one, leave-one-out (errs_unplaced: the fit's)
        pl = self.place
        if not pl.step():
            return
        i = self.i
        self.gap_n = pl.n
        self.placed_loo = _saturated(pl.placed_loo)      # -1 (not placed) as it stands
        self.placed_insample = _saturated(pl.placed_insample)
        self.step_unplaced = self.errs[i]
        if self.placed_loo >= 0:
            self.errs[i] = self.placed_loo
        self._next(i + 1)

    def take(self):
        """The fit re-kinded to the chosen candidate and holding its parameters and step
        time (the fit holds the last candidate tried until then); returns it.  The discovery
        goes on with its spare fit (the pipeline's model now holds this one)."""
        fit = self.fit
        self.fit = self.spare
        self.spare = fit
        _rekind(fit, self.kinds[self.chosen])
        for k in range(N_ALL):
            fit.p[k] = self.params[k]
        fit.ts = self.step_time
        return fit

    def run(self, pipe):
        """begin() and every step at once."""
        self.begin(pipe)
        self.finish()

    # the phases' slices, in phase order (acal/core/status.py): the class's one tuple of plain
    # functions, so an instance holds no bound method for them (only a reference to this)
    SLICES = (_score_base, _fit_slice, _search_slice, _score_candidate, _count_blocks,
              _compare_blocks, _place, _try, _begin_fit)


def _rekind(fit, kinds):
    # the one fit made another candidate: a preallocated tuple of at most as many effects
    fit.kinds = kinds
    fit.nk = len(kinds)
    fit.n_params = N_PARAMS + 3 * len(kinds)
    for k in range(len(kinds)):
        fit.kind_ids[k] = kinds[k]


def _saturated(e):
    return ERR_MAX if e > ERR_MAX else e


def _range(cond, n, c):
    # the range of condition c over n points' conditions (flat, COND apiece)
    if n == 0:
        return 0
    lo = hi = cond[c]
    for i in range(1, n):
        v = cond[COND * i + c]
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
    return hi - lo
