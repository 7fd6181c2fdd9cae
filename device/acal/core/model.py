# The 9-parameter error model (Farago 2024, eqs. 1-9): a = K (v + o), K lower-triangular.
#   a_x = kxx (v_x + o_x)
#   a_y = kxy (v_x + o_x) + kyy (v_y + o_y)
#   a_z = kxz (v_x + o_x) + kyz (v_y + o_y) + kzz (v_z + o_z)
# Parameters are a list of 9 ints in Q24 (fixed.py), in the order of eq. 6.  The per-sample
# apply of a calibration: acal/core/calibration.py.
from acal.core.fixed import (PARAM_ONE, A_Q, A_SHIFT, POINT_TO_PARAM_SHIFT, R_SHIFT, F_SHIFT, N_PARAMS,
                        K_DIAG_MIN, K_DIAG_MAX, K_OFF_MAX, O_MAX, FIT_K_DIAG_MIN,
                        FIT_K_DIAG_MAX, FIT_K_OFF_MAX, FIT_O_MAX, APPLY_W_MAX)

from acal.core import effects
from acal.core.bins import COND, int32s
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from array import array
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

_ONE_G2_Q56 = 1 << (2 * A_Q)
POINT_LIMIT = 1 << 20    # |point| < 16 g in Q16: the exact objective's domain (acal/paper/objective.py)
_ARG_LIMIT = const(1 << 29)
_P = array("i", [0] * N_PARAMS)   # objective()'s parameters
_LIMBS = []                       # ... and its limbs, made on first use


def identity(p):
    """Set p (list of 9 ints) to p0 = [1 1 1 0 0 0 0 0 0], the ideal sensor."""
    for i in range(N_PARAMS):
        p[i] = PARAM_ONE if i < 3 else 0


def _within(p, kmin, kmax, kofs, omax):
    for i in range(3):
        if not kmin <= p[i] <= kmax:
            return False
    for i in range(3, 6):
        if not -kofs <= p[i] <= kofs:
            return False
    for i in range(6, 9):
        if not -omax <= p[i] <= omax:
            return False
    return True


def in_bounds(p):
    """True when the parameters lie inside the calibration bounds (fixed.py)."""
    return _within(p, K_DIAG_MIN, K_DIAG_MAX, K_OFF_MAX, O_MAX)


def in_fit_region(p):
    """True while a fit has not diverged (the wider region of fixed.py)."""
    return _within(p, FIT_K_DIAG_MIN, FIT_K_DIAG_MAX, FIT_K_OFF_MAX, FIT_O_MAX)


def load_points(pts, n, u):
    """Points (Q16 g, flat x y z list) -> u (Q24 g; an int32 array for the exact objective), the
    form the objective reads.  False, u partly written, when a point lies past +-16 g (POINT_LIMIT:
    the exact objective's domain, acal/paper/objective.py; no LIS3DH reading is larger)."""
    for i in range(3 * n):
        v = pts[i]
        if v >= POINT_LIMIT or v < -POINT_LIMIT:
            return False
        u[i] = v << POINT_TO_PARAM_SHIFT
    return True


def objective(p, u, n):
    """Sum over the n points of (|a|^2 - 1 g^2)^2, the paper's eq. 12 without the square root.

    u: points in Q24 g (load_points).  Returns Q40 g^4.  The formula (objective_long) needs ints
    to ~2**62: products k*u < 2**51, a in Q28, |a|^2 < 2**61 and r**2 < 2**62 for rest means of a
    sensor inside the paper's error ranges, longs on a 32-bit board.  For u an int32 array inside
    the exact domain (parameters in the fit region, points within +-16 g, acal/paper/objective.py) the
    same integers come from limbs below 2**30 (viper on ports with emitters); otherwise from the
    formula, exact in Python ints of any size."""
    for i in range(N_PARAMS):   # past an int32, the formula (a long would not fit _P)
        if not -_ARG_LIMIT < p[i] < _ARG_LIMIT:
            return objective_long(p, u, n)
        _P[i] = p[i]
    if isinstance(u, array):
        from acal.paper import objective as limbs   # the paper profile's, loaded when used
        if not _LIMBS:
            _LIMBS.append(array("i", [0] * limbs.LIMBS))
        f = _LIMBS[0]
        if not limbs.objective_limbs(u, n, f, 0, _P, limbs.PLAIN, f, SIGN_SHIFT):
            return limbs.from_limbs(f, 0)
    return objective_long(p, u, n)


