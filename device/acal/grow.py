# Room for a composed model's points, made when a discovering board adopts an effect
# (Pipeline.adopt; docs/model-discovery.md "Points for a composed model"): its bins, its fit
# points and the fits that take them were sized for the base model's points per subset
# (profile.WEAR_MAX_COUNT) and grow to the composed model's (profile.adopted_max_count), once.
#
# Each int32 array grows by extend, in place: MicroPython's realloc (py/gc.c gc_realloc) lengthens
# the block where it lies when the blocks after it are free, and otherwise moves it and frees the
# old block at once, so the collector is left nothing but the small zeroed array each extend reads;
# a new array filled from the old one would hold both until a collection.  The array objects stay
# the same, so whatever holds one (a change-point search holding a fit's sort buffer) still
# does.  Only a discovering board imports this module.
from acal.bins import COND, N_SUBSETS, int32s


def extend(a, n):
    """n zeroed slots more at the end of the int32 array a; its values kept."""
    a.extend(int32s(n))


def grow_bins(b, max_count):
    """Bins b (acal/bins.py) made to hold up to max_count points per subset: every held point
    and its conditions kept in its subset and slot (slot k of subset s moves from s * m + k to
    s * max_count + k), nothing else changed."""
    m = b.max_count
    if max_count <= m:
        return
    extend(b.xyz, 3 * N_SUBSETS * (max_count - m))
    extend(b.cond, COND * N_SUBSETS * (max_count - m))
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


def grow_fit(fit, max_points):
    """A GaussNewton (acal/gaussnewton.py) made to take up to max_points points: its per-point
    buffers lengthened, its parameters and last fit's results kept."""
    n = max_points - fit.max_points
    if n <= 0:
        return
    extend(fit.u, 3 * n)
    extend(fit.aux, COND * n)
    extend(fit.index, n)
    extend(fit.keep, n)
    extend(fit.r, n)
    extend(fit.rt, n)
    extend(fit.srt, n)
    fit.max_points = max_points
