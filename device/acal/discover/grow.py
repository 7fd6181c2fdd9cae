# A discovering board's bins grown to a composed model's points when it adopts an effect
# (Pipeline.adopt; docs/model-discovery.md "Points for a composed model"): from the base model's
# points per subset (profile.WEAR_MAX_COUNT) to the composed model's (profile.adopted_max_count),
# in place, allocating nothing.
#
# The room is there from boot (the App preallocates): a discovering Pipeline's bins have the
# composed model's slots (Bins' room) and its fit points and fits take its points, while the bins
# hold the base model's until the adoption.  Grown at the adoption instead, the arrays fragmented
# the heap of a board hours into a recording and could fail there (docs/model-discovery.md
# "Points for a composed model").
from acal.core.bins import COND, N_SUBSETS


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
