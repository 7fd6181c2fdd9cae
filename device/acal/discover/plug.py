# Discovery plugged into the core pipeline (acal/core/pipeline.py; docs/model-discovery.md
# "Discovery on the board"): the one module of acal.discover the pipeline imports, and only when
# made with discover=True.  attach() gives it its held-out set and its Discover; its
# leave_early() and adopt() hand over to the functions of those names here, beside the
# discovery they serve.  Nothing here is allocated per point or per step.
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
from acal.core.bins import COND, N_SUBSETS
from acal.discover.heldout import HeldOut
from acal.discover.search import Discover, more


def attach(pipe, capacity):
    """A pipeline made with discover=True: its held-out set (pipe.held), its Discover sized for
    capacity fit points (pipe.discovery), its bins ready without their spreads (the discovery
    judges the spreads of its candidates itself)."""
    pipe.bins.need_span = False
    pipe.held = HeldOut()
    pipe.discovery = Discover(capacity, pipe.held)


def leave_early(pipe):
    """Pipeline.leave_early: the held-out blocks' points leave the bins, and from now on go to
    the held-out set only."""
    pipe.early = False
    held = pipe.held
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


def adopt(pipe):
    """Pipeline.adopt: the discovery's adopted effect becomes the pipeline's model."""
    from acal.core.pipeline import track
    d = pipe.discovery
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
    pipe.wait = kinds if again else None
    if not again:
        pipe.held = None
        pipe.discovery = None
    grow_bins(b, pipe.adopted_count)


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
