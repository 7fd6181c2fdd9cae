# The default profile's fit (README "Profiles"): Gauss-Newton with Levenberg-Marquardt damping on
# the paper's square-root-free residuals r_i = |a_i|^2 - 1 g^2 (eq. 12), in integers, run to the
# optimum of its points instead of a fixed 50 gradient steps; then integer outlier rejection:
# points whose residual stands far above the others' are dropped and the fit runs again.
#
# Sliced: begin() loads the points, each step() does a bounded piece of work (SLICE_POINTS
# points, one solve or a share of the sort) and returns True when the fit has ended, so the app
# runs it between FIFO reads; run() is begin() and every step at once, the same integers.
#
# Formats (fixed.py): points u Q24 g, parameters Q24, residuals Q30 g^2 (model.residual).
# Jacobian rows d = J 2**13 (model.residual_jacobian: analytic for the 9 parameters; an
# effect's, linear in its parameters, is its own correction with the offsets' sensitivities in
# place of its parameters: effects.correct_u, the one definition of each effect), |d| ~ 2**14.
# The normal equations, with J = d 2**-13, r = r_Q30 2**-30 and the step in Q24 LSB:
#   (sum d d^T) step = -2**STEP_SHIFT sum d r,          STEP_SHIFT = 2 * 13 - 30 - 13 + 24 = 7
# sum d d^T < 144 * 2**30 and |sum d r| < 144 * 2**15 * 2**31: below 2**53, << 7 below 2**60
# (acal/solve.py takes them from there).  The objective is model.objective's, Q40 g^4.
from acal.fixed import N_PARAMS, F_SHIFT
from acal import effects
from acal import model
from acal.optimiser import OK, DIVERGED, TOO_FEW, OUT_OF_BOUNDS, UNDETERMINED
from acal.solve import Solver

DEFAULT_ITERATIONS = 20   # Gauss-Newton steps per fit (it stops earlier once converged)
SLICE_POINTS = 1          # points per step() (README "Sliced fit": the RP2040 estimate)
SORT_POINTS = 2           # points inserted per step() of the sort
STEP_SHIFT = 7
MU_SHIFT = 8              # damping: diagonal * (1 + mu 2**-8); mu 0 is plain Gauss-Newton
MU_MAX = 1 << 24
CONVERGED_SHIFT = 14      # converged when a step lowers the objective by < 2**-14 of it
MAX_REFUSED = 6           # refused steps in a row: as far as the integers go
# Outlier rejection: |r| above REJECT_MUL x the median |r| (~4 standard deviations of Gaussian
# residuals) and above REJECT_MIN (4 mg of | |a| - 1 g |, as r ~ 2 (|a| - 1)); up to
# REJECT_ROUNDS rounds of dropping and refitting.
REJECT_MUL = 6
REJECT_MIN = (8 << 30) // 1000
REJECT_ROUNDS = 3

_ACCUM = 0   # residuals and Jacobian rows at p, point by point
_SOLVE = 1   # the damped normal equations
_SCALE = 2   # ... scaled (solve.Solver.begin)
_ELIM = 3    # ... and solved, a pivot row a step -> a trial step
_TRIAL = 4   # the objective at the trial parameters, point by point
_SORT = 5    # |r| sorted, point by point, for the median
_REJECT = 6  # the points above the limit dropped
_DONE = 7


