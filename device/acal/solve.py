# Symmetric positive definite linear systems in integers: the normal equations of the default
# profile's Gauss-Newton fit (acal/gaussnewton.py), n <= 21 unknowns.
#
# a x = b is solved by Gaussian elimination without pivoting (a is symmetric positive definite,
# so the pivots are positive) on a scaled copy, in Q formats chosen so that every product stays
# below 2**62 (unboxed on 64-bit ports; on 32-bit ones they are longs, README "Integer ranges"):
#   * each unknown k is scaled by 2**-s_k (s_k >= 0) so that the scaled diagonal lies below
#     2**DIAG_BITS; off-diagonals then obey |m_kl| <= sqrt(m_kk m_ll) < 2**DIAG_BITS;
#   * b is scaled by the same 2**-s_k and by one common power of two so that max |b| lies in
#     [2**(RHS_BITS-1), 2**RHS_BITS): the solution is linear in b, the shift is undone at the end;
#   * multipliers in Q(MUL_Q); the solution in units of 2**-MUL_Q before the scales are undone.
# A pivot that falls below its row's scaled diagonal >> GUARD_SHIFT means the unknown is almost
# a combination of the others (multiple correlation above 1 - 2**-GUARD_SHIFT): the data does not
# determine it, and solve() says so instead of returning a huge step.  The guard also bounds the
# multipliers: |m_ji / m_ii| <= 2**(GUARD_SHIFT / 2 + 1).
DIAG_BITS = 26
RHS_BITS = 24
MUL_Q = 20
GUARD_SHIFT = 12


def _shr(v, s):
    # v * 2**-s, floor; s may be negative.
    return v >> s if s >= 0 else v << (-s)


class Solver:
    """Preallocated work space for systems of up to n_max unknowns (row-major n x n).

    Sliced like the fit that uses it: begin() scales the system (O(n^2)), each step() eliminates
    one pivot row (O(n^2) at most) and the last one back-substitutes; solve() does it all."""

    def __init__(self, n_max):
        self.n_max = n_max
        self.m = [0] * (n_max * n_max)
        self.c = [0] * n_max
        self.y = [0] * n_max
        self.s = [0] * n_max
        self.floor = [0] * n_max
        self.n = 0
        self.i = 0
        self.e = 0
        self.x = None
        self.ok = False

    def solve(self, a, b, x, n):
        """Solve a x = b (a: n x n row-major ints, symmetric positive definite; b: n ints) into
        x (n ints, floor-rounded).  Returns False, x untouched, when an unknown is not determined
        (a pivot under its guard, or a diagonal <= 0)."""
        if self.begin(a, b, x, n):
            while not self.step():
                pass
        return self.ok

    def begin(self, a, b, x, n):
        """Scale a copy of the system; False (and ok False) if a diagonal is <= 0."""
        m = self.m
        c = self.c
        s = self.s
        fl = self.floor
        self.n = n
        self.x = x
        self.ok = False
        for k in range(n):
            d = a[k * n + k]
            if d <= 0:
                return False
            sk = 0
            while (d >> (2 * sk)) >= (1 << DIAG_BITS):
                sk += 1
            s[k] = sk
        for k in range(n):
            for j in range(n):
                m[k * n + j] = a[k * n + j] >> (s[k] + s[j])
            fl[k] = m[k * n + k] >> GUARD_SHIFT
        big = 0
        for k in range(n):
            v = b[k] >> s[k]
            c[k] = v
            if v < 0:
                v = -v
            if v > big:
                big = v
        e = 0  # c holds b_scaled * 2**-e
        while big >= (1 << RHS_BITS):
            big >>= 1
            e += 1
        while big and big < (1 << (RHS_BITS - 1)):
            big <<= 1
            e -= 1
        for k in range(n):
            c[k] = _shr(c[k], e)
        self.e = e
        self.i = 0
        return True

    def step(self):
        """Eliminate the next pivot row, or back-substitute after the last; True when done
        (ok says whether x holds the solution)."""
        m = self.m
        c = self.c
        n = self.n
        i = self.i
        if i < n:
            piv = m[i * n + i]
            if piv <= self.floor[i] or piv <= 0:
                return True
            for j in range(i + 1, n):
                mul = (m[j * n + i] << MUL_Q) // piv
                if mul:
                    for k in range(i + 1, n):
                        m[j * n + k] -= (mul * m[i * n + k]) >> MUL_Q
                    c[j] -= (mul * c[i]) >> MUL_Q
            self.i = i + 1
            return False
        # Back substitution: y in units of 2**-MUL_Q, then x_k = y_k * 2**(e - MUL_Q - s_k).
        y = self.y
        i = n - 1
        while i >= 0:
            acc = c[i] << MUL_Q
            for k in range(i + 1, n):
                acc -= m[i * n + k] * y[k]
            y[i] = acc // m[i * n + i]
            i -= 1
        x = self.x
        for k in range(n):
            x[k] = _shr(y[k], MUL_Q - self.e + self.s[k])
        self.ok = True
        return True
