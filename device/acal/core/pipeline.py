# The calibration pipeline: samples -> rest detection -> bins -> optimiser.
# One object, allocated once; the app feeds it FIFO reads, the host feeds it recordings.
from acal.core.rest import RestDetector, DEFAULT_SECONDS, DEFAULT_THRESHOLD
from acal.core.bins import (Bins, CENTRE, COND, DEFAULT_DIFFER, DIFFERS, N_SUBSETS,
                            conditions, int32s)
from acal.core.status import OK, BASE_KEPT_FAILED, BASE_KEPT_WORSE
from acal.core.fixed import N_PARAMS
from acal.core.gaussnewton import GaussNewton
from acal.core import gaussnewton
from acal.core.fixed import ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET
from acal.core.profile import GRADIENT, NEWTON
from acal.core import effects
from acal.core.status import Sliced

# the fit's phases: their slices' places in the table (acal/core/status.py; _DONE their count)
_BASE = 0       # the base fit (a composed model's, NEWTON), a slice a step
_MODEL = 1      # the model's own fit, a slice a step
_BASE_END = 2   # the base fit ended: a step's search begun, or the model's own fit
_SEARCH = 3     # a step's change-point search on the base fit
_LOAD = 4       # the model's own fit loading its points
_CENTRE = 5     # a composed model's points' conditions centred
_BEGIN = 6      # the optimiser (or the base fit) begun on the gathered points
_DONE = 7
_reference = None   # acal/core/reference.py once a composed or discovering Pipeline is made


