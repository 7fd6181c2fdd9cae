# The sums of the default fit's normal equations, point by point (acal/core/gaussnewton.py: the
# formats, the scales tau and s_k, and why every value stays below 2**30): each point's scaled
# Jacobian row and residual accumulated into A and b, the trial objective, the residuals' sort
# for outlier rejection, and the exact small-int helpers on the scaled objective.  The hot loops
# are viper on ports with emitters (acal/core/emit.py: typed pointers into the fit's int32 arrays;
# w: emit.SIGN_SHIFT), plain Python elsewhere; tests/device/test_ranges.py traces every value.
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from acal.core.model import FIT_W_MAX, residual_jacobian
from acal.core.effects import correct_kinds
from acal.core.wide import mul_shift

R_MAX = 1 << 18           # |r~| <= 2**18
D_MAX = 1 << 11           # |d~| <= 2**11
B_MASK = 511
B_SPLIT = 9               # b in two limbs: sum d~ (r~ >> 9) 2**9 + sum d~ (r~ & 511)
F_TAU_OFFSET = 7          # f reads r 2**-(tau + 7): |r| 2**-(tau + 7) <= 2**11
TRIAL_MAX = 1 << 13       # a trial residual past 2**(13 + tau + 7): the trial is worse
F_LIMIT = 1 << 29
OBJ_MAX = 0x3FFFFFFF      # 2**30 - 1
RHS_HI_MAX = 1 << (28 - 9 - 1)   # the high limb's bound for -b below 2**28
QD_BASE = 24
QD_EFFECT = 16


@viper
def accumulate(a: ptr32, d: ptr32, n: int, high, low, rh: int, rl: int, w: int):
    # One point's scaled row d~ (d) and residual r~ = rh 2**B_SPLIT + rl into A (a, the lower
    # triangle) and b (high, low limbs): the fit's hot loop, viper on ports with emitters
    # (acal/core/emit.py; w: emit.SIGN_SHIFT; 9 is B_SPLIT, 511 B_MASK).  Every value below 2**29
    # (above; tests/device/test_ranges.py traces them).  A and d~ are the first arguments, typed:
    # viper keeps a function's first three locals in registers (on an RP2040 this loop then
    # takes 192 us for 21 parameters, 236 us with them later), and A's index runs along its row.
    b = ptr32(high)
    bl = ptr32(low)
    k = 0
    while k < n:
        dk = int(d[k]) << w >> w
        if dk:
            at = k * n
            j = 0
            while j <= k:
                a[at] = (int(a[at]) << w >> w) + dk * (int(d[j]) << w >> w)
                j += 1
                at += 1
            v = (int(bl[k]) << w >> w) + dk * rl
            b[k] = (int(b[k]) << w >> w) + dk * rh + (v >> 9)
            bl[k] = v & 511
        k += 1


@viper
def accum_points(fit, i: int, end: int, tau: int, f: int) -> int:
    # Points [i, end) of a fit into its sums: each point's residual into r and f, its row scaled
    # into d~ and r~ = rh 2**B_SPLIT + rl, then accumulate().  The residuals' scale tau and the
    # columns' scales s_k grow as the points need (the sums so far shifted down with them, but at
    # a pass's first point, where they are zero); a point that grows one takes a slice of its
    # own: it is done first in a call, or left for the next (fit.state: where this stopped, and
    # tau).  Returns f.  Viper on ports with emitters (acal/core/emit.py): R_MAX 2**18, D_MAX 2**11,
    # F_TAU_OFFSET 7, B_SPLIT 9; wide.mul_shift(x, x, s) of the square written out.
    row = fit.d
    d = ptr32(row)
    rr = ptr32(fit.r)
    scales = fit.sh
    sh = ptr32(scales)
    params = fit.p
    sums = fit.a
    high = fit.b
    low = fit.bl
    b = ptr32(high)
    bl = ptr32(low)
    n = int(fit.n_params)
    w = int(SIGN_SHIFT)
    start = i
    while i < end:
        r0 = int(point_row(fit, params, i, 1))
        ar = r0 if r0 >= 0 else 0 - r0
        grows = (ar >> tau) >= 262144
        k = 0
        while k < n and not grows:
            v = int(d[k]) << w >> w
            grows = ((v if v >= 0 else 0 - v) >> (int(sh[k]) << w >> w)) >= 2048
            k += 1
        if grows and i > start:
            break             # the next slice's first point
        rr[i] = r0
        if (ar >> tau) >= 262144:
            # tau grows: the smallest that holds r~, 4 bits a step, then 1; f and b shift down
            g = tau
            while (ar >> (g + 4)) >= 262144:
                g += 4
            while (ar >> g) >= 262144:
                g += 1
            if i:
                f >>= 2 * (g - tau)
                k = 0
                while k < n:
                    hi = int(b[k]) << w >> w
                    h = hi >> (g - tau)
                    b[k] = h
                    bl[k] = (((hi - (h << (g - tau))) << 9) + (int(bl[k]) << w >> w)) >> (g - tau)
                    k += 1
            tau = g
        # f += floor(r0**2 4**-(tau + 7)) (below 2**26) as wide.mul_shift(x, x, s)
        t = tau + 7
        x = r0
        s = 2 * t
        if t < 8:
            x = r0 << (8 - t)
            s = 16
        h = x >> 15
        lo = x & 0x7FFF
        m = h * lo + lo * h
        c = (lo * lo) >> 15
        t = s - 15
        if t >= 15:
            f += (h * h + (m >> 15) + (((m & 0x7FFF) + c) >> 15)) >> (t - 15)
        else:
            f += ((h * h) << (15 - t)) + (m >> t) + (((m & ((1 << t) - 1)) + c) >> t)
        rs = r0
        if tau:
            rs = (r0 + (1 << (tau - 1))) >> tau
        if grows:             # the columns' scales grow as they must (their sums shift down)
            if int(scale_row(row, scales, fit.grown, n, w)) and i:
                grow_columns(sums, high, low, fit.grown, n, w)
        else:
            k = 0
            while k < n:
                s = int(sh[k]) << w >> w
                if s:
                    d[k] = ((int(d[k]) << w >> w) + (1 << (s - 1))) >> s
                k += 1
        accumulate(sums, row, n, high, low, rs >> 9, rs & 511, w)
        i += 1
        if grows:
            break
    st = ptr32(fit.state)
    st[0] = i
    st[1] = tau
    return f


