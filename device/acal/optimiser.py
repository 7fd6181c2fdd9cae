# The optimiser of Farago 2024 (section II-C, eqs. 12-16) in fixed point.
#
#   g_i = (f(p + h e_i) - f(p)) / h            forward difference, eq. 13, h = 2**-17
#   p  <- p - alpha o g / N                    eq. 14 with the vectorised rate of eq. 16
#
# f is the square-root-free objective summed over the N points (model.objective); dividing the
# gradient by N makes the step that of the objective averaged over the points, the scaling under
# which the paper's rates alpha_s = 0.3, alpha_m = 0.8, alpha_o = 0.2 converge (with the plain sum
# the scale step is N times too large and diverges;
# docs/method-and-formats.md "Learning-rate scaling").
# Formats: fixed.py.  Failure is reported, never returned as parameters: see the status codes.
from acal.fixed import (OBJ_Q, H_PARAM, N_PARAMS, UPDATE_MUL, ALPHA_DEN, ALPHA_SCALE,
                        ALPHA_MISALIGN, ALPHA_OFFSET)
from acal import model

OK = 0
DIVERGED = 1        # a parameter left the fit region, or the objective ended above its start
TOO_FEW = 2         # fewer points than parameters
OUT_OF_BOUNDS = 3   # converged outside the calibration bounds (fixed.py): not a sensor we trust
UNDETERMINED = 4    # the points do not pin every parameter (acal/gaussnewton.py)
# A composed model's fit that failed, or ended worse than the base fit of the same points (by
# mean squared residual over the points each kept): the base calibration is kept, with the
# effects at zero (acal/pipeline.py, the wear profile).
BASE_KEPT_FAILED = 5
BASE_KEPT_WORSE = 6
STATUS_NAMES = ("ok", "diverged", "too few points", "out of calibration bounds",
                "parameters not determined by the points",
                "composed fit failed: base calibration kept",
                "composed fit worse than the base fit: base calibration kept")


def usable(status):
    """True when the fit's parameters may be applied (OK, or a base calibration kept)."""
    return status == OK or status == BASE_KEPT_FAILED or status == BASE_KEPT_WORSE

MIN_POINTS = N_PARAMS
DEFAULT_ITERATIONS = 50
COMPOSED_ITERATIONS = 200  # composed models: the effect terms converge more slowly


class Optimiser:
    """Integer gradient descent on the 9 model parameters, plus 3 per effect of `kinds`
    (acal.effects ids: a composed model; their parameters take the offsets' rate, their
    regressors being normalised to an offset's size - acal/effects.py).

    Buffers for up to max_points points are allocated once; `run` allocates nothing on a 64-bit
    port.  After run(): p holds the parameters (Q24), status a code above, iterations the number
    done, objective the final objective and objective_start the one at p0 (Q40 g^4, summed).

    Sliced: begin() then step() until it returns True does what run() does, the same integers;
    a step is one evaluation of the objective (the app runs one between FIFO reads)."""

    OBJ_Q = OBJ_Q

    def __init__(self, max_points=18, alphas=(ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET), kinds=()):
        self.max_points = max_points
        self.kinds = tuple(kinds)
        self.n_params = N_PARAMS + 3 * len(self.kinds)
        self.u = [0] * (3 * max_points)
        self.w = [0] * (3 * max_points) if self.kinds else None  # points with effects removed
        self.p = [0] * self.n_params
        self.df = [0] * self.n_params
        self.alpha = [0] * self.n_params
        self.set_rates(alphas[0], alphas[1], alphas[2])
        self.status = OK
        self.iterations = 0
        self.objective = 0
        self.objective_start = 0
        self.n = 0
        self.aux = None
        self.max_iterations = 0
        self.den = 1
        self.f0 = 0
        self.i = 0
        self.done = True

    def set_rates(self, alpha_s, alpha_m, alpha_o):
        """Learning rates in tenths (0.3 -> 3), per group: scale, misalignment, offset (and the
        effects' parameters)."""
        for i in range(self.n_params):
            self.alpha[i] = alpha_s if i < 3 else (alpha_m if i < 6 else alpha_o)

    def _f(self, aux, n):
        if self.kinds:
            return model.objective_effects(self.p, self.u, aux, n, self.kinds, self.w)
        return model.objective(self.p, self.u, n)

    def run(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Fit the model to n points (flat x y z list, Q16 g; for a composed model aux holds
        each point's dT, dt and dV, acal/bins.COND apiece, acal/effects.py) from p0; return the
        status."""
        self.begin(pts, n, iterations, aux)
        while not self.step():
            pass
        return self.status

    def begin(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Load the points and start from p0 (run() without the iterations)."""
        self.iterations = 0
        self.done = True
        if n < self.n_params:
            self.status = TOO_FEW
            return
        if n > self.max_points:
            raise ValueError("more points than the optimiser was sized for")
        model.load_points(pts, n, self.u)
        model.identity(self.p)
        for i in range(N_PARAMS, self.n_params):
            self.p[i] = 0
        self.n = n
        self.aux = aux
        self.max_iterations = iterations
        self.den = ALPHA_DEN * n
        self.f0 = self._f(aux, n)
        self.objective_start = self.f0
        self.status = OK
        self.i = 0
        self.done = False
        if iterations <= 0:
            self._finish()

    def step(self):
        """One evaluation of the objective: the gradient's next component, or the update and
        the objective at the new parameters.  True when the fit has ended."""
        if self.done:
            return True
        p = self.p
        i = self.i
        aux = self.aux
        n = self.n
        if i < self.n_params:
            p[i] += H_PARAM
            self.df[i] = self._f(aux, n) - self.f0
            p[i] -= H_PARAM
            self.i = i + 1
            return False
        df = self.df
        alpha = self.alpha
        den = self.den
        for k in range(self.n_params):
            p[k] -= (alpha[k] * UPDATE_MUL * df[k]) // den
        self.iterations += 1
        if not model.in_fit_region(p) or (self.kinds and not model.effects_within(p, self.kinds, 4)):
            self.status = DIVERGED
            self.done = True
            return True
        self.f0 = self._f(aux, n)
        self.i = 0
        if self.iterations >= self.max_iterations:
            self._finish()
        return self.done

    def _finish(self):
        self.done = True
        f0 = self.f0
        p = self.p
        self.objective = f0
        if f0 > self.objective_start:
            self.status = DIVERGED
        elif not model.in_bounds(p) or (self.kinds and not model.effects_within(p, self.kinds, 1)):
            self.status = OUT_OF_BOUNDS
