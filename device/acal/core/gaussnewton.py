# The default profile's fit (docs/method-and-formats.md "Profiles"): Gauss-Newton with
# Levenberg-Marquardt damping on
# the paper's square-root-free residuals r_i = |a_i|^2 - 1 g^2 (eq. 12), in integers, run to the
# optimum of its points instead of a fixed 50 gradient steps; then integer outlier rejection:
# points whose residual stands far above the others' are dropped and the fit runs again.
#
# Sliced: begin() loads the points, each step() does a bounded piece of work (a point, or half
# of one for a composed model; a few rows of the solve; a share of the sort) and returns True when the fit has ended, so the app
# runs it between FIFO reads; run() is begin() and every step at once, the same integers.
#
# Every intermediate stays below 2**30, so a fit allocates nothing on a 32-bit port (an RP2040 or
# ESP32 keeps |int| < 2**30 unboxed): products wider than that go through acal/core/wide.py, and the
# sums are scaled as they grow (block floating point), per column and for the residuals.
# Formats (fixed.py, model.py): points u Q24 g, clamped to +-2.048 g per axis; parameters Q24;
# residuals r Q22 g^2 (model.residual); raw Jacobian rows d = J / 2 in 2**-QD_BASE (24) per
# parameter unit for the 9 parameters and 2**-QD_EFFECT (16) for an effect's (model.
# residual_jacobian; an effect's row is its own correction with the offsets' rows >> 8 in place
# of its parameters: effects.correct_u, the one definition of each effect).
# Scaled for the sums: r~ = round(r 2**-tau) and d~_k = round(d_k 2**-s_k), with tau and each s_k
# the smallest that keep |r~|, |d~_k| <= 2**11 over the points so far (a sum is shifted down
# when its scale grows), so that with n <= MAX_POINTS = 128 points
#   A = sum d~ d~^T, b = sum d~ r~ and f = sum floor(r^2 4**-tau) all stay below 2**29.
# The Gauss-Newton step (J^T J + lambda diag) delta = -J^T r is then, in Q24 LSB of each
# parameter,  (A + lambda diag A) z = -b,  delta_k = z_k 2**(tau + 1 - s_k + QD_k)
# (J = 2 d~ 2**(s - QD), r = r~ 2**(tau - 22)), solved by acal/core/solve.py.
# The objective f is in 2**(2 tau - 44) g^4; objective and objective_start are reported in
# Q24 g^4 (OBJ_Q), saturated at 2**30 - 1.
from array import array

from acal.core.fixed import N_PARAMS
from acal.core.bins import COND, conditions, int32s
from acal.core import model
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from acal.core.model import FIT_W_MAX
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x
from acal.core.status import OK, DIVERGED, TOO_FEW, OUT_OF_BOUNDS, UNDETERMINED
from acal.core.solve import Solver
from acal.core.status import Sliced
from acal.core.normal_sums import (QD_BASE, QD_EFFECT, F_TAU_OFFSET, accum_points, trial_points,
                               insert_abs, q24, above, rhs_from_limbs, point_row)

DEFAULT_ITERATIONS = 20   # Gauss-Newton steps per fit (it stops earlier once converged)
# residuals per step() of a trial (docs/method-and-formats.md "Sliced fit")
TRIAL_POINTS = 8
TRIAL_POINTS_COMPOSED = 8   # a composed model's residual costs its effects' removal too
ACCUM_POINTS = 6          # points per step() of the sums, a model without effects
ACCUM_POINTS_COMPOSED = 2
SORT_POINTS = 24          # points inserted per step() of the sort
REJECT_POINTS = 8        # points sifted per step() of the rejection
MAX_POINTS = 128          # the sums' bound (above)
OBJ_Q = 24
MU_MAX = 1 << 24          # damping lambda = mu 2**-8; mu 0 is plain Gauss-Newton
CONVERGED_SHIFT = 14      # converged when a step lowers the objective by < 2**-14 of it
MAX_REFUSED = 6           # refused steps in a row: as far as the integers go
# Outlier rejection: |r| above REJECT_MUL x the median |r| (~4 standard deviations of Gaussian
# residuals) and above REJECT_MIN (4 mg of | |a| - 1 g |, as r ~ 2 (|a| - 1)); up to
# REJECT_ROUNDS rounds of dropping and refitting.
REJECT_MUL = 6
REJECT_MIN = (8 << model.GN_R_Q) // 1000
REJECT_ROUNDS = 3

# the phases: their slices' places in the table (acal/core/status.py; const: compiled in)
_ACCUM = const(0)   # residuals and Jacobian rows at p, point by point
_SOLVE = const(1)   # the damped normal equations, scaled (solve.Solver.begin)
_ELIM = const(2)    # ... and solved, a few rows a step -> a trial step
_TRIAL = const(3)   # the objective at the trial parameters, point by point
_SORT = const(4)    # |r| sorted, point by point, for the median
_REJECT = const(5)  # the points above the limit dropped
_DONE = const(6)


