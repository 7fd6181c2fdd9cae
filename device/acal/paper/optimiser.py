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
# Every value of a run is a small int (below 2**30): the objectives are kept as limbs and the
# update's quotient taken from them (acal/paper/objective.py), so a run allocates nothing on a 32-bit
# port either.
from array import array

try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

from acal.core.fixed import (OBJ_Q, H_PARAM, N_PARAMS, ALPHA_DEN, ALPHA_SCALE,
                        ALPHA_MISALIGN, ALPHA_OFFSET)
from acal.core import model
from acal.core.emit import SIGN_SHIFT
from acal.core.status import Sliced
from acal.paper.objective import (objective_limbs, update, from_limbs, limbs_above, LIMBS, MAX_POINTS,
                            CACHE, PLAIN, BASE, GRADIENT)

# The fits' status codes live in acal/core/status.py (a wear-profile board does not load this module
# nor acal/paper/objective.py: their code would sit in its RAM); here for the paper profile's callers.
from acal.core.status import (OK, DIVERGED, TOO_FEW, OUT_OF_BOUNDS, UNDETERMINED,  # noqa: F401
                         BASE_KEPT_FAILED, BASE_KEPT_WORSE, usable)
# (the status codes' names: the host's alone, accelcal/bridge/boardlog.py STATUS_NAMES)

MIN_POINTS = N_PARAMS
DEFAULT_ITERATIONS = 50
COMPOSED_ITERATIONS = 200  # composed models: the effect terms converge more slowly


# the phases: their slices' places in the table (acal/core/status.py; _DONE is their count)
_START = const(0)      # the objective at p0
_GRADIENT = const(1)   # the gradient's objectives (a composed model's: one a slice)
_UPDATE = const(2)     # the update and the objective at the new parameters
_DONE = const(3)


