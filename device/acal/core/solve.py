# Symmetric positive definite linear systems in integers: the damped normal equations of the
# default profile's Gauss-Newton fit (acal/core/gaussnewton.py), n <= 21 unknowns, with every
# intermediate below 2**30 (acal/core/wide.py), so that a solve allocates nothing on a 32-bit port.
#
# (A + lambda diag A) x = b 2**xshift is solved, lambda = mu 2**-8, by Gaussian elimination
# without pivoting (the system is symmetric positive definite, so the pivots are positive) on a
# scaled copy:
#   * each unknown k is scaled by 2**-s_k so that the scaled diagonal D_k lies in
#     [2**(DIAG_BITS-2), 2**DIAG_BITS) (s_k < 0 scales a small one up); off-diagonals then obey |m_kl| <= sqrt(D_k D_l) < 2**DIAG_BITS, and so do
#     the Schur complements as the elimination runs;
#   * the damping divides the off-diagonals and b by 1 + lambda instead of multiplying the
#     diagonal by it (the same system, divided through), so no entry grows with mu;
#   * b is scaled by the same 2**-s_k and by one common power of two 2**-e so that max |c| lies
#     in [2**(RHS_BITS-1), 2**RHS_BITS) (e found from bit lengths, never forming a long); e grows by 4 whenever the elimination or the back
#     substitution would carry c or the solution past its bound (the solution is linear in b:
#     e is undone at the end);
#   * multipliers in Q(MUL_Q), < 2**27 (|m_ji / m_ii| <= sqrt(D_j / floor_i) <= 2**7);
#     the solution y in units of 2**-MUL_Q, |y| < 2**23.
# A pivot that falls below its row's scaled diagonal >> GUARD_SHIFT means the unknown is almost
# a combination of the others (multiple correlation above 1 - 2**-GUARD_SHIFT): the data does not
# determine it, and the solver says so instead of returning a huge step.  Rounding moves the
# Schur complements by ~2**4 an update, far below the smallest floor (2**(DIAG_BITS-2-12)).
from acal.core.bins import int32s
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from acal.core.wide import div_shift

DIAG_BITS = 24
RHS_BITS = 19
MUL_Q = 20
GUARD_SHIFT = 12
STEP_WORK = 208        # products a step() does, about (docs/method-and-formats.md "Sliced fit")
_Y_MAX_SHIFT = 3      # |y| < m_ii 2**3 2**-MUL_Q ... i.e. |y| < 2**(MUL_Q + 3)
_T_MAX = 1 << 28      # bound of a back-substitution partial sum
_MAX_RESCALES = 8
# Solver.state's slots and _run's answers
_I = 0
_J = 1
_E = 2
_RESCALES = 3
_BACK = 4
_STATE = 5
_MORE = 0
_SOLVED = 1
_FAILED = 2