@viper
def trial_points(fit, params, i: int, end: int, t: int, ft: int) -> int:
    # The trial objective over the points [i, end) at params: each residual into fit.rt, ft
    # plus floor(r**2 4**-t) each, saturated at F_LIMIT (2**29); a residual past 2**(13 + t)
    # (TRIAL_MAX) makes it F_LIMIT.  Viper on ports with emitters: point_row() is called;
    # floor(r**2 4**-t) by wide.mul_shift.
    rt = ptr32(fit.rt)
    while i < end:
        r = int(point_row(fit, params, i, 0))
        rt[i] = r
        if ((r if r >= 0 else 0 - r) >> t) >= 8192:
            ft = 536870912
        else:
            k = 8 - t
            if k > 0:
                ft += int(mul_shift(r << k, r << k, 16))
            else:
                ft += int(mul_shift(r, r, 2 * t))
            if ft > 536870912:
                ft = 536870912
        i += 1
    return ft


@viper
def insert_abs(res, ordered, i: int, end: int, w: int):
    # |res[i:end]| inserted into ordered[0:end], kept ascending (ordered[0:i] already is): the
    # sort's loop, viper on ports with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
    r = ptr32(res)
    srt = ptr32(ordered)
    while i < end:
        v = int(r[i]) << w >> w
        if v < 0:
            v = 0 - v
        j = i
        while j > 0 and (int(srt[j - 1]) << w >> w) > v:
            srt[j] = srt[j - 1]
            j -= 1
        srt[j] = v
        i += 1


@viper
def scale_row(row, scales, grown, n: int, w: int) -> int:
    # A point's raw row d (row) scaled in place to d~_k = round(d_k 2**-s_k), each scale s_k
    # (scales) first grown to the smallest that keeps |d~_k| <= D_MAX (2**11) and the growth
    # written to grown[k]: the number of columns grown.  Viper on ports with emitters (acal/
    # emit.py; w: emit.SIGN_SHIFT; 2048 is D_MAX); the smallest scale, 4 bits a step, then 1.
    d = ptr32(row)
    sh = ptr32(scales)
    g = ptr32(grown)
    count = 0
    k = 0
    while k < n:
        v = int(d[k]) << w >> w
        s = int(sh[k]) << w >> w
        av = v if v >= 0 else 0 - v
        g[k] = 0
        if (av >> s) >= 2048:
            t = s
            while (av >> (t + 4)) >= 2048:
                t += 4
            while (av >> t) >= 2048:
                t += 1
            g[k] = t - s
            sh[k] = t
            s = t
            count += 1
        if s:
            d[k] = (v + (1 << (s - 1))) >> s
        k += 1
    return count


def q24(f, t):
    # f 2**(2t - 44) g^4 in Q24 g^4, saturated at OBJ_MAX.
    s = 2 * t - 20
    if s <= 0:
        return f >> (-s)
    if f > (OBJ_MAX >> s):
        return OBJ_MAX
    return f << s


def above(f1, t1, f2, t2):
    # f1 4**t1 > f2 4**t2, exactly, without a long.
    if t1 >= t2:
        return f1 > (f2 >> (2 * (t1 - t2)))
    h = f1 >> (2 * (t2 - t1))
    return h > f2 or (h == f2 and f1 - (h << (2 * (t2 - t1))) > 0)