class GaussNewton:
    """Integer Gauss-Newton on the 9 model parameters, plus 3 per effect of `kinds` (a composed
    model, acal/effects.py; aux holds each point's dT and dt).  reject: outlier rejection after
    the fit.  Buffers for up to max_points points are allocated once.

    After the fit: p (Q24), status (OK, DIVERGED, TOO_FEW, OUT_OF_BOUNDS, UNDETERMINED),
    iterations (accepted steps, every round), objective and objective_start (Q40 g^4, over the
    points kept / all points at p0), n (points kept), rejected, and keep[i] 1/0 for each of the
    points given to begin() in their order."""

    def __init__(self, max_points=72, kinds=(), reject=True):
        self.max_points = max_points
        self.kinds = tuple(kinds)
        self.reject = reject
        np_ = N_PARAMS + 3 * len(self.kinds)
        self.n_params = np_
        self.u = [0] * (3 * max_points)
        self.aux = [0] * (2 * max_points)
        self.index = [0] * max_points
        self.keep = [0] * max_points
        self.r = [0] * max_points       # residuals at p
        self.rt = [0] * max_points      # residuals at the trial parameters
        self.srt = [0] * max_points     # |r| being sorted
        self.p = [0] * np_
        self.pt = [0] * np_
        self.d = [0] * np_
        self.a = [0] * (np_ * np_)      # sum d d^T, lower triangle
        self.b = [0] * np_              # sum d r
        self.m = [0] * (np_ * np_)      # the damped system
        self.rhs = [0] * np_
        self.step_ = [0] * np_
        self.w = [0, 0, 0]
        self.z = [0, 0, 0]
        self.solver = Solver(np_)
        self.status = OK
        self.phase = _DONE
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
        self.mu = 0
        self.refused = 0
        self.first = True

    # -- the fit as a whole ---------------------------------------------------------------------
    def run(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Fit n points (flat x y z, Q16 g) from p0 in one go; returns the status."""
        self.begin(pts, n, iterations, aux)
        while not self.step():
            pass
        return self.status

    def begin(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None, start=None):
        """Load n points (and for a composed model their dT, dt in aux) and start from p0, or
        from the 9 parameters of start (a base fit's: a composed fit then starts where the
        base model is best, effects at zero)."""
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
        model.load_points(pts, n, self.u)
        for i in range(n):
            self.index[i] = i
            self.keep[i] = 1
            if self.kinds:
                self.aux[2 * i] = aux[2 * i]
                self.aux[2 * i + 1] = aux[2 * i + 1]
        model.identity(self.p)
        if start is not None:
            for i in range(N_PARAMS):
                self.p[i] = start[i]
        for i in range(N_PARAMS, self.n_params):
            self.p[i] = 0
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
        np_ = self.n_params
        for i in range(np_ * np_):
            self.a[i] = 0
        for i in range(np_):
            self.b[i] = 0
        self.f = 0
        self.pos = 0
        self.phase = _ACCUM

    def step(self):
        """One slice of the fit; True when it has ended (status set)."""
        ph = self.phase
        if ph == _ACCUM:
            self._accum()
        elif ph == _SOLVE:
            self._solve()
        elif ph == _SCALE:
            if self.solver.begin(self.m, self.rhs, self.step_, self.n_params):
                self.phase = _ELIM
            else:
                self._undetermined()
        elif ph == _ELIM:
            self._elim()
        elif ph == _TRIAL:
            self._trial()
        elif ph == _SORT:
            self._sort()
        elif ph == _REJECT:
            self._reject()
        return self.phase == _DONE

    # -- residuals ----------------------------------------------------------------------------
    def _res(self, p, i):
        at = 3 * i
        if self.kinds:
            return model.residual_effects(p, self.u, at, self.aux[2 * i], self.aux[2 * i + 1],
                                          self.kinds, self.w)
        u = self.u
        return model.residual(p, u[at], u[at + 1], u[at + 2])

    def _row(self, i):
        # Residual of point i at p, its Jacobian row into d.
        p = self.p
        d = self.d
        u = self.u
        at = 3 * i
        kinds = self.kinds
        if not kinds:
            return model.residual_jacobian(p, u[at], u[at + 1], u[at + 2], d)
        w = self.w
        z = self.z
        dT = self.aux[2 * i]
        dt = self.aux[2 * i + 1]
        for c in range(3):
            w[c] = u[at + c]
        model.remove_effects(p, kinds, w, 0, dT, dt)
        r0 = model.residual_jacobian(p, w[0], w[1], w[2], d)
        for k in range(len(kinds)):
            # dr/dtheta = dr/do . dw/dtheta: the correction with d[6:9] as its parameters
            for c in range(3):
                z[c] = u[at + c]
            effects.correct_u(kinds[k], d, 6, z, dT, dt, 0)
            j = N_PARAMS + 3 * k
            for c in range(3):
                d[j + c] = z[c] - u[at + c]
        return r0

    def _accum(self):
        d = self.d
        a = self.a
        b = self.b
        np_ = self.n_params
        end = self.pos + SLICE_POINTS
        if end > self.n:
            end = self.n
        for i in range(self.pos, end):
            r0 = self._row(i)
            self.r[i] = r0
            self.f += (r0 * r0) >> F_SHIFT
            for k in range(np_):
                dk = d[k]
                if dk:
                    row = k * np_
                    for j in range(k + 1):
                        a[row + j] += dk * d[j]
                    b[k] += dk * r0
        self.pos = end
        if end == self.n:
            if self.first:
                self.objective_start = self.f
                self.first = False
            self.phase = _SOLVE

    def _solve(self):
        np_ = self.n_params
        a = self.a
        m = self.m
        mu = self.mu
        for k in range(np_):
            row = k * np_
            for j in range(k):
                m[row + j] = a[row + j]
                m[j * np_ + k] = a[row + j]
            dkk = a[row + k]
            m[row + k] = dkk + ((dkk * mu) >> MU_SHIFT)
            self.rhs[k] = -(self.b[k] << STEP_SHIFT)
        self.phase = _SCALE

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
        pt = self.pt
        rt = self.rt
        end = self.pos + SLICE_POINTS
        if end > self.n:
            end = self.n
        for i in range(self.pos, end):
            r = self._res(pt, i)
            rt[i] = r
            self.ft += (r * r) >> F_SHIFT
        self.pos = end
        if end < self.n:
            return
        if self.ft >= self.f:
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
        srt = self.srt
        r = self.r
        end = self.pos + SORT_POINTS
        if end > self.n:
            end = self.n
        for i in range(self.pos, end):
            v = r[i]
            if v < 0:
                v = -v
            j = i
            while j > 0 and srt[j - 1] > v:
                srt[j] = srt[j - 1]
                j -= 1
            srt[j] = v
        self.pos = end
        if end == self.n:
            self.phase = _REJECT

    def _reject(self):
        r = self.r
        limit = REJECT_MUL * self.srt[self.n >> 1]
        if limit < REJECT_MIN:
            limit = REJECT_MIN
        u = self.u
        aux = self.aux
        kept = 0
        for i in range(self.n):
            if -limit <= r[i] <= limit:
                if kept != i:
                    for c in range(3):
                        u[3 * kept + c] = u[3 * i + c]
                    aux[2 * kept] = aux[2 * i]
                    aux[2 * kept + 1] = aux[2 * i + 1]
                    self.index[kept] = self.index[i]
                    r[kept] = r[i]
                kept += 1
            else:
                self.keep[self.index[i]] = 0
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
        self.objective = self.f
        p = self.p
        if self.objective > self.objective_start and self.rejected == 0:
            self.status = DIVERGED
        elif not model.in_bounds(p) or (self.kinds and not model.effects_within(p, self.kinds, 1)):
            self.status = OUT_OF_BOUNDS
        else:
            self.status = OK
        self.phase = _DONE
