# Symmetric positive definite linear systems in integers: the damped normal equations of the
# default profile's Gauss-Newton fit (acal/gaussnewton.py), n <= 21 unknowns, with every
# intermediate below 2**30 (acal/wide.py), so that a solve allocates nothing on a 32-bit port.
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
from acal.bins import conditions
from acal.emit import SIGN_SHIFT, viper, ptr32
from acal.wide import mul_shift, div_shift

DIAG_BITS = 24
RHS_BITS = 19
MUL_Q = 20
GUARD_SHIFT = 12
STEP_WORK = 48        # products a step() does, about (docs/method-and-formats.md "Sliced fit")
_Y_MAX_SHIFT = 3      # |y| < m_ii 2**3 2**-MUL_Q ... i.e. |y| < 2**(MUL_Q + 3)
_T_MAX = 1 << 28      # bound of a back-substitution partial sum
_MAX_RESCALES = 8


class Solver:
    """Preallocated work space for systems of up to n_max unknowns (row-major n x n).

    Sliced like the fit that uses it: begin() finds the scales (O(n)), each step() does about
    STEP_WORK products of preparing rows, eliminating rows and back-substituting unknowns;
    solve() does it all.  a must stay unchanged until the rows are prepared."""

    def __init__(self, n_max):
        self.n_max = n_max
        self.m = conditions(n_max * n_max)   # int32 arrays: _eliminate's typed pointers
        self.c = conditions(n_max)
        self.y = [0] * n_max
        self.s = [0] * n_max
        self.floor = [0] * n_max
        self.xshift = [0] * n_max
        self.n = 0
        self.i = 0
        self.j = 0
        self.e = 0
        self.rescales = 0
        self.back = False
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
        for k in range(n):
            d = a[k * n + k]
            if d <= 0:
                return False
            # s_k: D_k = d 4**-s_k in [2**(DIAG_BITS-2), 2**DIAG_BITS); s_k < 0 scales up
            sk = 0
            while (d >> (2 * sk)) >= (1 << DIAG_BITS):
                sk += 1
            if sk == 0:
                while (d << (-2 * sk)) < (1 << (DIAG_BITS - 2)):
                    sk -= 1
            s[k] = sk
            self.xshift[k] = xshift[k] if xshift is not None else 0
        self.inv = div_shift(1 << 8, 256 + mu, 16) if mu else 0   # 2**16 / (1 + lambda)
        self.a = a
        # e: max_k |b_k| 2**-s_k 2**-e in [2**(RHS_BITS-1), 2**RHS_BITS), from bit lengths
        e = None
        for k in range(n):
            v = b[k] if b[k] >= 0 else -b[k]
            if v:
                bits = 0
                while (v >> (bits + 4)):
                    bits += 4
                while (v >> bits):
                    bits += 1
                ek = bits - s[k] - RHS_BITS
                if e is None or ek > e:
                    e = ek
        if e is None:
            e = 0
        for k in range(n):
            v = _shift_sat(b[k], -(s[k] + e))
            if mu:
                v = mul_shift(v, self.inv, 16)
            c[k] = v
        self.e = e
        self.i = 0
        self.j = 1
        self.prep = 0
        self.back = False
        self.rescales = 0
        return True

    def _rescale(self):
        # c >> 4 (floor), e + 4: the solution shrinks with it and is scaled back at the end.
        self.rescales += 1
        if self.rescales > _MAX_RESCALES:
            return False
        c = self.c
        for k in range(self.n):
            c[k] >>= 4
        self.e += 4
        return True

    def step(self):
        """About STEP_WORK products of work: rows prepared, rows eliminated, unknowns
        back-substituted; True when done (ok says whether x holds the solution)."""
        budget = STEP_WORK
        while budget > 0:
            if self.back:
                cost = self._back_unit()
            elif self.prep < self.n:
                cost = self._prepare_row()
            else:
                cost = self._elim_unit()
            if cost < 0:
                return True
            budget -= cost
        return False

    def _prepare_row(self):
        # Row `prep` of the scaled (and damped) copy; its cost.
        a = self.a
        m = self.m
        s = self.s
        inv = self.inv
        n = self.n
        k = self.prep
        for j in range(k):
            v = _shift_sat(a[k * n + j], -(s[k] + s[j]))
            if inv:
                v = mul_shift(v, inv, 16)
            m[k * n + j] = v
            m[j * n + k] = v
        dk = _shift_sat(a[k * n + k], -2 * s[k])
        m[k * n + k] = dk
        self.floor[k] = dk >> GUARD_SHIFT
        self.prep = k + 1
        return k + 1

    def _elim_unit(self):
        # Row j below pivot i eliminated (at a new pivot: its guard, c's bound); its cost, or
        # -1 when the solve has ended (a pivot under its guard).
        m = self.m
        c = self.c
        n = self.n
        i = self.i
        if i >= n - 1:
            if i == n - 1 and m[i * n + i] <= self.floor[i]:
                return -1
            self.back = True
            self.i = n - 1
            return 1
        piv = m[i * n + i]
        j = self.j
        if j == i + 1:
            if piv <= self.floor[i] or piv <= 0:
                return -1
            lim = 1 << RHS_BITS
            for k in range(n):
                while -lim >= c[k] or c[k] >= lim:
                    if not self._rescale():
                        return -1
        mji = m[j * n + i]
        if mji:
            if (mji if mji > 0 else -mji) >> 9 >= piv:
                return -1   # beyond any Schur complement of an SPD system: rounding won
            mul = div_shift(mji, piv, MUL_Q)
            _eliminate(m, j * n, i * n, i + 1, n, mul, SIGN_SHIFT)
            c[j] -= mul_shift(mul, c[i], MUL_Q)
        if j + 1 >= n:
            self.i = i + 1
            self.j = i + 2
        else:
            self.j = j + 1
        return n - i + 4

    def _back_unit(self):
        # y_i = (c_i 2**MUL_Q - sum_k m_ik y_k) / m_ii, in units of 2**-MUL_Q; a sum or a y past
        # its bound rescales c and starts the back substitution again.  Its cost, or -1 when
        # the solve has ended.
        m = self.m
        y = self.y
        n = self.n
        i = self.i
        t = self.c[i]
        row = i * n
        for k in range(i + 1, n):
            t -= mul_shift(m[row + k], y[k], MUL_Q)
            if t >= _T_MAX or t <= -_T_MAX:
                return self._back_restart()
        piv = m[row + i]
        if (t if t >= 0 else -t) >> _Y_MAX_SHIFT >= piv:
            return self._back_restart()
        y[i] = div_shift(t, piv, MUL_Q)
        if i > 0:
            self.i = i - 1
            return n - i + 4
        # x_k = y_k * 2**(e - MUL_Q - s_k + xshift_k)
        x = self.x
        for k in range(n):
            x[k] = _shift_sat(y[k], self.e - MUL_Q - self.s[k] + self.xshift[k])
        self.ok = True
        return -1

    def _back_restart(self):
        if not self._rescale():
            return -1
        self.i = self.n - 1
        return self.n

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
def _eliminate(rows, row: int, pivot: int, k: int, n: int, mul: int, w: int):
    # rows[row + k:row + n] -= mul_shift(mul, rows[pivot + k:pivot + n], MUL_Q): one row of the
    # elimination, the solver's hot loop, viper on ports with emitters (acal/emit.py; w:
    # emit.SIGN_SHIFT).  wide.mul_shift written out for s = MUL_Q = 20 (t = 5), mul's halves
    # split once: the same integers, each below 2**30 (tests/test_ranges.py traces them).
    m = ptr32(rows)
    ah = mul >> 15
    al = mul & 0x7FFF
    while k < n:
        b = int(m[pivot + k]) << w >> w
        bh = b >> 15
        bl = b & 0x7FFF
        mm = ah * bl + al * bh
        c = (al * bl) >> 15
        m[row + k] = (int(m[row + k]) << w >> w) - (((ah * bh) << 10) + (mm >> 5) +
                                                    (((mm & 31) + c) >> 5))
        k += 1
