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
# ESP32 keeps |int| < 2**30 unboxed): products wider than that go through acal/wide.py, and the
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
# (J = 2 d~ 2**(s - QD), r = r~ 2**(tau - 22)), solved by acal/solve.py.
# The objective f is in 2**(2 tau - 44) g^4; objective and objective_start are reported in
# Q24 g^4 (OBJ_Q), saturated at 2**30 - 1.
from acal.fixed import N_PARAMS, POINT_TO_PARAM_SHIFT
from acal.bins import COND, conditions
from acal import effects
from acal import model
from acal.model import FIT_W_MAX
from acal.wide import mul_shift
from acal.emit import SIGN_SHIFT, viper, ptr32
from acal.optimiser import OK, DIVERGED, TOO_FEW, OUT_OF_BOUNDS, UNDETERMINED
from acal.solve import Solver

DEFAULT_ITERATIONS = 20   # Gauss-Newton steps per fit (it stops earlier once converged)
# residuals per step() of a trial (docs/method-and-formats.md "Sliced fit")
TRIAL_POINTS = 4
SORT_POINTS = 8           # points inserted per step() of the sort
REJECT_POINTS = 8        # points sifted per step() of the rejection
MAX_POINTS = 128          # the sums' bound (above)
QD_BASE = 24
QD_EFFECT = 16
R_MAX = 1 << 18           # |r~| <= 2**18
D_MAX = 1 << 11           # |d~| <= 2**11
B_MASK = 511
B_SPLIT = 9               # b in two limbs: sum d~ (r~ >> 9) 2**9 + sum d~ (r~ & 511)
F_TAU_OFFSET = 7          # f reads r 2**-(tau + 7): |r| 2**-(tau + 7) <= 2**11
TRIAL_MAX = 1 << 13       # a trial residual past 2**(13 + tau + 7): the trial is worse
F_LIMIT = 1 << 29
RHS_HI_MAX = 1 << (28 - 9 - 1)   # the high limb's bound for -b below 2**28
OBJ_Q = 24
OBJ_MAX = 0x3FFFFFFF      # 2**30 - 1
MU_MAX = 1 << 24          # damping lambda = mu 2**-8; mu 0 is plain Gauss-Newton
CONVERGED_SHIFT = 14      # converged when a step lowers the objective by < 2**-14 of it
MAX_REFUSED = 6           # refused steps in a row: as far as the integers go
# Outlier rejection: |r| above REJECT_MUL x the median |r| (~4 standard deviations of Gaussian
# residuals) and above REJECT_MIN (4 mg of | |a| - 1 g |, as r ~ 2 (|a| - 1)); up to
# REJECT_ROUNDS rounds of dropping and refitting.
REJECT_MUL = 6
REJECT_MIN = (8 << model.GN_R_Q) // 1000
REJECT_ROUNDS = 3

_ACCUM = 0   # residuals and Jacobian rows at p, point by point
_SOLVE = 1   # the damped normal equations, scaled (solve.Solver.begin)
_ELIM = 2    # ... and solved, a few rows a step -> a trial step
_TRIAL = 3   # the objective at the trial parameters, point by point
_SORT = 4    # |r| sorted, point by point, for the median
_REJECT = 5  # the points above the limit dropped
_DONE = 6