class Pipeline(Sliced):
    """rate_hz, seconds, threshold (Q10 g or rest.AUTO), axis (or rest.ALL_AXES): rest
    detection; min_count, max_count, differ (Q16 g), policy: bins; fit (profile.GRADIENT: the
    paper's, with iterations and alphas, learning rates in tenths; profile.NEWTON: Gauss-Newton
    with outlier rejection, and bins that are also ready on coverage): the optimiser.  A
    profile's settings: acal.core.profile.settings().

    on_rest, if given, is called as on_rest(x, y, z, subset) for every rest mean (Q16 g), with
    the subset it was kept in or -1 (the app logs these; the host collects them).

    kinds: the effects of a composed model (acal.core.effects ids; () is the paper's model).  Their
    bins track temperature, time and the board's supply (bins.py), and the feeder keeps the
    conditions `now` current (below); a fit takes each point's conditions relative to the
    middle of the held points' ranges (`ref`, now's columns), which the calibration keeps.  iterations None: 50 for the
    paper's model, 200 for a composed one (50 leave the effect terms under-converged); with
    NEWTON at most gaussnewton.DEFAULT_ITERATIONS steps per round (it stops when converged).

    A model with a step (effects.STEP; NEWTON only): the model without the step is fitted
    first, acal/core/changepoint.py finds the step's time on its residuals (step_time, 64 s units
    from ref[C_TIME], which the calibration keeps), and the whole model is fitted from there.

    The fit is sliced: begin_fit() then fit_step() until it returns True (the app does one step
    between FIFO reads), or calibrate() at once; the same integers either way.

    worn: the feeder's wear signal.  A rest segment that closes while it is False (a device off
    the wrist, on a table; imputed or idle-sleep stretches) is counted in `excluded` but not
    offered: it is still, but not what the wearer's data looks like.  The app leaves it True;
    the host sets it from its non-wear and quality masks.

    plug: None, or what plugs in around the fit (acal/discover/plug.py's Plug: the board's own
    discovery of its missing effect; docs/model-discovery.md "Discovery on the board").  The
    pipeline holds nothing of it but this reference and calls it at four named points: room()
    (the points per subset its bins and fits make room for), attach() (once, the pipeline
    made), offer() (each rest mean: True when the bins take it too) and ready() (once the
    bins' own rule is met: True when the plug's is too).  After a fit the feeder hands the
    plug the pipeline (Plug.fitted).

    now: the conditions the rest means are seen at (bins.conditions(1): C_TEMP Q2 degC, C_TIME
    64 s units, C_SUPPLY mV), the feeder's own array, which it keeps current (the Processor's
    `now`); None: a zeroed one of the pipeline's own."""

    def __init__(self, rate_hz=100, seconds=DEFAULT_SECONDS, threshold=DEFAULT_THRESHOLD, axis=0,
                 min_count=2, max_count=2, differ=DEFAULT_DIFFER, policy=CENTRE,
                 iterations=None, on_rest=None,
                 alphas=(ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET), kinds=(), fit=GRADIENT,
                 plug=None, now=None):
        self.kinds = tuple(kinds)
        self.fit = fit
        self.rest = RestDetector(rate_hz, seconds, threshold, axis)
        base_kinds = []
        for k in self.kinds:
            if k != effects.STEP:
                base_kinds.append(k)
        # points per subset the bins and the fits have room for (a plug's may be more)
        room = max_count if plug is None else plug.room(self.kinds, fit, max_count)
        capacity = N_SUBSETS * room   # points the fits take
        self.bins = Bins(min_count, max_count, differ, policy, coverage=fit == NEWTON,
                         room=room)
        # the spread each effect's regressor needs in the held points
        track(self.bins, self.kinds)
        self.plug = plug
        self.base_fit = None
        self.search = None
        self.step_time = 0
        # the base fit: the paper's model, or for a model with a step the model without it
        self.base_kinds = tuple(base_kinds) if len(base_kinds) < len(self.kinds) else ()
        if fit == NEWTON:
            self.optimiser = GaussNewton(capacity, self.kinds, True)
            if self.kinds:  # the base fit of the same points: kept when the composed one fails;
                # before a step's search without outlier rejection: the points after a shock are
                # the outliers of the model without the step, the search's evidence (issue 50
                # part 5: once the rest means lost the Q10 rounding's bias, a smaller median
                # residual let the rejection drop them, and the step was placed 3.7 h late)
                self.base_fit = GaussNewton(capacity, self.base_kinds,
                                            len(base_kinds) >= len(self.kinds))
                self.start = [0] * (N_PARAMS + 3 * len(self.kinds))
            if len(base_kinds) < len(self.kinds):
                from acal.core.changepoint import ChangePoint   # a step's models only
                self.search = ChangePoint()
        elif len(base_kinds) < len(self.kinds):
            raise ValueError("a step is found by the wear profile's fit (NEWTON)")
        else:
            # the paper's gradient descent, imported here: a wear-profile board never loads it
            # (nor acal/paper/objective.py), whose code would sit in its RAM
            from acal.paper import optimiser
            self.optimiser = optimiser.Optimiser(capacity, alphas, self.kinds)
            if iterations is None:
                iterations = (optimiser.COMPOSED_ITERATIONS if self.kinds
                              else optimiser.DEFAULT_ITERATIONS)
        if iterations is None:
            iterations = gaussnewton.DEFAULT_ITERATIONS
        self.iterations = iterations
        self.points = int32s(3 * capacity)
        self.aux = conditions(capacity)  # dT, dt, dV per point (composed models)
        if self.kinds or plug is not None:   # the fit's references (_centre), imported here:
            global _reference                # the base model's board never loads the module
            from acal.core import reference  # (a module global: an instance attribute more
            _reference = reference           # took Pipeline's table from 23 slots to 29)
        # the conditions now (bins.conditions(1): C_TEMP, C_TIME, C_SUPPLY), shared with the feeder
        self.now = conditions(1) if now is None else now
        self.ref = conditions(1)   # a composed fit's references, now's columns (_centre)
        self.on_rest = on_rest
        self.rest_count = 0
        self.worn = True
        self.excluded = 0
        self.position = 0  # samples of the current add_samples call consumed so far
        # the fit's phases (_BASE ... above), in their order
        self.sliced()
        self.from_base = False   # the model's own fit starts from the base fit's parameters
        self.n_fit = 0     # points gathered for the fit
        if plug is not None:
            plug.attach(self, capacity)

    def offer(self, x, y, z):
        """A rest mean (Q16 g), seen at the conditions self.now -> bins; returns the subset it was
        kept in or -1."""
        self.rest_count += 1
        plug = self.plug
        if plug is None or plug.offer(self, x, y, z):
            c = self.now
            s = self.bins.offer(x, y, z, c)
        else:
            s = -1
        if self.on_rest is not None:
            self.on_rest(x, y, z, s)
        return s

    def add_samples(self, buf, start, n):
        """Feed n interleaved samples (Q10 g) from sample index start."""
        rest = self.rest
        while n > 0:
            used = rest.add_samples(buf, start, n)
            start += used
            n -= used
            self.position = start
            if rest.ended:
                rest.ended = False
                if rest.still:
                    if self.worn:
                        self.offer(rest.mean_x, rest.mean_y, rest.mean_z)
                    else:
                        self.excluded += 1

    def ready(self):
        b = self.bins
        if not b.ready():
            return False
        return self.plug is None or self.plug.ready(b)

    def calibrate(self):
        """Run the optimiser on the held points; returns its status (optimiser.OK, ...).
        The parameters are in self.optimiser.p (Q24; 9, then 3 per effect)."""
        self.begin_fit()
        self.finish()
        return self.optimiser.status

    def begin_fit(self):
        """Gather the held points (the fit's own copy: the bins go on taking points while it
        runs); the rest of the fit's start runs in fit_step's slices (docs/method-and-formats.md
        "Sliced fit"): a composed model's points' dT, dt, dV centred on the middle of their
        ranges (_CENTRE), then the optimiser started on them (_BEGIN; a composed model with
        the wear profile's fit: the base fit of the same points first)."""
        self.step_time = 0
        if self._bare():
            self.n_fit = self.bins.gather(self.points)
            self.phase = _BEGIN
        else:
            self.n_fit = self.bins.gather(self.points, self.aux)
            self.phase = _CENTRE

    def _bare(self):
        # the base model, no plug: its fit takes no conditions (no aux, no centring)
        return not self.kinds and self.plug is None

    def _centre(self):
        # the references, column by column into self.ref, and each point's conditions
        # relative to them
        aux = self.aux
        n = self.n_fit
        kinds = self.kinds
        r = _reference
        for c in range(COND):
            self.ref[c] = r.centre(aux, n, c, r.lowest(kinds, c), COND)
        self.phase = _BEGIN

    def _begin(self):
        # the optimiser (or the base fit) started on the gathered points
        if self._bare():
            self.phase = _MODEL
            self.optimiser.begin(self.points, self.n_fit, self.iterations)
        elif self.base_fit is not None:
            self.phase = _BASE
            self.base_fit.begin(self.points, self.n_fit, self.iterations, self.aux)
        else:
            self.phase = _MODEL
            self.optimiser.begin(self.points, self.n_fit, self.iterations, self.aux)

    def fit_step(self):
        """One slice of the fit; True when it has ended (the status is the optimiser's).  The
        points the fit rejected as outliers leave the bins then (by value: the bins may have
        taken or replaced points while the fit ran on its own copy).  A composed model whose
        fit failed or ended worse than the base fit keeps the base fit's parameters (effects
        zero) with status BASE_KEPT_FAILED or BASE_KEPT_WORSE."""
        if self.phase == _MODEL:   # the optimiser's own slices, nearly all: its step at once
            if not self.optimiser.step():   # (through _model, a call more: 25 us a slice on
                return False                # the emulated Pico, docs/notes/boards-and-logs.md)
            self._model_ended()
            return True
        return self.step()

    def _model(self):
        if self.optimiser.step():
            self._model_ended()

    def _model_ended(self):
        self._ended()
        self.phase = _DONE

    def _base(self):
        if self.base_fit.step():
            self.phase = _BASE_END   # the model's own fit begins in a slice of its own

    def _base_end(self):
        b = self.base_fit
        if self.search is not None:
            if b.status != OK:   # nothing to search the step on
                self._keep_base(b.status)
                return
            self.search.begin(b)
            self.phase = _SEARCH
            return
        self._begin_model(b.status == OK)

    def _load(self):
        self.phase = _MODEL
        self.optimiser.begin(self.points, self.n_fit, self.iterations, self.aux,
                             self.start if self.from_base else None)

    def _search(self):
        if not self.search.step():
            return
        if not self.search.found:   # no split pins a step: the model without it stays
            self._keep_base(BASE_KEPT_FAILED)
            return
        self.step_time = self.search.ts
        self._begin_model(True)

    def _ended(self):
        # the model's own fit has ended: the base fit's parameters kept if it did better, the
        # points it rejected out of the bins
        o = self.optimiser
        b = self.base_fit
        if b is not None and b.status == OK:
            if o.status != OK:
                self._keep_base(BASE_KEPT_FAILED)
            elif _mean_above(o.objective, o.n, b.objective, b.n):
                self._keep_base(BASE_KEPT_WORSE)
        if self.fit == NEWTON and o.rejected:
            pts = self.points
            for i in range(o.n_given):
                if not o.keep[i]:
                    self.bins.remove(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2])

    def _begin_model(self, from_base):
        # the model's own fit, from the base fit's parameters (the step's at zero); it loads its
        # points in the next slice (_LOAD): both in one slice took 2.2 ms on an RP2040 at 126
        # points, four effects (docs/method-and-formats.md "Sliced fit")
        b = self.base_fit
        self.phase = _LOAD
        self.from_base = from_base
        self.optimiser.ts = self.step_time
        if from_base:
            copy_params(b.p, self.base_kinds, self.start, self.kinds)

    def _keep_base(self, why):
        # the fit ends with the base fit's parameters
        self.phase = _DONE
        o = self.optimiser
        b = self.base_fit
        copy_params(b.p, self.base_kinds, o.p, self.kinds)
        o.n_given = b.n_given
        for i in range(o.n_given):
            o.keep[i] = b.keep[i]
        o.rejected = b.rejected
        o.n = b.n
        o.iterations = b.iterations
        o.objective = b.objective
        o.status = why

    # the phases' slices, in phase order (acal/core/status.py): the class's one tuple of plain
    # functions, so an instance holds no bound method for them (only a reference to this)
    SLICES = (_base, _model, _base_end, _search, _load, _centre, _begin)


