# The coverage rule's hemisphere test, in integers: are the held points all on one side of (or
# on) a plane through 0 g?  Then the sphere's far side is unseen and a fit's centre is an
# extrapolation: the float methods refuse such points (host methods.coverage_reason, the same
# rule decided by a linear programme there), and the wear profile's bins are not ready on them.
# If such a plane exists and the points span space, one touches two of the points (an extreme
# ray of the cone of its normals has two independent points on its plane), so the normals to
# try are the cross products of pairs: one with no point on its negative side, or none on its
# positive side, is such a plane.  A pair's test stops at the first point on each side, so
# covering points cost about n^2 / 2 short scans; and points that are not one-sided stay so
# with more added, so held(), for the bins, asks the first point of each group before all.
# Points are Q16 g (|v| <= 1.5 g, the bins' gate), taken at Q8 (SHIFT; 4 mg steps) so that
# a cross product is < 2 * 384^2 and its dot with a point < 3.4e8 < 2^30.
SHIFT = 8


def held(xyz, counts, m):
    """True when the held points lie on one side of a plane through 0 g (or on it): xyz holds
    (x, y, z) Q16 triples in groups of m slots, group s holding counts[s] points (the bins'
    layout).  The first point of each group decides when they already cover."""
    return one_sided(xyz, counts, m, 1) and one_sided(xyz, counts, m, m)


def one_sided(xyz, counts, m, per):
    """True when the points lie on one side of a plane through 0 g (or on it): the first `per`
    of each group's counts[s] points, in xyz's groups of m slots (a plain array of n points:
    counts=[n], m=per=n)."""
    groups = len(counts)
    for si in range(groups):
        for ki in range(min(counts[si], per)):
            i = 3 * (si * m + ki)
            ax = xyz[i] >> SHIFT
            ay = xyz[i + 1] >> SHIFT
            az = xyz[i + 2] >> SHIFT
            for sj in range(si, groups):
                for kj in range(ki + 1 if sj == si else 0, min(counts[sj], per)):
                    j = 3 * (sj * m + kj)
                    bx = xyz[j] >> SHIFT
                    by = xyz[j + 1] >> SHIFT
                    bz = xyz[j + 2] >> SHIFT
                    nx = ay * bz - az * by
                    ny = az * bx - ax * bz
                    nz = ax * by - ay * bx
                    if (nx or ny or nz) and _all_one_side(xyz, counts, m, per, nx, ny, nz):
                        return True
    return False


def _all_one_side(xyz, counts, m, per, nx, ny, nz):
    # True when no two of the points lie strictly on opposite sides of the plane with normal n.
    pos = False
    neg = False
    for s in range(len(counts)):
        for k in range(min(counts[s], per)):
            i = 3 * (s * m + k)
            d = nx * (xyz[i] >> SHIFT) + ny * (xyz[i + 1] >> SHIFT) + nz * (xyz[i + 2] >> SHIFT)
            if d > 0:
                pos = True
            elif d < 0:
                neg = True
            if pos and neg:
                return False
    return True