@viper
def grow_columns(sums, high, low, grown, n: int, w: int):
    # Each column k whose scale grew by g = grown[k] bits: its row and column of A (sums, the
    # lower triangle; the diagonal twice) and its entry of b (high, low limbs) shift down, the
    # floor of each (shifts of one entry by two columns compose).  Viper on ports with emitters.
    a = ptr32(sums)
    b = ptr32(high)
    bl = ptr32(low)
    gr = ptr32(grown)
    k = 0
    while k < n:
        g = int(gr[k]) << w >> w
        if g:
            j = 0
            while j < n:
                if j < k:
                    a[k * n + j] = (int(a[k * n + j]) << w >> w) >> g
                elif j > k:
                    a[j * n + k] = (int(a[j * n + k]) << w >> w) >> g
                j += 1
            # the diagonal by 2g: at most 31, what any larger shift of an int32 gives (0 or
            # -1), as every architecture shifts (Xtensa and RV32 take the amount mod 32)
            g2 = 2 * g
            if g2 > 31:
                g2 = 31
            a[k * n + k] = (int(a[k * n + k]) << w >> w) >> g2
            hi = int(b[k]) << w >> w
            h = hi >> g
            b[k] = h
            bl[k] = (((hi - (h << g)) << 9) + (int(bl[k]) << w >> w)) >> g
        k += 1


@viper
def rhs_from_limbs(high, low, rhs, n: int, w: int) -> int:
    # -b from its limbs (b_k = high_k 2**B_SPLIT + low_k, B_SPLIT 9) into rhs, shifted down by
    # the smallest e that keeps every |high_k| 2**-e below RHS_HI_MAX (2**18), so that -b
    # 2**-e lies below 2**28; returns e.  Viper on ports with emitters.
    b = ptr32(high)
    bl = ptr32(low)
    r = ptr32(rhs)
    e = 0
    k = 0
    while k < n:
        v = int(b[k]) << w >> w
        if v < 0:
            v = 0 - v
        while (v >> e) >= 262144:
            e += 1
        k += 1
    k = 0
    while k < n:
        hi = int(b[k]) << w >> w
        lo = int(bl[k]) << w >> w
        if e <= 9:
            r[k] = 0 - ((hi << (9 - e)) + (lo >> e))
        else:
            h = hi >> (e - 9)
            r[k] = 0 - (h + ((((hi - (h << (e - 9))) << 9) + lo) >> e))
        k += 1
    return e


@viper
def point_row(fit, params, i: int, columns: int) -> int:
    # Point i of a GaussNewton fit: its residual at params (an int32 array; Q22 g^2), a composed
    # model's effects removed first, into fit.w (effects.correct_kinds: model.remove_effects'
    # integers, each axis clamped to +-FIT_W_MAX); the 9 parameters' Jacobian row, a by-product
    # (model.residual_jacobian), into fit.d.  columns: the effects' columns too (the raw row
    # the sums take): dr/dtheta = dr/do . dw/dtheta, the effect's correction of the reading with
    # the offsets' rows >> (QD_BASE - QD_EFFECT) = 8 as its parameters (effects.correct_kinds
    # with no clamp: each kind alone, clamp < 0, one call for every effect).  One function for
    # both, each of the fit's arrays read once a point: the sums' row as a second call re-read
    # them and paid a call, 3.6 % of a base+temp_offset fit on the emulated Pico (268.3 ->
    # 258.7 ms).  Viper on ports with emitters.
    u = ptr32(fit.u)
    row = fit.d
    w = int(SIGN_SHIFT)
    at = 3 * i
    x = int(u[at]) << w >> w
    y = int(u[at + 1]) << w >> w
    z = int(u[at + 2]) << w >> w
    nk = int(fit.nk)
    if nk == 0:
        return int(residual_jacobian(params, x, y, z, row))
    removed = fit.w
    v = ptr32(removed)
    aux = fit.aux
    ids = fit.kind_ids
    j = int(fit.ncond) * i    # bins.COND per point (a viper loop takes no other module's const)
    ts = int(fit.ts)
    v[0] = x
    v[1] = y
    v[2] = z
    correct_kinds(ids, 0, nk, params, 9, removed, aux, j, ts, int(FIT_W_MAX))
    x = int(v[0]) << w >> w
    y = int(v[1]) << w >> w
    z = int(v[2]) << w >> w
    r0 = int(residual_jacobian(params, x, y, z, row))
    if not columns:
        return r0
    d = ptr32(row)
    offs = fit.q
    q = ptr32(offs)
    moved = fit.z
    m = ptr32(moved)
    c = 0
    while c < 3:
        q[c] = (int(d[6 + c]) << w >> w) >> 8
        c += 1
    m[0] = u[at]
    m[1] = u[at + 1]
    m[2] = u[at + 2]
    correct_kinds(ids, 0, nk, offs, 0, moved, aux, j, ts, -1)   # each kind alone, one call
    k = 0
    while k < 3 * nk:
        c = 0
        while c < 3:
            d[9 + k + c] = (int(m[3 + k + c]) << w >> w) - (int(u[at + c]) << w >> w)
            c += 1
        k += 3
    return r0
