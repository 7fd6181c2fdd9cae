# The paper profile's objective (model.objective, Farago 2024 eq. 12 without the square root) and
# its gradient step's quotient, exactly, in small ints: the same integers as the long-int formula
#   a = floor(K v / 2**20) (Q28 g), r = floor((|a|^2 - 2**56) / 2**26) (Q30 g^2),
#   f = sum of floor(r^2 / 2**20) (Q40 g^4),
# which on a 32-bit board needs ints to ~2**62 (heap-allocated longs there).  Here every value is
# kept as limbs of 14 bits, low first, the top limb signed (floor semantics: x >> 14 and
# x & 0x3FFF split any int), so that a sum of three limb products stays below 2**30.  Both
# functions are viper on ports with emitters (acal/emit.py; w: emit.SIGN_SHIFT).
#
# Domain (checked here; outside it objective_limbs returns a non-zero code and model.objective
# takes the long-int formula instead): parameters in the fit region (fixed.py) widened by the
# gradient's step H_PARAM, points |u| < 2**28 in Q24 (16 g per axis: every rest mean a LIS3DH can
# give at any full scale, |sample| <= SAMPLE_MAX), at most MAX_POINTS points.  Inside it, at the
# worst corner: v = u + o < 2**28.05, the products' middle sums < 2**29.8, |a| < 49.5 g
# (2**33.7), r < 2**42.4 (its top limb < 2**14.4), r^2's middle limb < 2**29.9 and the sums'
# top limb < 2**29.7 (tests/test_ranges.py traces them).
from acal.emit import viper, ptr32

LIMBS = 4            # an objective: 4 limbs of 14 bits, the top one signed (< 2**30)
MAX_POINTS = 128     # the sums' top limb: 128 terms of < 2**22.7
QUOTIENT_MAX = 134217728   # 2**27: a step this large leaves the fit region (optimiser.py)