class Optimiser(Sliced):
    """Integer gradient descent on the 9 model parameters, plus 3 per effect of `kinds`
    (acal.core.effects ids: a composed model; their parameters take the offsets' rate, their
    regressors being normalised to an offset's size - acal/core/effects.py).

    Buffers for up to max_points (<= 128) points are allocated once; `run` allocates nothing.
    After run(): p holds the parameters (Q24), status a code above, iterations the number done,
    objective the final objective and objective_start the one at p0 (Q40 g^4, summed; read-only,
    from their limbs: a long past 2**30 on a 32-bit port).

    Sliced: begin() then step() until it returns True does what run() does, the same integers;
    a step is the gradient (nine objectives from one pass over the points; a composed model's:
    one objective) or the update and one objective (the app runs one between FIFO reads)."""

    OBJ_Q = OBJ_Q

    def __init__(self, max_points=18, alphas=(ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET), kinds=()):
        if max_points > MAX_POINTS:
            raise ValueError("the optimiser takes at most 128 points")
        self.max_points = max_points
        self.kinds = tuple(kinds)
        self.n_params = N_PARAMS + 3 * len(self.kinds)
        self.u = array("i", [0] * (3 * max_points))
        self.w = array("i", [0] * (3 * max_points)) if self.kinds else None  # effects removed
        # objectives in limbs (acal/paper/objective.py): f(p + h e_k) per parameter k, then f(p), the
        # one at p0 and the final one
        self.base = LIMBS * self.n_params
        self.f = array("i", [0] * (self.base + 3 * LIMBS))
        # per point, what the gradient's objectives take from the one at p (acal/paper/objective.py;
        # a composed model's points move with its parameters: none)
        self.cache = self.f if self.kinds else array("i", [0] * (CACHE * max_points))
        self.p = [0] * self.n_params
        self.pa = array("i", [0] * self.n_params)   # p, as the viper functions read it
        self.alpha = array("i", [0] * self.n_params)
        self.set_rates(alphas[0], alphas[1], alphas[2])
        self.status = OK
        self.iterations = 0
        self.n = 0
        self.aux = None
        self.max_iterations = 0
        self.den = 1
        self.i = 0           # the gradient's next parameter
        # the phases' slices (acal/core/status.py): the objective at p0, the gradient, the update
        self.sliced()

    def __getattr__(self, name):
        # objective and objective_start, read from their limbs (a long past 2**30 on a 32-bit
        # port, made only when read): a property would slow every attribute store on MicroPython
        if name == "objective":
            return from_limbs(self.f, self.base + 2 * LIMBS)
        if name == "objective_start":
            return from_limbs(self.f, self.base + LIMBS)
        raise AttributeError(name)

    def set_rates(self, alpha_s, alpha_m, alpha_o):
        """Learning rates in tenths (0.3 -> 3), per group: scale, misalignment, offset (and the
        effects' parameters); each below 51.2 (objective.update's domain)."""
        for a in (alpha_s, alpha_m, alpha_o):
            if not 0 <= a < 512:
                raise ValueError("a learning rate lies in [0, 51.2)")
        for i in range(self.n_params):
            self.alpha[i] = alpha_s if i < 3 else (alpha_m if i < 6 else alpha_o)

    def _f(self, at, mode):
        # the objective at pa into f[at:at+LIMBS] (objective_limbs' mode); non-zero outside the
        # exact domain, which the fit's parameters (fit region, plus h) and points (load_points)
        # cannot leave
        if self.kinds:
            model.points_without_effects(self.p, self.u, self.aux, self.n, self.kinds, self.w)
            return objective_limbs(self.w, self.n, self.f, at, self.pa, PLAIN, self.cache,
                                   SIGN_SHIFT)
        return objective_limbs(self.u, self.n, self.f, at, self.pa, mode, self.cache, SIGN_SHIFT)

    def _sync(self):
        # p from pa (the viper functions' copy)
        for k in range(self.n_params):
            self.p[k] = self.pa[k]

    def run(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Fit the model to n points (flat x y z list, Q16 g; for a composed model aux holds
        each point's dT, dt and dV, acal/core/bins.COND apiece, acal/core/effects.py) from p0; return the
        status."""
        self.begin(pts, n, iterations, aux)
        self.finish()
        return self.status

    def begin(self, pts, n, iterations=DEFAULT_ITERATIONS, aux=None):
        """Load the points and start from p0 (run() without the iterations; the objective at p0
        is the first step)."""
        self.iterations = 0
        self.phase = _DONE
        if n < self.n_params:
            self.status = TOO_FEW
            return
        if n > self.max_points:
            raise ValueError("more points than the optimiser was sized for")
        if not model.load_points(pts, n, self.u):
            self.status = DIVERGED
            return
        p = self.p
        model.identity(p)
        for i in range(self.n_params):
            if i >= N_PARAMS:
                p[i] = 0
            self.pa[i] = p[i]
        self.n = n
        self.aux = aux
        self.max_iterations = iterations
        self.den = ALPHA_DEN * n
        self.status = OK
        self.phase = _START   # the objective at p0 first, in a slice of its own

    # step() (Sliced): one slice: the gradient (the nine objectives at p + h e_k, from the one
    # at p, in one call; a composed model's, one objective a slice), or the update and the
    # objective at the new parameters.  True when the fit has ended.

    def _start(self):
        # the objective at p0 (on an RP2040 begin's loading and it took 1.9 ms)
        f = self.f
        base = self.base
        if self._f(base, BASE):
            self.status = DIVERGED
            self.phase = _DONE
            return
        for j in range(LIMBS):
            f[base + LIMBS + j] = f[base + j]
        self.i = 0
        self.phase = _GRADIENT
        if self.max_iterations <= 0:
            self._finish()

    def _gradient(self):
        i = self.i
        if self.kinds:
            p = self.p
            pa = self.pa
            p[i] += H_PARAM
            pa[i] += H_PARAM
            bad = self._f(LIMBS * i, PLAIN)
            p[i] -= H_PARAM
            pa[i] -= H_PARAM
            self.i = i + 1
        else:
            bad = objective_limbs(self.u, self.n, self.f, 0, self.pa, GRADIENT, self.cache,
                                  SIGN_SHIFT)
            self.i = N_PARAMS
        if bad:
            self._diverged()
        elif self.i >= self.n_params:
            self.phase = _UPDATE

    def _update(self):
        # p[k] -= (alpha[k] * UPDATE_MUL * df[k]) // den, df[k] = f(p + h e_k) - f(p)
        out = update(self.f, self.base, self.pa, self.alpha, self.n_params, self.den, SIGN_SHIFT)
        self.iterations += 1
        if self.kinds:
            self._sync()
            if not model.effects_within(self.p, self.kinds, 4):
                out = 1
        if out or self._f(self.base, BASE):
            self._diverged()
            return
        self.i = 0
        self.phase = _GRADIENT
        if self.iterations >= self.max_iterations:
            self._finish()

    def _diverged(self):
        self._sync()
        self.status = DIVERGED
        self.phase = _DONE

    def _finish(self):
        self._sync()
        self.phase = _DONE
        f = self.f
        base = self.base
        for j in range(LIMBS):
            f[base + 2 * LIMBS + j] = f[base + j]
        if limbs_above(f, base, base + LIMBS):
            self.status = DIVERGED
        elif not model.in_bounds(self.p) or \
                (self.kinds and not model.effects_within(self.p, self.kinds, 1)):
            self.status = OUT_OF_BOUNDS

    # the phases' slices, in phase order (acal/core/status.py): the class's one tuple of plain
    # functions, so an instance holds no bound method for them (only a reference to this)
    SLICES = (_start, _gradient, _update)