class Solver:
    """Preallocated work space for systems of up to n_max unknowns (row-major n x n).

    Sliced like the fit that uses it: begin() finds the scales (O(n)), each step() does about
    STEP_WORK products of preparing rows, eliminating rows and back-substituting unknowns;
    solve() does it all.  a must stay unchanged until the rows are prepared."""

    def __init__(self, n_max):
        self.n_max = n_max
        self.m = int32s(n_max * n_max)   # int32 arrays: _eliminate_rows' typed pointers
        self.c = int32s(n_max)
        self.y = int32s(n_max)           # ... and these (_back_substitute, _prepare_rows)
        self.s = int32s(n_max)
        self.floor = int32s(n_max)
        self.xshift = int32s(n_max)
        # the elimination's place, for _run: pivot i, row j, e, rescales done, back
        # substitution under way (0/1)
        self.state = int32s(_STATE)
        self.n = 0
        self.prep = 0
        self.inv = 0
        self.a = None
        self.x = None
        self.ok = False

    def solve(self, a, b, x, n, mu=0, xshift=None):
        """Solve (a + mu 2**-8 diag a) x = b 2**xshift (a: n x n row-major ints, symmetric
        positive definite, only the lower triangle read, entries below 2**29; b: n ints below
        2**29; xshift: n ints or None for 0) into x (n ints, floor-rounded, saturated at
        +-2**29).  Returns False, x untouched, when an unknown is not determined (a pivot under
        its guard, a diagonal <= 0, or a solution the integers cannot hold)."""
        if self.begin(a, b, x, n, mu, xshift):
            while not self.step():
                pass
        return self.ok

    def begin(self, a, b, x, n, mu=0, xshift=None):
        """Find the scales and scale b; False (and ok False) if a diagonal is <= 0."""
        c = self.c
        s = self.s
        self.n = n
        self.x = x
        self.ok = False
        if _diagonal_scales(a, s, n, SIGN_SHIFT):
            return False
        for k in range(n):
            self.xshift[k] = xshift[k] if xshift is not None else 0
        self.inv = div_shift(1 << 8, 256 + mu, 16) if mu else 0   # 2**16 / (1 + lambda)
        self.a = a
        # e: max_k |b_k| 2**-s_k 2**-e in [2**(RHS_BITS-1), 2**RHS_BITS), from bit lengths
        e = _rhs_shift(b, s, n, SIGN_SHIFT)
        _scale_rhs(b, c, s, n, e, self.inv, 1 if mu else 0, SIGN_SHIFT)
        st = self.state
        st[_I] = 0
        st[_J] = 1
        st[_E] = e
        st[_RESCALES] = 0
        st[_BACK] = 0
        self.prep = 0
        return True

    def step(self):
        """About STEP_WORK products of work: rows prepared (a slice of their own), or rows
        eliminated and unknowns back-substituted (_run); True when done (ok says whether x
        holds the solution).  Not on acal/core/status.py: no phase, one test inline, and it
        runs inside GaussNewton's _ELIM slice, where a call more cost 5 % of the wear base
        fit on the emulated Pico (docs/notes/boards-and-logs.md "One slice machine")."""
        # (the solution's scaling a method apart: with it here the frame passed 11 words,
        # which MicroPython takes from the heap on every call: docs/method-and-formats.md
        # "Frames")
        if self.prep < self.n:
            self._prepare_row()
            return False
        r = _run(self.m, self.c, self.y, self.floor, self.state, self.n, STEP_WORK, SIGN_SHIFT)
        if r == _MORE:
            return False
        if r == _SOLVED:
            self._solved()
        return True

    def _solved(self):
        # x_k = y_k * 2**(e - MUL_Q - s_k + xshift_k)
        x = self.x
        y = self.y
        e = self.state[_E] - MUL_Q
        k = self.n
        while k:
            k -= 1
            x[k] = _shift_sat(y[k], e - self.s[k] + self.xshift[k])
        self.ok = True

    def _prepare_row(self):
        # Rows prep.. of the scaled (and damped) copy, up to STEP_WORK // 2 entries (at least a
        # row).
        k = self.prep
        end = k + 1
        work = k + 1
        while end < self.n and work + end + 1 <= STEP_WORK // 2:
            end += 1
            work += end
        _prepare_rows(self.a, self.m, self.s, k, end, self.n, self.inv, SIGN_SHIFT)
        for j in range(k, end):
            self.floor[j] = self.m[j * self.n + j] >> GUARD_SHIFT
        self.prep = end


_SAT = 1 << 29


def _shift_sat(v, s):
    # v * 2**s, floor; saturated at +-2**29 (a step that large leaves every fit region).
    if s <= 0:
        return v >> (-s)
    if v == 0:
        return 0
    if v >= (_SAT >> s):
        return _SAT
    if v <= -(_SAT >> s):
        return -_SAT
    return v << s


@viper
def _eliminate_rows(rows, rhs, i: int, j: int, end: int, n: int, w: int) -> int:
    # Rows j..end-1 of the scaled system (rows, row-major n x n; rhs: c) eliminated below pivot
    # i: m_jk -= mul m_ik for k > i and c_j -= mul c_i, mul = m_ji / m_ii in Q(MUL_Q)
    # (div_shift), each product wide.mul_shift(mul, ., MUL_Q) written out (s = 20, t = 5; mul's
    # halves split once).  1 (nothing more done) at a row whose |m_ji| 2**-9 reaches the pivot,
    # else 0.  The solver's hot loop, viper on ports with emitters (acal/core/emit.py; w:
    # emit.SIGN_SHIFT); the same integers as mul_shift, each below 2**30 (tests/device/test_ranges.py).
    m = ptr32(rows)
    c = ptr32(rhs)
    pivot = i * n
    piv = int(m[pivot + i]) << w >> w
    ci = int(c[i]) << w >> w
    while j < end:
        row = j * n
        mji = int(m[row + i]) << w >> w
        if mji:
            if ((mji if mji > 0 else 0 - mji) >> 9) >= piv:
                return 1
            mul = int(div_shift(mji, piv, 20))
            ah = mul >> 15
            al = mul & 0x7FFF
            k = i + 1
            while k < n:
                b = int(m[pivot + k]) << w >> w
                bh = b >> 15
                bl = b & 0x7FFF
                mm = ah * bl + al * bh
                m[row + k] = (int(m[row + k]) << w >> w) - (((ah * bh) << 10) + (mm >> 5) +
                                                            (((mm & 31) + ((al * bl) >> 15)) >> 5))
                k += 1
            bh = ci >> 15
            bl = ci & 0x7FFF
            mm = ah * bl + al * bh
            c[j] = (int(c[j]) << w >> w) - (((ah * bh) << 10) + (mm >> 5) +
                                            (((mm & 31) + ((al * bl) >> 15)) >> 5))
        j += 1
    return 0