class GaussNewton(Sliced):
    """Integer Gauss-Newton on the 9 model parameters, plus 3 per effect of `kinds` (a composed
    model, acal/core/effects.py; aux holds each point's dT, dt and dV, COND apiece).  reject: outlier
    rejection after the fit.  Buffers for up to max_points (<= MAX_POINTS) points are allocated once.

    After the fit: p (Q24), status (OK, DIVERGED, TOO_FEW, OUT_OF_BOUNDS, UNDETERMINED),
    iterations (accepted steps, every round), objective and objective_start (Q24 g^4, OBJ_Q,
    over the points kept / all points at p0), n (points kept), rejected, and keep[i] 1/0 for
    each of the points given to begin() in their order."""

    OBJ_Q = OBJ_Q

    def __init__(self, max_points=72, kinds=(), reject=True):
        if max_points > MAX_POINTS:
            raise ValueError("at most 128 points: the fit's sums are sized for them")
        self.max_points = max_points
        self.kinds = tuple(kinds)
        self.reject = reject
        np_ = N_PARAMS + 3 * len(self.kinds)
        self.n_params = np_
        self.u = int32s(3 * max_points)  # Q24 g, clamped: int32 (_trial_points reads it)
        self.aux = conditions(max_points)
        self.index = int32s(max_points)   # int32: load_points sets them
        self.keep = int32s(max_points)
        self.r = int32s(max_points)     # residuals at p (Q22 g^2; int32: _insert_abs reads r)
        self.rt = int32s(max_points)    # residuals at the trial parameters
        self.srt = int32s(max_points)   # |r| being sorted
        self.p = int32s(np_)            # int32 arrays: model.residual's typed pointer
        self.pt = int32s(np_)
        # int32 arrays: _accumulate reads them through typed pointers (acal/core/emit.py)
        self.d = int32s(np_)
        self.a = int32s(np_ * np_)  # sum d~ d~^T, lower triangle
        self.b = int32s(np_)        # sum d~ r~, high limb (units of 2**B_SPLIT)
        self.bl = int32s(np_)       # ... low limb, in [0, 2**B_SPLIT) between points
        self.sh = int32s(np_)           # column scales s_k (int32: scale_row's pointers)
        self.grown = int32s(np_)        # ... and by how much a point grew them
        self.state = int32s(2)          # where accum_points stopped, and tau
        self.qd = [QD_BASE if k < N_PARAMS else QD_EFFECT for k in range(np_)]
        self.rhs = int32s(np_)          # int32: the solver's _rhs_shift reads it
        self.xshift = [0] * np_
        self.step_ = [0] * np_
        self.w = int32s(3)              # int32: effects.correct_kinds' pointers
        self.z = int32s(3 + 3 * len(self.kinds))   # point_row: the point, each effect's result
        self.q = int32s(3)
        self.nk = len(self.kinds)
        self.ncond = COND               # aux's conditions a point, for normal_sums' viper rows
        self.kind_ids = int32s(self.nk)
        for k in range(len(self.kinds)):
            self.kind_ids[k] = self.kinds[k]
        self.solver = Solver(np_)
        self.status = OK
        # the phases' slices, in their order (acal/core/status.py; _DONE is their count)
        self.sliced()
        self.iterations = 0
        self.max_iterations = DEFAULT_ITERATIONS
        self.objective = 0
        self.objective_start = 0
        self.n = 0
        self.n_given = 0
        self.rejected = 0
        self.rounds = 0
        self.pos = 0
        self.f = 0
        self.ft = 0
        self.tau = 0
        self.f_start = 0
        self.tau_start = 0
        self.mu = 0
        self.refused = 0
        self.limit = 0
        self.kept = 0
        self.first = True
        self.ts = 0                     # a step's time (as aux's dt), set before begin()

    # -- the fit as a whole ---------------------------------------------------------------------
    def run(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Fit n points (flat x y z, Q16 g) from p0 in one go; returns the status."""
        self.begin(pts, n, iterations, aux)
        self.finish()
        return self.status

    def begin(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None, start=None):
        """Load n points (pts, Q16 g; and for a composed model their dT, dt, dV in aux: int32
        arrays, or lists, copied to one first) and start from p0, or
        from start: its 9 parameters (a base fit's: a composed fit then starts where the base
        model is best, effects at zero), or all of them when it holds as many as this fit."""
        if n > self.max_points:
            raise ValueError("more points than the optimiser was sized for")
        self.n = n
        self.n_given = n
        self.max_iterations = iterations
        self.iterations = 0
        self.rejected = 0
        self.rounds = 0
        self.objective = 0
        self.objective_start = 0
        self.first = True
        if type(pts) is list:     # a caller's list (the device hands int32 arrays over)
            pts = array("i", pts)
        if type(aux) is list:
            aux = array("i", aux)
        load_points(pts, self.u, 3 * n, aux, self.aux, 0 if aux is None else COND * n,
                    self.index, self.keep)
        model.identity(self.p)
        for i in range(N_PARAMS, self.n_params):
            self.p[i] = 0
        if start is not None:
            for i in range(N_PARAMS if len(start) < self.n_params else self.n_params):
                self.p[i] = start[i]
        for k in range(self.n_params):
            self.sh[k] = 12 if k < N_PARAMS else 4   # ~1 g rows: 2**24, 2**16 -> 2**11
        self.tau = 0
        if n < self.n_params:
            self.status = TOO_FEW
            self.phase = _DONE
            return
        self.status = OK
        self._restart()

    def _restart(self):
        self.mu = 0
        self.refused = 0
        self._accum_start()

    def _accum_start(self):
        # the sums zeroed, the columns' scales started a bit below the last pass's
        clear_sums(self.a, self.b, self.bl, self.sh, self.n_params, SIGN_SHIFT)
        self.tau = 0              # the residuals' scale from the smallest
        self.f = 0
        self.pos = 0
        self.phase = _ACCUM

    def _accum(self):
        # Up to ACCUM_POINTS points (a composed model's: ACCUM_POINTS_COMPOSED) at once; a point
        # that grows a scale in a slice of its own (accum_points).
        end = self.pos + (ACCUM_POINTS_COMPOSED if self.kinds else ACCUM_POINTS)
        if end > self.n:
            end = self.n
        self.f = accum_points(self, self.pos, end, self.tau, self.f)
        self.tau = self.state[1]
        self._accumulated(self.state[0])

    def point(self, i, w):
        """Point i's residual at p (Q22 g^2), and its reading with the effects removed into w
        (a list of 3, Q24 g): what acal/core/changepoint.py reads."""
        r = point_row(self, self.p, i, 0)
        src = self.w if self.kinds else self.u
        at = 0 if self.kinds else 3 * i
        for c in range(3):
            w[c] = src[at + c]
        return r

    def _accumulated(self, i):
        self.pos = i
        if i == self.n:
            if self.first:
                self.f_start = self.f
                self.tau_start = self.tau + F_TAU_OFFSET
                self.objective_start = q24(self.f, self.tau + F_TAU_OFFSET)
                self.first = False
            self.phase = _SOLVE

    def _solve(self):
        # -b from its limbs, shifted down by e so that it lies below 2**28.  (No local for
        # n_params: this and the solver's begin made a frame of 12 words, which MicroPython
        # takes from the heap: docs/method-and-formats.md "Frames".)
        e = rhs_from_limbs(self.b, self.bl, self.rhs, self.n_params, SIGN_SHIFT)
        for k in range(self.n_params):
            self.xshift[k] = self.tau + 1 - self.sh[k] + self.qd[k] + e
        if self.solver.begin(self.a, self.rhs, self.step_, self.n_params, self.mu, self.xshift):
            self.phase = _ELIM
        else:
            self._undetermined()

    def _undetermined(self):
        self.status = UNDETERMINED
        self.phase = _DONE

    def _elim(self):
        if not self.solver.step():
            return
        if not self.solver.ok:
            self._undetermined()
            return
        np_ = self.n_params
        pt = self.pt
        for k in range(np_):
            pt[k] = self.p[k] + self.step_[k]
        if model.in_fit_region(pt) and (not self.kinds or model.effects_within(pt, self.kinds, 4)):
            self.ft = 0
            self.pos = 0
            self.phase = _TRIAL
        else:
            self._refuse()

    def _refuse(self):
        # A step that did not lower the objective (or left the fit region): more damping.
        self.mu = 4 * self.mu + 1
        self.refused += 1
        if self.refused >= MAX_REFUSED or self.mu > MU_MAX:
            self._fitted()
        else:
            self.phase = _SOLVE

    def _trial(self):
        end = self.pos + (TRIAL_POINTS_COMPOSED if self.kinds else TRIAL_POINTS)
        if end > self.n:
            end = self.n
        self.ft = trial_points(self, self.pt, self.pos, end, self.tau + F_TAU_OFFSET, self.ft)
        self.pos = end
        if end < self.n:
            return
        if self.ft >= self.f:
            if self.mu == 0 and self.ft - self.f <= (self.f >> CONVERGED_SHIFT):
                self._fitted()   # the plain step changes f by less than its resolution
            else:
                self._refuse()
            return
        # accept: p <- pt, r <- rt (swapped, not copied)
        self.p, self.pt = self.pt, self.p
        self.r, self.rt = self.rt, self.r
        self.iterations += 1
        converged = self.f - self.ft <= (self.f >> CONVERGED_SHIFT)
        self.f = self.ft
        self.mu >>= 2
        self.refused = 0
        if converged or self.iterations >= self.max_iterations:
            self._fitted()
        else:
            self._accum_start()

    # -- outlier rejection --------------------------------------------------------------------
    def _fitted(self):
        if self.reject and self.rounds < REJECT_ROUNDS:
            self.pos = 0
            self.phase = _SORT
        else:
            self._finish()

    def _sort(self):
        # Insertion sort of |r|, SORT_POINTS a slice.
        end = self.pos + SORT_POINTS
        if end > self.n:
            end = self.n
        insert_abs(self.r, self.srt, self.pos, end, SIGN_SHIFT)
        self.pos = end
        if end == self.n:
            med = self.srt[self.n >> 1]
            limit = REJECT_MUL * med if med < (1 << 29) // REJECT_MUL else 1 << 29
            self.limit = limit if limit > REJECT_MIN else REJECT_MIN
            self.kept = 0
            self.pos = 0
            self.phase = _REJECT

    def _reject(self):
        # The points within the limit moved down over the dropped ones, REJECT_POINTS a step.
        r = self.r
        u = self.u
        aux = self.aux
        limit = self.limit
        kept = self.kept
        end = self.pos + REJECT_POINTS
        if end > self.n:
            end = self.n
        for i in range(self.pos, end):
            if -limit <= r[i] <= limit:
                if kept != i:
                    for c in range(3):
                        u[3 * kept + c] = u[3 * i + c]
                    for c in range(COND):
                        aux[COND * kept + c] = aux[COND * i + c]
                    self.index[kept] = self.index[i]
                    r[kept] = r[i]
                kept += 1
            else:
                self.keep[self.index[i]] = 0
        self.kept = kept
        self.pos = end
        if end < self.n:
            return
        if kept == self.n:
            self._finish()
            return
        self.rejected += self.n - kept
        self.n = kept
        self.rounds += 1
        if kept < self.n_params:
            self.status = TOO_FEW
            self.phase = _DONE
            return
        self._restart()

    def _finish(self):
        self.objective = q24(self.f, self.tau + F_TAU_OFFSET)
        p = self.p
        if above(self.f, self.tau + F_TAU_OFFSET, self.f_start, self.tau_start) and self.rejected == 0:
            self.status = DIVERGED
        elif not model.in_bounds(p) or (self.kinds and not model.effects_within(p, self.kinds, 1)):
            self.status = OUT_OF_BOUNDS
        else:
            self.status = OK
        self.phase = _DONE

    # the phases' slices, in phase order (acal/core/status.py): the class's one tuple of plain
    # functions, so an instance holds no bound method for them (only a reference to this)
    SLICES = (_accum, _solve, _elim, _trial, _sort, _reject)


@viper
def load_points(points, fit_points, n3: int, aux, fit_aux, naux: int, order, kept):
    # A fit's points (int32 arrays, Q16 g) clamped to +-FIT_W_MAX and into Q24 (<< 8), naux of
    # their conditions copied, each point's index (order) its own and kept (1): GaussNewton.
    # begin's loops, viper on ports with emitters.
    src = ptr32(points)
    u = ptr32(fit_points)
    index = ptr32(order)
    keep = ptr32(kept)
    i = 0
    while i < n3 // 3:
        index[i] = i
        keep[i] = 1
        i += 1
    w = int(SIGN_SHIFT)
    lim = int(FIT_W_MAX) >> 8
    i = 0
    while i < n3:
        v = int(src[i]) << w >> w
        if v > lim:
            v = lim
        elif v < 0 - lim:
            v = 0 - lim
        u[i] = v << 8
        i += 1
    if naux:
        a = ptr32(aux)
        b = ptr32(fit_aux)
        i = 0
        while i < naux:
            b[i] = a[i]
            i += 1


@viper
def clear_sums(sums, high, low, scales, n: int, w: int):
    # A pass's sums zeroed (A's lower triangle, b's limbs) and each column's scale started one
    # below the last pass's (when above 0): GaussNewton._accum_start's loops, viper on ports
    # with emitters.
    a = ptr32(sums)
    b = ptr32(high)
    bl = ptr32(low)
    sh = ptr32(scales)
    k = 0
    while k < n:
        j = 0
        while j <= k:
            a[k * n + j] = 0
            j += 1
        b[k] = 0
        bl[k] = 0
        s = int(sh[k]) << w >> w
        if s:
            sh[k] = s - 1
        k += 1
