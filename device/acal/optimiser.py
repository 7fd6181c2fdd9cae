# The optimiser of Farago 2024 (section II-C, eqs. 12-16) in fixed point.
#
#   g_i = (f(p + h e_i) - f(p)) / h            forward difference, eq. 13, h = 2**-17
#   p  <- p - alpha o g / N                    eq. 14 with the vectorised rate of eq. 16
#
# f is the square-root-free objective summed over the N points (model.objective); dividing the
# gradient by N makes the step that of the objective averaged over the points, the scaling under
# which the paper's rates alpha_s = 0.3, alpha_m = 0.8, alpha_o = 0.2 converge (with the plain sum
# the scale step is N times too large and diverges; README "Learning-rate scaling").
# Formats: fixed.py.  Failure is reported, never returned as parameters: see the status codes.
from acal.fixed import (H_PARAM, N_PARAMS, UPDATE_MUL, ALPHA_DEN, ALPHA_SCALE, ALPHA_MISALIGN,
                        ALPHA_OFFSET)
from acal import model

OK = 0
DIVERGED = 1        # a parameter left the fit region, or the objective ended above its start
TOO_FEW = 2         # fewer points than parameters
OUT_OF_BOUNDS = 3   # converged outside the calibration bounds (fixed.py): not a sensor we trust
STATUS_NAMES = ("ok", "diverged", "too few points", "out of calibration bounds")

MIN_POINTS = N_PARAMS
DEFAULT_ITERATIONS = 50
COMPOSED_ITERATIONS = 200  # composed models: the effect terms converge more slowly


class Optimiser:
    """Integer gradient descent on the 9 model parameters, plus 3 per effect of `kinds`
    (acal.effects ids: a composed model; their parameters take the offsets' rate, their
    regressors being normalised to an offset's size - acal/effects.py).

    Buffers for up to max_points points are allocated once; `run` allocates nothing on a 64-bit
    port.  After run(): p holds the parameters (Q24), status a code above, iterations the number
    done, objective the final objective and objective_start the one at p0 (Q40 g^4, summed)."""

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
        each point's dT and dt, acal/effects.py) from p0; return the status."""
        self.iterations = 0
        np_ = self.n_params
        if n < np_:
            self.status = TOO_FEW
            return TOO_FEW
        if n > self.max_points:
            raise ValueError("more points than the optimiser was sized for")
        u = self.u
        p = self.p
        df = self.df
        alpha = self.alpha
        kinds = self.kinds
        model.load_points(pts, n, u)
        model.identity(p)
        for i in range(N_PARAMS, np_):
            p[i] = 0
        den = ALPHA_DEN * n
        mul = UPDATE_MUL
        h = H_PARAM
        f0 = self._f(aux, n)
        self.objective_start = f0
        self.status = OK
        for it in range(iterations):
            for i in range(np_):
                p[i] += h
                df[i] = self._f(aux, n) - f0
                p[i] -= h
            for i in range(np_):
                p[i] -= (alpha[i] * mul * df[i]) // den
            self.iterations = it + 1
            if not model.in_fit_region(p) or (kinds and not model.effects_within(p, kinds, 4)):
                self.status = DIVERGED
                return DIVERGED
            f0 = self._f(aux, n)
        self.objective = f0
        if f0 > self.objective_start:
            self.status = DIVERGED
        elif not model.in_bounds(p) or (kinds and not model.effects_within(p, kinds, 1)):
            self.status = OUT_OF_BOUNDS
        return self.status