@viper
def _prepare_rows(sums, rows, scales, k: int, end: int, n: int, inv: int, w: int):
    # Rows k..end-1 of the scaled copy (rows) of the sums' lower triangle: m_kj = m_jk =
    # a_kj 2**-(s_k + s_j) (floor), saturated at +-2**29 as _shift_sat, then times inv 2**-16
    # (the damping; wide.mul_shift written out for s = 16, t = 1) when inv; the diagonal
    # a_kk 4**-s_k.  Viper on ports with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT); the
    # shifts lie in [-6, 22] (the scales s_k in [-11, 3]), below a word's width.
    a = ptr32(sums)
    m = ptr32(rows)
    s = ptr32(scales)
    ih = inv >> 15
    il = inv & 0x7FFF
    while k < end:
        sk = int(s[k]) << w >> w
        j = 0
        while j <= k:
            v = int(a[k * n + j]) << w >> w
            sh = 0 - (sk + (int(s[j]) << w >> w))
            if sh <= 0:
                v = v >> (0 - sh)
            elif v:
                if v >= (536870912 >> sh):
                    v = 536870912
                elif v <= 0 - (536870912 >> sh):
                    v = -536870912
                else:
                    v = v << sh
            if j < k:
                if inv:
                    vh = v >> 15
                    vl = v & 0x7FFF
                    mm = vh * il + vl * ih
                    v = ((vh * ih) << 14) + (mm >> 1) + (((mm & 1) + ((vl * il) >> 15)) >> 1)
                m[k * n + j] = v
                m[j * n + k] = v
            else:
                m[k * n + k] = v
            j += 1
        k += 1


@viper
def _back_substitute(rows, rhs, sol, i: int, n: int, w: int) -> int:
    # y_i = floor((c_i 2**MUL_Q - sum_{k>i} m_ik y_k) / m_ii) into sol[i] (wide.mul_shift and
    # div_shift for MUL_Q = 20: t = 5): 1, y_i untouched, when a partial sum reaches +-_T_MAX
    # (2**28) or |t| 2**-_Y_MAX_SHIFT (3) reaches the pivot, else 0.  Viper on ports with
    # emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
    m = ptr32(rows)
    y = ptr32(sol)
    c = ptr32(rhs)
    t = int(c[i]) << w >> w
    row = i * n
    k = i + 1
    while k < n:
        a = int(m[row + k]) << w >> w
        b = int(y[k]) << w >> w
        ah = a >> 15
        al = a & 0x7FFF
        bh = b >> 15
        bl = b & 0x7FFF
        mm = ah * bl + al * bh
        t -= ((ah * bh) << 10) + (mm >> 5) + (((mm & 31) + ((al * bl) >> 15)) >> 5)
        if t >= 268435456 or t <= -268435456:
            return 1
        k += 1
    piv = int(m[row + i]) << w >> w
    if ((t if t >= 0 else 0 - t) >> 3) >= piv:
        return 1
    y[i] = int(div_shift(t, piv, 20))
    return 0


@viper
def _diagonal_scales(sums, scales, n: int, w: int) -> int:
    # s_k for each unknown: D_k = a_kk 4**-s_k in [2**(DIAG_BITS-2), 2**DIAG_BITS) (22, 24),
    # s_k < 0 scaling a small one up, into scales; 1 (a diagonal <= 0) or 0.  Viper on ports
    # with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
    a = ptr32(sums)
    s = ptr32(scales)
    k = 0
    while k < n:
        d = int(a[k * n + k]) << w >> w
        if d <= 0:
            return 1
        sk = 0
        while (d >> (2 * sk)) >= 16777216:
            sk += 1
        if sk == 0:
            while (d << (0 - 2 * sk)) < 4194304:
                sk -= 1
        s[k] = sk
        k += 1
    return 0


