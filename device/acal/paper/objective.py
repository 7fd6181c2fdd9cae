# The paper profile's objective (model.objective, Farago 2024 eq. 12 without the square root) and
# its gradient step's quotient, exactly, in small ints: the same integers as the long-int formula
#   a = floor(K v / 2**20) (Q28 g), r = floor((|a|^2 - 2**56) / 2**26) (Q30 g^2),
#   f = sum of floor(r^2 / 2**20) (Q40 g^4),
# which on a 32-bit board needs ints to ~2**62 (heap-allocated longs there).  Here every value is
# kept as limbs of 14 bits, low first, the top limb signed (floor semantics: x >> 14 and
# x & 0x3FFF split any int), so that a sum of three limb products stays below 2**30.  Both
# functions are viper on ports with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
#
# Domain (checked here; outside it objective_limbs returns a non-zero code and model.objective
# takes the long-int formula instead): parameters in the fit region (fixed.py) widened by the
# gradient's step H_PARAM, points |u| < 2**28 in Q24 (16 g per axis: every rest mean a LIS3DH can
# give at any full scale, |sample| <= SAMPLE_MAX), at most MAX_POINTS points.  Inside it, at the
# worst corner: v = u + o < 2**28.05, the products' middle sums < 2**29.8, |a| < 49.5 g
# (2**33.7), r < 2**42.4 (its top limb < 2**14.4), r^2's middle limb < 2**29.9 and the sums'
# top limb < 2**29.7 (tests/device/test_ranges.py traces them).
#
# Two shortcuts give the same integers faster where the values are those of a real sensor:
# - |a| < 2 g on every axis: a is a small int; its halves of 15 bits (the low one in
#   [-2**14, 2**14)) give |a|^2 in three sums of three products, and when |a|^2 is within 1/4 g^2
#   of 1 g^2, r (< 2**28.1) and r^2 / 2**20 follow in a few products.
# - the gradient's objectives at p + h e_k (h = 2**7 in Q24): with a = floor(S / 2**20) and its
#   remainder rho = S mod 2**20 kept per point from the objective at p (CACHE per point), S
#   moves by 2**7 X (X a point's coordinate for a scale or misalignment, a K entry for an
#   offset), X = X1 2**14 + X0, so a moves by 2 X1 + floor((rho + X0 2**7) / 2**20): a few ops
#   per changed axis instead of the products.
from acal.core.emit import viper, ptr32

LIMBS = 4            # an objective: 4 limbs of 14 bits, the top one signed (< 2**30)
MAX_POINTS = 128     # the sums' top limb: 128 terms of < 2**22.7
QUOTIENT_MAX = 134217728   # 2**27: a step this large leaves the fit region (optimiser.py)
CACHE = 6            # per point: a_x, a_y, a_z (Q28) and their rho, or rho_x = -1: not kept
PLAIN = -2           # objective_limbs' mode: the objective at par
BASE = -1            #   the same, the cache filled
GRADIENT = 0         #   the 9 objectives at par + h e_j, from the cache


