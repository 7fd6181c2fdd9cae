# Room for a composed model's points, made when a discovering board adopts an effect
# (Pipeline.adopt; docs/model-discovery.md "Points for a composed model"): its bins, its fit
# points and the fits that take them were sized for the base model's points per subset
# (profile.WEAR_MAX_COUNT) and grow to the composed model's (profile.adopted_max_count), once.
#
# Each int32 array grows by extend, in place: MicroPython's realloc (py/gc.c gc_realloc) lengthens
# the block where it lies when the blocks after it are free, and otherwise moves it and frees the
# old block at once; a new array filled from the old one would hold both until a collection.  The
# slots added are copied from one zeroed array (`zeros`, read through a memoryview: no copy of
# it per array), so that the growth leaves the collector only that array.  The array objects stay
# the same, so whatever holds one (a change-point search holding a fit's sort buffer) still
# does.  Only a discovering board imports this module.
from acal.bins import COND, N_SUBSETS, int32s


def extend(a, n, zeros):
    """n zeroed slots more at the end of the int32 array a (its values kept), from the int32
    array zeros (at least n long, all 0)."""
    a.extend(memoryview(zeros)[:n])


def grow_bins(b, max_count, zeros=None):
    """Bins b (acal/bins.py) made to hold up to max_count points per subset: every held point
    and its conditions kept in its subset and slot (slot k of subset s moves from s * m + k to
    s * max_count + k), nothing else changed.  zeros: as extend's, for 3 slots a point added
    (None: made here)."""
    m = b.max_count
    if max_count <= m:
        return
    n = N_SUBSETS * (max_count - m)
    if zeros is None:
        zeros = int32s(3 * n)
    extend(b.xyz, 3 * n, zeros)
    extend(b.cond, COND * n, zeros)
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


def grow_fit(fit, max_points, zeros=None):
    """A GaussNewton (acal/gaussnewton.py) made to take up to max_points points: its per-point
    buffers lengthened, its parameters and last fit's results kept.  zeros: as grow_bins'."""
    n = max_points - fit.max_points
    if n <= 0:
        return
    if zeros is None:
        zeros = int32s(3 * n)
    extend(fit.u, 3 * n, zeros)
    extend(fit.aux, COND * n, zeros)
    extend(fit.index, n, zeros)
    extend(fit.keep, n, zeros)
    extend(fit.r, n, zeros)
    extend(fit.rt, n, zeros)
    extend(fit.srt, n, zeros)
    fit.max_points = max_points