@viper
def _rhs_shift(rhs, scales, n: int, w: int) -> int:
    # e: max_k |b_k| 2**-s_k 2**-e in [2**(RHS_BITS-1), 2**RHS_BITS) (RHS_BITS 19), from bit
    # lengths, never forming a long; 0 when b is 0.  rhs: an int32 array, |b_k| < 2**31.  Viper on ports with
    # emitters.
    b = ptr32(rhs)
    s = ptr32(scales)
    e = 0
    found = 0
    k = 0
    while k < n:
        v = int(b[k]) << w >> w
        if v < 0:
            v = 0 - v
        if v:
            # the bit length of v, every shift amount in 0..31 (a viper shift of 32 or more
            # is v itself on Xtensa and RV32: without the bounds v >= 2**28 never ends there)
            bits = 0
            while bits < 28 and (v >> (bits + 4)):
                bits += 4
            while bits < 31 and (v >> bits):
                bits += 1
            ek = bits - (int(s[k]) << w >> w) - 19
            if not found or ek > e:
                e = ek
                found = 1
        k += 1
    return e


@viper
def _run(rows, rhs, sol, floors, state, n: int, budget: int, w: int) -> int:
    # The elimination below each pivot (rows at a time: _eliminate_rows) and the back
    # substitution (_back_substitute), from where state says, until about `budget` products
    # are done: _MORE (0), _SOLVED (1: y holds the solution in units of 2**-MUL_Q) or _FAILED
    # (2: a pivot under its guard, rounding beyond an SPD system, or past _MAX_RESCALES).  At
    # a new pivot c is brought within +-2**RHS_BITS (19) and a back substitution that overflows
    # starts again, both by c >> 4 and e + 4 (the solution shrinks with it and is scaled back at
    # the end).  Viper on ports with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
    m = ptr32(rows)
    c = ptr32(rhs)
    fl = ptr32(floors)
    st = ptr32(state)
    i = int(st[0])
    j = int(st[1])
    e = int(st[2]) << w >> w
    rescales = int(st[3])
    back = int(st[4])
    result = 0
    while budget > 0:
        shrink = 0
        if back == 0:
            if i >= n - 1:
                if i == n - 1 and (int(m[i * n + i]) << w >> w) <= (int(fl[i]) << w >> w):
                    result = 2
                    break
                back = 1
                i = n - 1
                budget -= 1
                continue
            if j == i + 1:
                piv = int(m[i * n + i]) << w >> w
                if piv <= (int(fl[i]) << w >> w) or piv <= 0:
                    result = 2
                    break
                k = 0
                while k < n:
                    v = int(c[k]) << w >> w
                    if v <= -524288 or v >= 524288:
                        shrink = 1
                        break
                    k += 1
            if not shrink:
                cost = n - i + 4
                end = j + (budget + cost - 1) // cost
                if end > n:
                    end = n
                if int(_eliminate_rows(rows, rhs, i, j, end, n, w)):
                    result = 2
                    break
                budget -= cost * (end - j)
                if end >= n:
                    i += 1
                    j = i + 1
                else:
                    j = end
        elif int(_back_substitute(rows, rhs, sol, i, n, w)):
            shrink = 1
            i = n - 1
            budget -= n
        elif i > 0:
            budget -= n - i + 4
            i -= 1
        else:
            result = 1
            break
        if shrink:
            rescales += 1
            if rescales > 8:
                result = 2
                break
            k = 0
            while k < n:
                c[k] = (int(c[k]) << w >> w) >> 4
                k += 1
            e += 4
    st[0] = i
    st[1] = j
    st[2] = e
    st[3] = rescales
    st[4] = back
    return result


@viper
def _scale_rhs(rhs, scaled, scales, n: int, e: int, inv: int, damped: int, w: int):
    # c_k = b_k 2**-(s_k + e) (floor), saturated at +-2**29 as _shift_sat, then times inv 2**-16
    # (the damping; wide.mul_shift for s = 16) when damped (mu > 0: inv may floor to 0).  Viper
    # on ports with emitters.
    b = ptr32(rhs)
    c = ptr32(scaled)
    s = ptr32(scales)
    ih = inv >> 15
    il = inv & 0x7FFF
    k = 0
    while k < n:
        v = int(b[k]) << w >> w
        sh = 0 - ((int(s[k]) << w >> w) + e)
        if sh <= 0:
            v = v >> (0 - sh)
        elif v:
            if v >= (536870912 >> sh):
                v = 536870912
            elif v <= 0 - (536870912 >> sh):
                v = -536870912
            else:
                v = v << sh
        if damped:
            vh = v >> 15
            vl = v & 0x7FFF
            mm = vh * il + vl * ih
            v = ((vh * ih) << 14) + (mm >> 1) + (((mm & 1) + ((vl * il) >> 15)) >> 1)
        c[k] = v
        k += 1