@viper
def objective_limbs(u, n: int, out, at: int, par, mode: int, cache, w: int) -> int:
    """The objective of the n points u (Q24 g, flat x y z, an int32 array) at the parameters
    par (Q24, an int32 array: kxx kyy kzz kxy kxz kyz ox oy oz) into out[at:at+LIMBS]; 0, or 1
    for parameters and 2 for points outside the domain (out then not meaningful).  mode:
    PLAIN; BASE (cache, CACHE ints a point, filled); GRADIENT: the objectives at par + h e_j,
    j = 0..8, into out[at + LIMBS j:], cache the BASE one at par."""
    q = ptr32(par)
    kxx = int(q[0]) << w >> w
    kyy = int(q[1]) << w >> w
    kzz = int(q[2]) << w >> w
    kxy = int(q[3]) << w >> w
    kxz = int(q[4]) << w >> w
    kyz = int(q[5]) << w >> w
    ox = int(q[6]) << w >> w
    oy = int(q[7]) << w >> w
    oz = int(q[8]) << w >> w
    # the fit region (fixed.FIT_*) widened by H_PARAM = 128, for every parameter set evaluated
    top = 0
    if mode == 0:
        top = 128
    if kxx < 8388480 or kxx > 33554560 - top or kyy < 8388480 or kyy > 33554560 - top or \
            kzz < 8388480 or kzz > 33554560 - top:
        return 1
    if kxy < -8388736 or kxy > 8388736 - top or kxz < -8388736 or kxz > 8388736 - top or \
            kyz < -8388736 or kyz > 8388736 - top:
        return 1
    if ox < -8388736 or ox > 8388736 - top or oy < -8388736 or oy > 8388736 - top or \
            oz < -8388736 or oz > 8388736 - top or n < 0 or n > 128 or mode < -2 or mode > 0:
        return 1
    p = ptr32(u)
    o = ptr32(out)
    cc = ptr32(cache)
    # a gradient's objective at p + h e_j, from the cache: for an offset j, every axis from j
    # down moves by its K entry in column j, X = X1 2**14 + X0, as 2 X1 + (rho + X0 2**7) >> 20
    kx1 = (kxx >> 14) << 1
    kx0 = (kxx & 16383) << 7
    ky1 = (kyy >> 14) << 1
    ky0 = (kyy & 16383) << 7
    kz1 = (kzz >> 14) << 1
    kz0 = (kzz & 16383) << 7
    xy1 = (kxy >> 14) << 1
    xy0 = (kxy & 16383) << 7
    xz1 = (kxz >> 14) << 1
    xz0 = (kxz & 16383) << 7
    yz1 = (kyz >> 14) << 1
    yz0 = (kyz & 16383) << 7
    kend = 0
    groups = 1
    if mode == 0:
        kend = 9
        groups = 9
    j = 0
    while j < groups * 4:
        o[at + j] = 0
        j += 1
    i = 0
    end = 3 * n
    while i < end:
        b = i << 1
        cached = 0
        if mode == 0 and int(cc[b + 3]) >= 0:
            cached = 1
            bx = int(cc[b]) << w >> w
            by = int(cc[b + 1]) << w >> w
            bz = int(cc[b + 2]) << w >> w
            rx = int(cc[b + 3])
            ry = int(cc[b + 4])
            rz = int(cc[b + 5])
            # for a K entry in column c: X is the point's coordinate c (plus its offset)
            v = (int(p[i]) << w >> w) + ox
            vx1 = (v >> 14) << 1
            vx0 = (v & 16383) << 7
            v = (int(p[i + 1]) << w >> w) + oy
            vy1 = (v >> 14) << 1
            vy0 = (v & 16383) << 7
            v = (int(p[i + 2]) << w >> w) + oz
            vz1 = (v >> 14) << 1
            vz0 = (v & 16383) << 7
        kk = -1             # PLAIN and BASE: once; GRADIENT: j = 0 .. 8
        if mode == 0:
            kk = 0
        while kk < kend:
            big = 0
            if cached:
                ax = bx
                ay = by
                az = bz
                if kk == 0:
                    ax += vx1 + ((rx + vx0) >> 20)
                elif kk == 1:
                    ay += vy1 + ((ry + vy0) >> 20)
                elif kk == 2:
                    az += vz1 + ((rz + vz0) >> 20)
                elif kk == 3:
                    ay += vx1 + ((ry + vx0) >> 20)
                elif kk == 4:
                    az += vx1 + ((rz + vx0) >> 20)
                elif kk == 5:
                    az += vy1 + ((rz + vy0) >> 20)
                elif kk == 6:
                    ax += kx1 + ((rx + kx0) >> 20)
                    ay += xy1 + ((ry + xy0) >> 20)
                    az += xz1 + ((rz + xz0) >> 20)
                elif kk == 7:
                    ay += ky1 + ((ry + ky0) >> 20)
                    az += yz1 + ((rz + yz0) >> 20)
                else:
                    az += kz1 + ((rz + kz0) >> 20)
            else:
                # the parameters evaluated (a gradient's: one of them plus h), in halves of 14 bits
                pxx = kxx
                pyy = kyy
                pzz = kzz
                pxy = kxy
                pxz = kxz
                pyz = kyz
                pox = ox
                poy = oy
                poz = oz
                if kk == 0:
                    pxx += 128
                elif kk == 1:
                    pyy += 128
                elif kk == 2:
                    pzz += 128
                elif kk == 3:
                    pxy += 128
                elif kk == 4:
                    pxz += 128
                elif kk == 5:
                    pyz += 128
                elif kk == 6:
                    pox += 128
                elif kk == 7:
                    poy += 128
                elif kk == 8:
                    poz += 128
                vx = int(p[i]) << w >> w
                vy = int(p[i + 1]) << w >> w
                vz = int(p[i + 2]) << w >> w
                if vx < -268435456 or vx >= 268435456 or vy < -268435456 or vy >= 268435456 or \
                        vz < -268435456 or vz >= 268435456:
                    return 2
                vx += pox
                vy += poy
                vz += poz
                x1 = vx >> 14
                x0 = vx & 16383
                y1 = vy >> 14
                y0 = vy & 16383
                z1 = vz >> 14
                z0 = vz & 16383
                # a = floor(S / 2**20) for S = sum k v = h 2**28 + m 2**14 + l:
                #   floor(S / 2**14) = h 2**14 + m + (l >> 14), then >> 6; a = c 2**14 + a0 (t its
                #   low part), rho = S mod 2**20
                k1 = pxx >> 14
                k0 = pxx & 16383
                h = k1 * x1
                e = k0 * x0
                m = k1 * x0 + k0 * x1 + (e >> 14)
                sx = ((m & 63) << 14) + (e & 16383)
                t = ((h & 63) << 8) + (m >> 6)
                cx = (h >> 6) + (t >> 14)
                ax0 = t & 16383
                k1 = pxy >> 14
                k0 = pxy & 16383
                l1 = pyy >> 14
                l0 = pyy & 16383
                h = k1 * x1 + l1 * y1
                e = k0 * x0 + l0 * y0
                m = k1 * x0 + k0 * x1 + l1 * y0 + l0 * y1 + (e >> 14)
                sy = ((m & 63) << 14) + (e & 16383)
                t = ((h & 63) << 8) + (m >> 6)
                cy = (h >> 6) + (t >> 14)
                ay0 = t & 16383
                k1 = pxz >> 14
                k0 = pxz & 16383
                l1 = pyz >> 14
                l0 = pyz & 16383
                n1 = pzz >> 14
                n0 = pzz & 16383
                h = k1 * x1 + l1 * y1 + n1 * z1
                e = k0 * x0 + l0 * y0 + n0 * z0
                m = k1 * x0 + k0 * x1 + l1 * y0 + l0 * y1 + n1 * z0 + n0 * z1 + (e >> 14)
                sz = ((m & 63) << 14) + (e & 16383)
                t = ((h & 63) << 8) + (m >> 6)
                cz = (h >> 6) + (t >> 14)
                az0 = t & 16383
                if cx < -32768 or cx >= 32768 or cy < -32768 or cy >= 32768 or \
                        cz < -32768 or cz >= 32768:
                    big = 1       # some |a| >= 2 g: the limbs
                    ax1 = cx & 16383
                    ax2 = cx >> 14
                    ay1 = cy & 16383
                    ay2 = cy >> 14
                    az1 = cz & 16383
                    az2 = cz >> 14
                    if mode == -1:
                        cc[b + 3] = -1
                else:
                    ax = (cx << 14) + ax0
                    ay = (cy << 14) + ay0
                    az = (cz << 14) + az0
                    if mode == -1:
                        cc[b] = ax
                        cc[b + 1] = ay
                        cc[b + 2] = az
                        cc[b + 3] = sx
                        cc[b + 4] = sy
                        cc[b + 5] = sz
            x = at
            if kk > 0:
                x = at + (kk << 2)
            if big == 0:
                # |a| < 2 g (+ a gradient step): halves of 15 bits, the low one in [-2**14, 2**14)
                x1 = (ax + 16384) >> 15
                x0 = ax - (x1 << 15)
                y1 = (ay + 16384) >> 15
                y0 = ay - (y1 << 15)
                z1 = (az + 16384) >> 15
                z0 = az - (z1 << 15)
                # |a|^2 - 2**56 = (e2 - 2**26) 2**30 + e1 2**16 + e0
                h = x1 * x1 + y1 * y1 + z1 * z1 - 67108864
                if h > -16777216 and h < 16777216:
                    e = x1 * x0 + y1 * y0 + z1 * z0
                    m = x0 * x0 + y0 * y0 + z0 * z0
                    r = (h << 4) + ((e + (m >> 16)) >> 10)     # |r| < 2**28.01
                    # r^2 / 2**20, r = r1 2**15 + r0: r1^2 2**10 + (r1 r0 + r0^2 / 2**16) / 2**4
                    r1 = r >> 15
                    r0 = r & 32767
                    h = r1 * r1
                    t = ((h & 15) << 10) + ((r1 * r0 + ((r0 * r0) >> 16)) >> 4)
                    o[x] = int(o[x]) + (t & 16383)
                    o[x + 1] = int(o[x + 1]) + (h >> 4) + (t >> 14)
                else:
                    big = 1
                    ax0 = ax & 16383
                    ax1 = (ax >> 14) & 16383
                    ax2 = ax >> 28
                    ay0 = ay & 16383
                    ay1 = (ay >> 14) & 16383
                    ay2 = ay >> 28
                    az0 = az & 16383
                    az1 = (az >> 14) & 16383
                    az2 = az >> 28
            if big:
                # |a|^2 - 2**56 = e0 + 2 e1 2**14 + e2 2**28 + e3 2**42 + e4 2**56
                e0 = ax0 * ax0 + ay0 * ay0 + az0 * az0
                e1 = ax1 * ax0 + ay1 * ay0 + az1 * az0
                e2 = ax1 * ax1 + ay1 * ay1 + az1 * az1 + ((ax2 * ax0 + ay2 * ay0 + az2 * az0) << 1)
                e3 = (ax2 * ax1 + ay2 * ay1 + az2 * az1) << 1
                e4 = ax2 * ax2 + ay2 * ay2 + az2 * az2 - 1
                # floor(/ 2**14) carried into 14-bit limbs, r = that >> 12 = r2 2**28 + r1 2**14 + r0
                t = ((e1 & 16383) << 1) + (e0 >> 14)
                e2 += ((e1 >> 14) << 1) + (t >> 14)
                e3 += e2 >> 14
                e4 += e3 >> 14
                r0 = ((t & 16383) >> 12) + ((e2 & 4095) << 2)
                r1 = ((e2 & 16383) >> 12) + ((e3 & 4095) << 2)
                r2 = ((e3 & 16383) >> 12) + (e4 << 2)
                # r^2 = f0 + f1 2**14 + f2 2**28 + f3 2**42 + f4 2**56; floor / 2**20 (>> 14, >> 6)
                f0 = r0 * r0
                t = ((r1 * r0) << 1) + (f0 >> 14)
                f2 = r1 * r1 + ((r2 * r0) << 1) + (t >> 14)
                f3 = ((r2 * r1) << 1) + (f2 >> 14)
                f4 = r2 * r2 + (f3 >> 14)
                o[x] = int(o[x]) + ((t & 16383) >> 6) + ((f2 & 63) << 8)
                o[x + 1] = int(o[x + 1]) + ((f2 & 16383) >> 6) + ((f3 & 63) << 8)
                o[x + 2] = int(o[x + 2]) + ((f3 & 16383) >> 6) + ((f4 & 63) << 8)
                o[x + 3] = int(o[x + 3]) + (f4 >> 6)
            kk += 1
        i += 3
    # each sum's limbs carried (every limb sum is >= 0)
    j = 0
    while j < groups:
        x = at + (j << 2)
        s = int(o[x])
        o[x] = s & 16383
        s = int(o[x + 1]) + (s >> 14)
        o[x + 1] = s & 16383
        s = int(o[x + 2]) + (s >> 14)
        o[x + 2] = s & 16383
        o[x + 3] = int(o[x + 3]) + (s >> 14)
        j += 1
    return 0