def objective_long(p, u, n):
    """objective() by its formula in Python ints (longs past 2**30): the reference the exact
    limbs reproduce, and the path outside their domain."""
    kxx = p[0]
    kyy = p[1]
    kzz = p[2]
    kxy = p[3]
    kxz = p[4]
    kyz = p[5]
    ox = p[6]
    oy = p[7]
    oz = p[8]
    one = _ONE_G2_Q56
    q = A_SHIFT  # locals: module globals cost a lookup each in the loop
    rs = R_SHIFT
    fs = F_SHIFT
    total = 0
    i = 0
    end = 3 * n
    while i < end:
        ux = u[i] + ox
        uy = u[i + 1] + oy
        uz = u[i + 2] + oz
        ax = (kxx * ux) >> q
        ay = (kxy * ux + kyy * uy) >> q
        az = (kxz * ux + kyz * uy + kzz * uz) >> q
        r = (ax * ax + ay * ay + az * az - one) >> rs
        total += (r * r) >> fs
        i += 3
    return total


# The default profile's fit (acal/core/gaussnewton.py) reads residuals and Jacobian rows in formats
# that keep every intermediate below 2**30, so that it allocates nothing on a 32-bit port:
#   readings u clamped to +-FIT_W_MAX (2.048 g, the apply's clamp) per axis, v = u + o;
#   a = K v in Q24 g (wide.mul_shift), |a| < 7.7 g inside the fit region;
#   r = |a|^2 - 1 g^2 in Q22 g^2 (GN_R_Q; |a|^2 < 125 g^2 < 2**29 in Q22);
#   Jacobian rows d = J / 2 in Q24 (g^2 per parameter unit) from a, v and K truncated to Q12:
#   each product < 2**28.3 in the fit region, to ~2**-12 of itself (the fit's rows are scaled
#   to 11 bits anyway, gaussnewton.py).
GN_R_Q = 22
FIT_W_MAX = APPLY_W_MAX << 10    # 2.048 g in Q24


_ROW = int32s(9)   # residual()'s scratch row

# residual_jacobian() is the default fit's hot loop, viper on ports with emitters
# (acal/core/emit.py): p is an int32 array (the fit's), each wide.mul_shift written out (P below).
# For a product P(k, u, 24) of a parameter k and a reading u, with h = x >> 15, l = x & 0x7fff:
#   m = kh ul + kl uh,  c = (kl ul) >> 15,  P = ((kh uh) << 6) + (m >> 9) + (((m & 511) + c) >> 9)
# and for a square P(a, a, 26):
#   m = 2 ah al,  c = (al al) >> 15,  P = ((ah ah) << 4) + (m >> 11) + (((m & 2047) + c) >> 11)
# the same integers as mul_shift (tests/device/test_wide.py checks them against it), each
# below 2**30 (tests/device/test_ranges.py traces them).
def residual(p, ux, uy, uz):
    """r = |K (u + o)|^2 - 1 g^2 of one point u (Q24 g, |u| <= FIT_W_MAX per axis) in Q22 g^2,
    every intermediate below 2**30 inside the fit region (fixed.py); p: an int32 array.
    residual_jacobian's, its row into a scratch (one body for both: viper's code sits in RAM)."""
    return residual_jacobian(p, ux, uy, uz, _ROW)


