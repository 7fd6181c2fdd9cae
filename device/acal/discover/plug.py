# Discovery plugged into the core pipeline (acal/core/pipeline.py; docs/model-discovery.md
# "Discovery on the board"): the one module of acal.discover the pipeline and the Processor
# load, and only on a discovering board (Pipeline(..., plug=Plug())).  The Plug holds every
# piece of the discovery's state (its held-out set, its Discover, the early bins, the spread
# the bins wait for after an adoption); the pipeline holds the Plug and calls it at four named
# points (room, attach, offer, ready), the feeder after each usable fit (fitted, then step
# until the choice, then adopt).  Nothing here is allocated per point or per step.
#
# At the adoption a discovering board's bins grow to a composed model's points (grow_bins; docs/
# model-discovery.md "Points for a composed model"): from the base model's points per subset
# (profile.WEAR_MAX_COUNT) to the composed model's (profile.adopted_max_count), in place.  The
# room is there from boot (the App preallocates): a discovering Pipeline's bins have the
# composed model's slots (Bins' room) and its fit points and fits take its points, while the bins
# hold the base model's until the adoption.  Grown at the adoption instead, the arrays fragmented
# the heap of a board hours into a recording and could fail there.
# Formats as the pipeline's: points Q16 g, conditions as bins.py (COND a point).
from acal.core import effects
from acal.core.bins import COND, N_SUBSETS, gravity
from acal.core.fixed import C_TIME
from acal.core.pipeline import spanned, track
from acal.core.profile import NEWTON, adopted_max_count
from acal.discover.heldout import HeldOut
from acal.discover.search import Discover, more