def track(bins, kinds, every=False):
    """Set the bins' least differences (bins.py) to what the effects' regressors need (every:
    all three conditions, e.g. for a plug's candidates), and the spread weights with them
    (bins.set_differ)."""
    bins.set_differ([_needed(kinds, c, every) for c in range(COND)])


def _needed(kinds, c, every):
    # condition c's threshold (DIFFERS) when tracked: every, or an effect of kinds reads it
    # (effects.condition_of, as spanned and discover.testable ask); else 0
    if every:
        return DIFFERS[c]
    for k in kinds:
        if effects.condition_of(k) == c:
            return DIFFERS[c]
    return 0


def spanned(bins, kinds):
    """True when the bins' points span what each effect's regressor needs (track's thresholds;
    discover.testable asks the same of the fit points, through the same effects.condition_of
    and DIFFERS: only the points' storage differs)."""
    for k in kinds:
        c = effects.condition_of(k)
        if c >= 0 and bins.span(c) < DIFFERS[c]:
            return False
    return True


def _mean_above(f1, n1, f2, n2):
    # f1 / n1 > f2 / n2 (objectives, the mean over the points each kept), without a long:
    # both shifted alike to 22 bits, times n <= 128.
    s = 0
    while (f1 >> s) >= (1 << 22) or (f2 >> s) >= (1 << 22):
        s += 1
    return (f1 >> s) * n2 > (f2 >> s) * n1


def copy_params(src, src_kinds, dst, dst_kinds):
    """A fit's parameters (9, then 3 per effect of src_kinds) into a composed model's (dst_kinds):
    the nine, each effect both hold, and zero for the others (the step the search adds)."""
    for i in range(N_PARAMS):
        dst[i] = src[i]
    for k in range(len(dst_kinds)):
        j = -1
        for m in range(len(src_kinds)):
            if src_kinds[m] == dst_kinds[k]:
                j = m
        for c in range(3):
            dst[N_PARAMS + 3 * k + c] = src[N_PARAMS + 3 * j + c] if j >= 0 else 0