@viper
def residual_jacobian(params, ux: int, uy: int, uz: int, row) -> int:
    """residual() of one point (Q24 g, effects already removed) and its derivatives with
    respect to the 9 parameters, halved, into row[0:9] (an int32 array, Q24; analytic:
    a = K (u + o), r = |a|^2 - 1, d = a da/dp), a and v truncated to Q12 for the row: each
    product < 2**28.3 in the fit region, to ~2**-12 of itself."""
    p = ptr32(params)
    d = ptr32(row)
    w = int(SIGN_SHIFT)
    ux += int(p[6]) << w >> w
    uy += int(p[7]) << w >> w
    uz += int(p[8]) << w >> w
    xh = ux >> 15
    xl = ux & 0x7FFF
    yh = uy >> 15
    yl = uy & 0x7FFF
    zh = uz >> 15
    zl = uz & 0x7FFF
    kxx = int(p[0]) << w >> w
    kh = kxx >> 15
    kl = kxx & 0x7FFF
    m = kh * xl + kl * xh
    ax = ((kh * xh) << 6) + (m >> 9) + (((m & 511) + ((kl * xl) >> 15)) >> 9)
    kxy = int(p[3]) << w >> w
    kh = kxy >> 15
    kl = kxy & 0x7FFF
    m = kh * xl + kl * xh
    ay = ((kh * xh) << 6) + (m >> 9) + (((m & 511) + ((kl * xl) >> 15)) >> 9)
    kyy = int(p[1]) << w >> w
    kh = kyy >> 15
    kl = kyy & 0x7FFF
    m = kh * yl + kl * yh
    ay += ((kh * yh) << 6) + (m >> 9) + (((m & 511) + ((kl * yl) >> 15)) >> 9)
    kxz = int(p[4]) << w >> w
    kh = kxz >> 15
    kl = kxz & 0x7FFF
    m = kh * xl + kl * xh
    az = ((kh * xh) << 6) + (m >> 9) + (((m & 511) + ((kl * xl) >> 15)) >> 9)
    kyz = int(p[5]) << w >> w
    kh = kyz >> 15
    kl = kyz & 0x7FFF
    m = kh * yl + kl * yh
    az += ((kh * yh) << 6) + (m >> 9) + (((m & 511) + ((kl * yl) >> 15)) >> 9)
    kzz = int(p[2]) << w >> w
    kh = kzz >> 15
    kl = kzz & 0x7FFF
    m = kh * zl + kl * zh
    az += ((kh * zh) << 6) + (m >> 9) + (((m & 511) + ((kl * zl) >> 15)) >> 9)
    h = ax >> 15
    lo = ax & 0x7FFF
    m = h * lo + lo * h
    r = ((h * h) << 4) + (m >> 11) + (((m & 2047) + ((lo * lo) >> 15)) >> 11)
    h = ay >> 15
    lo = ay & 0x7FFF
    m = h * lo + lo * h
    r += ((h * h) << 4) + (m >> 11) + (((m & 2047) + ((lo * lo) >> 15)) >> 11)
    h = az >> 15
    lo = az & 0x7FFF
    m = h * lo + lo * h
    r += ((h * h) << 4) + (m >> 11) + (((m & 2047) + ((lo * lo) >> 15)) >> 11)
    ax >>= 12
    ay >>= 12
    az >>= 12
    ux >>= 12
    uy >>= 12
    uz >>= 12
    d[0] = ax * ux
    d[1] = ay * uy
    d[2] = az * uz
    d[3] = ay * ux
    d[4] = az * ux
    d[5] = az * uy
    d[6] = ax * (kxx >> 12) + ay * (kxy >> 12) + az * (kxz >> 12)
    d[7] = ay * (kyy >> 12) + az * (kyz >> 12)
    d[8] = az * (kzz >> 12)
    return r - 4194304   # 1 g^2 in Q22 (_ONE_G2_Q22)


def remove_effects(p, kinds, w, at, d, da, ts=0):
    """Remove a composed model's effects (acal.core.effects ids, parameters p[9 + 3k : 12 + 3k]) from
    the reading w[at:at+3] (Q24 g) in place, last first: the reverse of the order they act in,
    at the relative conditions d[da:da + COND] (effects.regressor; ts: a step's time, as dt).
    Each result is clamped to +-FIT_W_MAX, as the apply clamps it (fixed.APPLY_W_MAX)."""
    k = len(kinds) - 1
    while k >= 0:
        effects.correct_u(kinds[k], p, N_PARAMS + 3 * k, w, d, da, at, ts)
        for c in range(at, at + 3):
            if w[c] > FIT_W_MAX:
                w[c] = FIT_W_MAX
            elif w[c] < -FIT_W_MAX:
                w[c] = -FIT_W_MAX
        k -= 1


def objective_effects(p, u, aux, n, kinds, w, ts=0):
    """objective() for a composed model: the effects `kinds` (acal.core.effects ids, parameters
    p[9 + 3k : 12 + 3k]) are first removed from each point, last first (the reverse of the order
    they act in), into w (3 n ints; an int32 array for the exact objective); the 9-parameter
    objective then reads w.  aux: per point dT (Q2 degC), dt (64 s units) and dV (mV), flat (COND
    per point)."""
    points_without_effects(p, u, aux, n, kinds, w, ts)
    return objective(p, w, n)


def points_without_effects(p, u, aux, n, kinds, w, ts=0):
    """objective_effects' first part: the points u with the effects removed, into w (each
    coordinate clamped to +-FIT_W_MAX: inside the exact objective's domain)."""
    for i in range(3 * n):
        w[i] = u[i]
    for i in range(n):
        remove_effects(p, kinds, w, 3 * i, aux, COND * i, ts)


def effects_within(p, kinds, factor):
    """True when every effect parameter lies within factor x its bound (acal.core.effects.BOUNDS)."""
    for k in range(len(kinds)):
        b = effects.BOUNDS[kinds[k]] * factor
        for i in range(3):
            v = p[N_PARAMS + 3 * k + i]
            if v > b or v < -b:
                return False
    return True