class GaussNewton:
    """Integer Gauss-Newton on the 9 model parameters, plus 3 per effect of `kinds` (a composed
    model, acal/effects.py; aux holds each point's dT, dt and dV, COND apiece).  reject: outlier
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
        self.u = [0] * (3 * max_points)
        self.aux = conditions(max_points)
        self.index = [0] * max_points
        self.keep = [0] * max_points
        self.r = [0] * max_points       # residuals at p (Q22 g^2)
        self.rt = [0] * max_points      # residuals at the trial parameters
        self.srt = [0] * max_points     # |r| being sorted
        self.p = [0] * np_
        self.pt = [0] * np_
        # int32 arrays: _accumulate reads them through typed pointers (acal/emit.py)
        self.d = conditions(np_)
        self.a = conditions(np_ * np_)  # sum d~ d~^T, lower triangle
        self.b = conditions(np_)        # sum d~ r~, high limb (units of 2**B_SPLIT)
        self.bl = conditions(np_)       # ... low limb, in [0, 2**B_SPLIT) between points
        self.sh = [0] * np_             # column scales s_k
        self.qd = [QD_BASE if k < N_PARAMS else QD_EFFECT for k in range(np_)]
        self.rhs = [0] * np_
        self.xshift = [0] * np_
        self.step_ = [0] * np_
        self.w = [0, 0, 0]
        self.z = [0, 0, 0]
        self.q = [0, 0, 0]
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
        self.tau = 0
        self.f_start = 0
        self.tau_start = 0
        self.mu = 0
        self.refused = 0
        self.limit = 0
        self.kept = 0
        self.rh = 0
        self.rl = 0
        self.row_ready = False
        self.first = True
        self.ts = 0                     # a step's time (as aux's dt), set before begin()

    # -- the fit as a whole ---------------------------------------------------------------------
    def run(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Fit n points (flat x y z, Q16 g) from p0 in one go; returns the status."""
        self.begin(pts, n, iterations, aux)
        while not self.step():
            pass
        return self.status

    def begin(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None, start=None):
        """Load n points (and for a composed model their dT, dt, dV in aux) and start from p0, or
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
        u = self.u
        lim = FIT_W_MAX >> POINT_TO_PARAM_SHIFT
        for i in range(3 * n):
            v = pts[i]
            if v > lim:
                v = lim
            elif v < -lim:
                v = -lim
            u[i] = v << POINT_TO_PARAM_SHIFT
        index = self.index
        keep = self.keep
        for i in range(n):
            index[i] = i
            keep[i] = 1
        if aux is not None:   # the effects' regressors (and the points' times a step search reads)
            for i in range(COND * n):
                self.aux[i] = aux[i]
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
        np_ = self.n_params
        a = self.a
        for k in range(np_):   # the lower triangle, the part the sums use
            row = k * np_
            for j in range(k + 1):
                a[row + j] = 0
        for i in range(np_):
            self.b[i] = 0
            self.bl[i] = 0
            if self.sh[i]:
                self.sh[i] -= 1   # the columns' scales start a bit below the last pass's
        self.tau = 0              # the residuals' scale from the smallest
        self.f = 0
        self.pos = 0
        self.row_ready = False
        self.phase = _ACCUM

    def step(self):
        """One slice of the fit; True when it has ended (status set)."""
        ph = self.phase
        if ph == _ACCUM:
            self._accum()
        elif ph == _SOLVE:
            self._solve()
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
            j = COND * i
            return model.residual_effects(p, self.u, at, self.aux[j], self.aux[j + 1],
                                          self.kinds, self.w, self.ts, self.aux[j + 2])
        u = self.u
        return model.residual(p, u[at], u[at + 1], u[at + 2])

    def point(self, i, w):
        """Point i's residual at p (Q22 g^2), and its reading with the effects removed into w
        (a list of 3, Q24 g): what acal/changepoint.py reads."""
        at = 3 * i
        if self.kinds:
            r = self._res(self.p, i)
            for c in range(3):
                w[c] = self.w[c]
            return r
        u = self.u
        for c in range(3):
            w[c] = u[at + c]
        return model.residual(self.p, u[at], u[at + 1], u[at + 2])

    def _row(self, i):
        # Residual of point i at p, its raw Jacobian row into d.
        p = self.p
        d = self.d
        u = self.u
        at = 3 * i
        kinds = self.kinds
        if not kinds:
            return model.residual_jacobian(p, u[at], u[at + 1], u[at + 2], d)
        w = self.w
        z = self.z
        q = self.q
        dT = self.aux[COND * i]
        dt = self.aux[COND * i + 1]
        dV = self.aux[COND * i + 2]
        for c in range(3):
            w[c] = u[at + c]
        model.remove_effects(p, kinds, w, 0, dT, dt, self.ts, dV)
        r0 = model.residual_jacobian(p, w[0], w[1], w[2], d)
        for c in range(3):
            q[c] = d[6 + c] >> (QD_BASE - QD_EFFECT)
        for k in range(len(kinds)):
            # dr/dtheta = dr/do . dw/dtheta: the correction with the offsets' rows as its
            # parameters
            for c in range(3):
                z[c] = u[at + c]
            effects.correct_u(kinds[k], q, 0, z, dT, dt, 0, self.ts, dV)
            j = N_PARAMS + 3 * k
            for c in range(3):
                d[j + c] = z[c] - u[at + c]
        return r0

    def _accum(self):
        # One point; a composed model's takes two calls: its scaled row, then the sums.
        i = self.pos
        if not self.row_ready:
            self._scaled_row(i)
            if self.kinds:
                self.row_ready = True
                return
        self.row_ready = False
        _accumulate(self.d, self.a, self.b, self.bl, self.n_params, self.rh, self.rl, SIGN_SHIFT)
        i += 1
        self.pos = i
        if i == self.n:
            if self.first:
                self.f_start = self.f
                self.tau_start = self.tau + F_TAU_OFFSET
                self.objective_start = _q24(self.f, self.tau + F_TAU_OFFSET)
                self.first = False
            self.phase = _SOLVE

    def _scaled_row(self, i):
        # Point i's residual into r and f, its row scaled into d (d~), r~ into rh, rl.
        d = self.d
        sh = self.sh
        r0 = self._row(i)
        self.r[i] = r0
        # the residual's scale tau: grows (and shifts f and b down) as residuals grow
        ar = r0 if r0 >= 0 else -r0
        t = self.tau
        if (ar >> t) >= R_MAX:
            g = _scale_for(ar, t, R_MAX)
            self.tau = g
            if i:   # the sums so far are zero at a pass's first point
                self.f >>= 2 * (g - t)
                self._shift_b(g - t)
            t = g
        self.f += _square(r0, t + F_TAU_OFFSET)
        rs = (r0 + (1 << (t - 1))) >> t if t else r0
        self.rh = rs >> B_SPLIT
        self.rl = rs & B_MASK
        # the columns' scales s_k, likewise
        for k in range(self.n_params):
            v = d[k]
            s = sh[k]
            av = v if v >= 0 else -v
            if (av >> s) >= D_MAX:
                g = _scale_for(av, s, D_MAX)
                if i:
                    self._grow(k, g - s)
                s = g
                sh[k] = g
            d[k] = (v + (1 << (s - 1))) >> s if s else v

    def _grow(self, k, g):
        # Column k's scale grows by g bits: its row and column of A (the diagonal twice) and
        # its entry of b shift down.
        a = self.a
        np_ = self.n_params
        for j in range(np_):
            if j < k:
                a[k * np_ + j] >>= g
            elif j > k:
                a[j * np_ + k] >>= g
        a[k * np_ + k] >>= 2 * g
        self._shift_limbs(k, g)

    def _shift_b(self, g):
        for k in range(self.n_params):
            self._shift_limbs(k, g)

    def _shift_limbs(self, k, g):
        # b_k = hi 2**9 + lo (lo in [0, 2**9)) -> floor(b_k 2**-g), in limbs again
        hi = self.b[k]
        h = hi >> g
        self.b[k] = h
        self.bl[k] = (((hi - (h << g)) << B_SPLIT) + self.bl[k]) >> g

    def _solve(self):
        np_ = self.n_params
        b = self.b
        bl = self.bl
        # -b from its limbs, shifted down by e so that it lies below 2**28
        e = 0
        for k in range(np_):
            v = b[k] if b[k] >= 0 else -b[k]
            while (v >> e) >= RHS_HI_MAX:
                e += 1
        for k in range(np_):
            if e <= B_SPLIT:
                self.rhs[k] = -((b[k] << (B_SPLIT - e)) + (bl[k] >> e))
            else:
                h = b[k] >> (e - B_SPLIT)
                self.rhs[k] = -(h + ((((b[k] - (h << (e - B_SPLIT))) << B_SPLIT) + bl[k]) >> e))
            self.xshift[k] = self.tau + 1 - self.sh[k] + self.qd[k] + e
        if self.solver.begin(self.a, self.rhs, self.step_, np_, self.mu, self.xshift):
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
        pt = self.pt
        rt = self.rt
        t = self.tau + F_TAU_OFFSET
        end = self.pos + TRIAL_POINTS
        if end > self.n:
            end = self.n
        for i in range(self.pos, end):
            r = self._res(pt, i)
            rt[i] = r
            if ((r if r >= 0 else -r) >> t) >= TRIAL_MAX:
                self.ft = F_LIMIT
            else:
                self.ft += _square(r, t)
                if self.ft > F_LIMIT:
                    self.ft = F_LIMIT
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
        self.objective = _q24(self.f, self.tau + F_TAU_OFFSET)
        p = self.p
        if _above(self.f, self.tau + F_TAU_OFFSET, self.f_start, self.tau_start) and self.rejected == 0:
            self.status = DIVERGED
        elif not model.in_bounds(p) or (self.kinds and not model.effects_within(p, self.kinds, 1)):
            self.status = OUT_OF_BOUNDS
        else:
            self.status = OK
        self.phase = _DONE


@viper
def _accumulate(row, sums, high, low, n: int, rh: int, rl: int, w: int):
    # One point's scaled row d~ (row) and residual r~ = rh 2**B_SPLIT + rl into A (sums, the
    # lower triangle) and b (high, low limbs): the fit's hot loop, viper on ports with emitters
    # (acal/emit.py; w: emit.SIGN_SHIFT; 9 is B_SPLIT, 511 B_MASK).  Every value below 2**29
    # (above; tests/test_ranges.py traces them).
    d = ptr32(row)
    a = ptr32(sums)
    b = ptr32(high)
    bl = ptr32(low)
    k = 0
    while k < n:
        dk = int(d[k]) << w >> w
        if dk:
            at = k * n
            j = 0
            while j <= k:
                a[at + j] = (int(a[at + j]) << w >> w) + dk * (int(d[j]) << w >> w)
                j += 1
            v = (int(bl[k]) << w >> w) + dk * rl
            b[k] = (int(b[k]) << w >> w) + dk * rh + (v >> 9)
            bl[k] = v & 511
        k += 1


def _scale_for(v, s, limit):
    # The smallest g >= s with v >> g below limit (v >= 0): 4 bits a step, then 1.
    while (v >> (s + 4)) >= limit:
        s += 4
    while (v >> s) >= limit:
        s += 1
    return s


def _square(r, t):
    # floor(r**2 4**-t) for |r| < 2**(13 + t), below 2**26, without a long.
    k = 8 - t
    if k > 0:
        r <<= k
        return mul_shift(r, r, 16)
    return mul_shift(r, r, 2 * t)


def _q24(f, t):
    # f 2**(2t - 44) g^4 in Q24 g^4, saturated at OBJ_MAX.
    s = 2 * t - 20
    if s <= 0:
        return f >> (-s)
    if f > (OBJ_MAX >> s):
        return OBJ_MAX
    return f << s


def _above(f1, t1, f2, t2):
    # f1 4**t1 > f2 4**t2, exactly, without a long.
    if t1 >= t2:
        return f1 > (f2 >> (2 * (t1 - t2)))
    h = f1 >> (2 * (t2 - t1))
    return h > f2 or (h == f2 and f1 - (h << (2 * (t2 - t1))) > 0)