class Plug:
    """The board's own discovery, plugged into a Pipeline (acal/core/pipeline.py).

    early: the bins also take the held-out blocks' rest means until the first calibration
    (leave_early() ends it): held out from the start, a wearer's bins filled 29 h later
    (docs/model-discovery.md "Discovery on the board"); the Processor starts with it True.
    After a usable fit, fitted(pipe) starts the discovery (running), step() runs it a slice at
    a time, adopt(pipe) makes its adopted effect the pipeline's model.  held: the held-out set
    (heldout.py), discovery: the Discover (search.py); both None once no discovery remains."""

    def __init__(self, early=False):
        self.early = early
        self.held = None
        self.discovery = None
        self.running = False   # a discovery begun and not yet chosen
        self.count = 0         # points per subset once an effect is adopted (room())
        # the adopted effects, whose spread alone the bins wait for (the bins track every
        # condition for the next round: adopt()); None: the bins' own rule
        self.wait = None
        self.wait_at = -1
        self.wait_ok = False

    def room(self, kinds, fit, max_count):
        """Points per subset the pipeline makes room for: a composed model's
        (profile.adopted_max_count), for which the bins, the fit points and the fits have room
        from the start."""
        if kinds or fit != NEWTON:
            raise ValueError("discovery starts from the paper's model with the wear fit (NEWTON)")
        self.count = adopted_max_count(fit, max_count)
        return self.count

    def attach(self, pipe, capacity):
        """The pipeline made: its bins track every condition a candidate needs and are ready
        without their spreads (the discovery judges its candidates' spreads itself); the
        held-out set and the Discover sized for capacity fit points."""
        track(pipe.bins, (), True)
        pipe.bins.need_span = False
        self.held = HeldOut()
        self.discovery = Discover(capacity, self.held)

    def offer(self, pipe, x, y, z):
        """A rest mean (Q16 g) at the conditions pipe.now: a held-out block's goes to the held-out
        set (and to the bins too while early); True when the bins take it."""
        held = self.held
        c = pipe.now
        if held is None or not held.takes(c[C_TIME]):
            return True
        if gravity(x, y, z):
            held.offer(x, y, z, c)
        return self.early

    def ready(self, b):
        """The bins b are ready by their own rule: True unless an adopted model's effects'
        spread is still missing (asked once a block: spans only when the points change)."""
        if self.wait is None:
            return True
        if self.wait_at != b.changes:
            self.wait_at = b.changes
            self.wait_ok = spanned(b, self.wait)
        return self.wait_ok

    def fitted(self, pipe):
        """A usable calibration has ended: the first one's held-out points leave the bins;
        after a later one the discovery begins (True: step() until it has chosen)."""
        if self.early:
            self.leave_early(pipe)
        elif self.discovery is not None:
            self.discovery.begin(pipe)
            self.running = True
        return self.running

    def step(self):
        """One slice of the discovery; True when it has chosen (discovery.chosen, adopted)."""
        if self.discovery.step():
            self.running = False
            return True
        return False

    def leave_early(self, pipe):
        """The first calibration has ended: the held-out blocks' points leave the bins (the
        next fit, the discovery's, never sees a point the held-out set may hold), and from now
        on go to the held-out set only."""
        self.early = False
        held = self.held
        b = pipe.bins
        m = b.max_count
        for s in range(N_SUBSETS):
            k = 0
            while k < b.counts[s]:
                j = s * m + k
                if held.takes(b.cond[COND * j + 1]):
                    b.remove(b.xyz[3 * j], b.xyz[3 * j + 1], b.xyz[3 * j + 2])
                else:
                    k += 1

    def adopt(self, pipe):
        """The discovery's adopted effect becomes the model (its fit, re-kinded, the pipeline's
        optimiser; the paper's fit stays its base fit; the bins then wait for the spread of
        that model's effects only, and track every condition while the discovery goes on: a
        second round judges its candidates testable on the fit points' spread, as the first);
        the parameters are the discovery's.  While the model has room for another effect
        (search.more) the discovery goes on after each calibration, from this model; else the
        plug leaves the pipeline (pipe.plug None: the held-out blocks' rest means go to the
        bins again).  The bins grow to `count` points per subset (a composed model's: the next
        calibration fits on up to 126), every held point and its conditions kept, in the room
        they have (nothing allocated)."""
        d = self.discovery
        fit = d.take()
        kinds = fit.kinds
        if not pipe.kinds:
            pipe.base_fit = pipe.optimiser
        pipe.optimiser = fit
        pipe.kinds = kinds
        pipe.base_kinds = ()
        pipe.start = [0] * fit.n_params
        pipe.step_time = d.step_time
        if effects.STEP in kinds:
            pipe.search = d.search
        again = more(kinds)
        b = pipe.bins
        track(b, kinds, again)   # going on: every condition, for the next round's candidates
        b.need_span = not again
        b.changes += 1
        self.wait = kinds if again else None
        if not again:
            self.held = None
            self.discovery = None
            pipe.plug = None
        grow_bins(b, self.count)


def grow_bins(b, max_count):
    """Bins b (acal/core/bins.py, made with room for max_count points per subset) made to hold up to
    max_count: every held point and its conditions kept in its subset and slot (slot k of subset
    s moves from s * m + k to s * max_count + k), nothing else changed."""
    m = b.max_count
    if max_count <= m:
        return
    if len(b.xyz) < 3 * N_SUBSETS * max_count:
        raise ValueError("the bins have no room for that many points")
    xyz = b.xyz
    cond = b.cond
    # from the last slot of the last subset down: a slot only moves up, onto slots already moved
    # or never used (subset 0 stays where it is)
    for s in range(N_SUBSETS - 1, 0, -1):
        for k in range(b.counts[s] - 1, -1, -1):
            i = 3 * (s * m + k)
            j = 3 * (s * max_count + k)
            xyz[j] = xyz[i]
            xyz[j + 1] = xyz[i + 1]
            xyz[j + 2] = xyz[i + 2]
            i = COND * (s * m + k)
            j = COND * (s * max_count + k)
            for c in range(COND):
                cond[j + c] = cond[i + c]
    b.max_count = max_count
    b.changes += 1   # ready()'s cache: the same points, but asked again