@viper
def objective_limbs(u, n: int, out, at: int, kxx: int, kyy: int, kzz: int, kxy: int, kxz: int,
                    kyz: int, ox: int, oy: int, oz: int, w: int) -> int:
    """The objective of the n points u (Q24 g, flat x y z, an int32 array) at the parameters
    kxx .. oz (Q24) into out[at:at+LIMBS]; 0, or 1 for parameters and 2 for points outside the
    domain (out then untouched)."""
    # the fit region (fixed.FIT_*) widened by H_PARAM = 128
    if kxx < 8388480 or kxx > 33554560 or kyy < 8388480 or kyy > 33554560 or \
            kzz < 8388480 or kzz > 33554560:
        return 1
    if kxy < -8388736 or kxy > 8388736 or kxz < -8388736 or kxz > 8388736 or \
            kyz < -8388736 or kyz > 8388736:
        return 1
    if ox < -8388736 or ox > 8388736 or oy < -8388736 or oy > 8388736 or \
            oz < -8388736 or oz > 8388736 or n < 0 or n > 128:
        return 1
    p = ptr32(u)
    o = ptr32(out)
    xx1 = kxx >> 14
    xx0 = kxx & 16383
    yy1 = kyy >> 14
    yy0 = kyy & 16383
    zz1 = kzz >> 14
    zz0 = kzz & 16383
    xy1 = kxy >> 14
    xy0 = kxy & 16383
    xz1 = kxz >> 14
    xz0 = kxz & 16383
    yz1 = kyz >> 14
    yz0 = kyz & 16383
    s0 = 0
    s1 = 0
    s2 = 0
    s3 = 0
    i = 0
    end = 3 * n
    while i < end:
        vx = int(p[i]) << w >> w
        vy = int(p[i + 1]) << w >> w
        vz = int(p[i + 2]) << w >> w
        if vx < -268435456 or vx >= 268435456 or vy < -268435456 or vy >= 268435456 or \
                vz < -268435456 or vz >= 268435456:
            return 2
        vx += ox
        vy += oy
        vz += oz
        x1 = vx >> 14
        x0 = vx & 16383
        y1 = vy >> 14
        y0 = vy & 16383
        z1 = vz >> 14
        z0 = vz & 16383
        # a = floor(S / 2**20) for S = sum k v = h 2**28 + m 2**14 + l:
        #   floor(S / 2**14) = h 2**14 + m + (l >> 14), then >> 6; a = a2 2**28 + a1 2**14 + a0
        h = xx1 * x1
        m = xx1 * x0 + xx0 * x1 + ((xx0 * x0) >> 14)
        t = ((h & 63) << 8) + (m >> 6)
        c = (h >> 6) + (t >> 14)
        ax0 = t & 16383
        ax1 = c & 16383
        ax2 = c >> 14
        h = xy1 * x1 + yy1 * y1
        m = xy1 * x0 + xy0 * x1 + yy1 * y0 + yy0 * y1 + ((xy0 * x0 + yy0 * y0) >> 14)
        t = ((h & 63) << 8) + (m >> 6)
        c = (h >> 6) + (t >> 14)
        ay0 = t & 16383
        ay1 = c & 16383
        ay2 = c >> 14
        h = xz1 * x1 + yz1 * y1 + zz1 * z1
        m = xz1 * x0 + xz0 * x1 + yz1 * y0 + yz0 * y1 + zz1 * z0 + zz0 * z1 + \
            ((xz0 * x0 + yz0 * y0 + zz0 * z0) >> 14)
        t = ((h & 63) << 8) + (m >> 6)
        c = (h >> 6) + (t >> 14)
        az0 = t & 16383
        az1 = c & 16383
        az2 = c >> 14
        # |a|^2 - 2**56 = e0 + 2 e1 2**14 + e2 2**28 + e3 2**42 + e4 2**56
        e0 = ax0 * ax0 + ay0 * ay0 + az0 * az0
        e1 = ax1 * ax0 + ay1 * ay0 + az1 * az0
        e2 = ax1 * ax1 + ay1 * ay1 + az1 * az1 + ((ax2 * ax0 + ay2 * ay0 + az2 * az0) << 1)
        e3 = (ax2 * ax1 + ay2 * ay1 + az2 * az1) << 1
        e4 = ax2 * ax2 + ay2 * ay2 + az2 * az2 - 1
        # floor(/ 2**14), carried into 14-bit limbs, then r = that >> 12 = r2 2**28 + r1 2**14 + r0
        t = ((e1 & 16383) << 1) + (e0 >> 14)
        e2 += ((e1 >> 14) << 1) + (t >> 14)
        e3 += e2 >> 14
        e4 += e3 >> 14
        r0 = ((t & 16383) >> 12) + ((e2 & 4095) << 2)
        r1 = ((e2 & 16383) >> 12) + ((e3 & 4095) << 2)
        r2 = ((e3 & 16383) >> 12) + (e4 << 2)
        # r^2 = f0 + f1 2**14 + f2 2**28 + f3 2**42 + f4 2**56; its floor / 2**20 (>> 14, >> 6)
        f0 = r0 * r0
        t = ((r1 * r0) << 1) + (f0 >> 14)
        f2 = r1 * r1 + ((r2 * r0) << 1) + (t >> 14)
        f3 = ((r2 * r1) << 1) + (f2 >> 14)
        f4 = r2 * r2 + (f3 >> 14)
        s0 += ((t & 16383) >> 6) + ((f2 & 63) << 8)
        s1 += ((f2 & 16383) >> 6) + ((f3 & 63) << 8)
        s2 += ((f3 & 16383) >> 6) + ((f4 & 63) << 8)
        s3 += f4 >> 6
        i += 3
    s1 += s0 >> 14
    s2 += s1 >> 14
    s3 += s2 >> 14
    o[at] = s0 & 16383
    o[at + 1] = s1 & 16383
    o[at + 2] = s2 & 16383
    o[at + 3] = s3
    return 0


@viper
def quotient(f, at: int, base: int, m: int, den: int, w: int) -> int:
    """floor(m (F_at - F_base) / den) for two objectives in limbs (f[at:at+4], f[base:base+4]),
    0 <= m < 2**10 and 0 < den < 2**15: exact when its magnitude is below QUOTIENT_MAX, else
    +-QUOTIENT_MAX with its sign."""
    a = ptr32(f)
    d0 = (int(a[at]) << w >> w) - (int(a[base]) << w >> w)
    d1 = (int(a[at + 1]) << w >> w) - (int(a[base + 1]) << w >> w) + (d0 >> 14)
    d2 = (int(a[at + 2]) << w >> w) - (int(a[base + 2]) << w >> w) + (d1 >> 14)
    d3 = (int(a[at + 3]) << w >> w) - (int(a[base + 3]) << w >> w) + (d2 >> 14)
    if m == 0:
        return 0
    # D = q den + r, long division from the top limb (remainders < den, so r 2**14 < 2**29);
    # then floor(m D / den) = m q + floor(m r / den)
    q3 = d3 // den
    r = d3 - q3 * den
    c = (r << 14) + (d2 & 16383)
    q2 = c // den
    r = c - q2 * den
    c = (r << 14) + (d1 & 16383)
    q1 = c // den
    r = c - q1 * den
    c = (r << 14) + (d0 & 16383)
    q0 = c // den
    r = c - q0 * den
    if q3 == 0 and q2 == 0:
        q = (q1 << 14) + q0
    elif q3 == -1 and q2 == 16383:
        q = ((q1 - 16384) << 14) + q0
    elif q3 < 0:
        return -134217728
    else:
        return 134217728
    lim = 134217728 // m
    if q >= lim:
        return 134217728
    if q <= -lim:
        return -134217728
    return m * q + (m * r) // den