def from_limbs(f, at):
    """The int an objective's limbs f[at:at+LIMBS] hold (acal/paper/objective.py); a long past 2**30 on
    a 32-bit port."""
    return (((((f[at + 3] << 14) + f[at + 2]) << 14) + f[at + 1]) << 14) + f[at]


def limbs_above(f, a, b):
    """True when the objective in limbs at f[a:] is larger than the one at f[b:]."""
    j = LIMBS - 1
    while j >= 0:
        if f[a + j] != f[b + j]:
            return f[a + j] > f[b + j]
        j -= 1
    return False


@viper
def update(f, base: int, par, alpha, n: int, den: int, w: int) -> int:
    """The gradient step on the n parameters par (Q24, an int32 array): par[k] -= floor(2
    alpha[k] (F_k - F) / den) (fixed.UPDATE_MUL = 2), F_k the objective at p + h e_k in f[4k:],
    F the one at p in f[base:] (limbs), 0 <= alpha < 2**9 and 0 < den < 2**15; exact while a
    step is below QUOTIENT_MAX in size, else +-QUOTIENT_MAX (a step that large leaves the fit
    region: the fit has diverged either way, optimiser.py).  Returns 1 when the 9 parameters
    left the fit region (model.in_fit_region), else 0."""
    a = ptr32(f)
    q = ptr32(par)
    al = ptr32(alpha)
    k = 0
    while k < n:
        at = k << 2
        d0 = (int(a[at]) << w >> w) - (int(a[base]) << w >> w)
        d1 = (int(a[at + 1]) << w >> w) - (int(a[base + 1]) << w >> w) + (d0 >> 14)
        d2 = (int(a[at + 2]) << w >> w) - (int(a[base + 2]) << w >> w) + (d1 >> 14)
        d3 = (int(a[at + 3]) << w >> w) - (int(a[base + 3]) << w >> w) + (d2 >> 14)
        m = (int(al[k]) << w >> w) << 1
        step = 0
        if m != 0:
            # D = q den + r, long division from the top limb (remainders < den, so
            # r 2**14 < 2**29); then floor(m D / den) = m q + floor(m r / den)
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
            lim = 134217728 // m
            if q3 == 0 and q2 == 0 and (q1 << 14) + q0 < lim:
                step = m * ((q1 << 14) + q0) + (m * r) // den
            elif q3 == -1 and q2 == 16383 and ((q1 - 16384) << 14) + q0 > -lim:
                step = m * (((q1 - 16384) << 14) + q0) + (m * r) // den
            elif q3 < 0:
                step = -134217728
            else:
                step = 134217728
        q[k] = (int(q[k]) << w >> w) - step
        k += 1
    # the fit region (fixed.FIT_*)
    i = 0
    while i < 9:
        v = int(q[i]) << w >> w
        if i < 3:
            if v < 8388608 or v > 33554432:
                return 1
        elif v < -8388608 or v > 8388608:
            return 1
        i += 1
    return 0
