"""acal/core/wide.py, the products and quotients the default profile's fit needs past 2^30, against
CPython's exact integers: random operands over the whole domain and its edges, and the same
integers, with the heap locked, on the 32-bit MicroPython (where any int past 2^30 would
allocate)."""
import random

from acal.core.wide import div_shift, mul_shift

LIM = 1 << 29


def mul_cases(n, seed=1):
    rnd = random.Random(seed)
    edges = [0, 1, -1, LIM - 1, -(LIM - 1), 0x7FFF, -0x8000, 1 << 15, -(1 << 15)]
    out = []
    for s in (16, 17, 24, 26, 29, 30, 31, 40, 58, 62, 63, 64, 100):   # s >= 62: a shift by 32+
        for a in edges:
            for b in edges:
                if abs((a * b) >> s) < LIM:
                    out.append((a, b, s))
    while len(out) < n:
        s = rnd.randint(16, 70)
        a = rnd.randint(-LIM + 1, LIM - 1)
        lim = min(LIM - 1, ((LIM - 1) << s) // max(1, abs(a)))
        b = rnd.randint(-lim, lim)
        if abs((a * b) >> s) < LIM:
            out.append((a, b, s))
    return out


def div_cases(n, seed=2):
    rnd = random.Random(seed)
    out = [(LIM - 1, (1 << 26) - 1, 3), (-(LIM - 1), (1 << 26) - 1, 3), (-1, 1, 28), (0, 7, 20),
           (5, (1 << 26) - 1, 0), (-5, 3, 1)]
    while len(out) < n:
        d = rnd.randint(1, (1 << 26) - 1)
        s = rnd.randint(0, 30)
        lim = min(LIM - 1, ((LIM - 1) * d) >> s)
        out.append((rnd.randint(-lim, lim), d, s))
    return out


def test_mul_shift_is_the_exact_floor():
    for a, b, s in mul_cases(100000):
        assert mul_shift(a, b, s) == (a * b) >> s, (a, b, s)


def test_div_shift_is_the_exact_floor():
    for x, d, s in div_cases(100000):
        assert div_shift(x, d, s) == (x << s) // d, (x, d, s)


def test_the_same_integers_without_a_long_on_the_32_bit_port(tmp_path, mp32):
    muls = mul_cases(3000)
    divs = div_cases(3000)
    f = tmp_path / "wide32.py"
    f.write_text(f"""
import micropython
from acal.core.wide import mul_shift, div_shift
M = [int(v) for v in "{' '.join(str(v) for c in muls for v in c)}".split()]
D = [int(v) for v in "{' '.join(str(v) for c in divs for v in c)}".split()]
nm = len(M) // 3
nd = len(D) // 3
out = [0] * (nm + nd)


def work(M, D, out, nm, nd):   # locals only: a new module global would itself allocate
    for i in range(nm):
        out[i] = mul_shift(M[3 * i], M[3 * i + 1], M[3 * i + 2])
    for i in range(nd):
        out[nm + i] = div_shift(D[3 * i], D[3 * i + 1], D[3 * i + 2])


micropython.heap_lock()
try:
    work(M, D, out, nm, nd)
    micropython.heap_unlock()
    print("OK")
except MemoryError:
    micropython.heap_unlock()
    print("ALLOCATED")
print(" ".join([str(v) for v in out]))
""")
    lines = mp32(str(f)).splitlines()
    assert lines[0] == "OK"
    want = [(a * b) >> s for a, b, s in muls] + [(x << s) // d for x, d, s in divs]
    assert [int(v) for v in lines[1].split()] == want


def _rows_from_mul_shift(p, ux, uy, uz):
    # The default fit's residual and Jacobian row as wide.mul_shift composes them (the form
    # model.residual_jacobian writes out for the boards' viper).
    ux += p[6]
    uy += p[7]
    uz += p[8]
    ax = mul_shift(p[0], ux, 24)
    ay = mul_shift(p[3], ux, 24) + mul_shift(p[1], uy, 24)
    az = mul_shift(p[4], ux, 24) + mul_shift(p[5], uy, 24) + mul_shift(p[2], uz, 24)
    r = mul_shift(ax, ax, 26) + mul_shift(ay, ay, 26) + mul_shift(az, az, 26) - (1 << 22)
    ax, ay, az, ux, uy, uz = (v >> 12 for v in (ax, ay, az, ux, uy, uz))
    k = [v >> 12 for v in p[:6]]
    return r, [ax * ux, ay * uy, az * uz, ay * ux, az * ux, az * uy,
               ax * k[0] + ay * k[3] + az * k[4], ay * k[1] + az * k[5], az * k[2]]


def test_fit_rows_are_the_mul_shift_products():
    """model.residual and residual_jacobian (mul_shift written out, for viper) give the integers
    mul_shift gives, over the fit region and the fit's clamp, its corners included."""
    import itertools

    from acal.core import fixed, model
    rnd = random.Random(5)
    w = model.FIT_W_MAX
    kd = (fixed.FIT_K_DIAG_MIN, fixed.FIT_K_DIAG_MAX)
    ko = (-fixed.FIT_K_OFF_MAX, fixed.FIT_K_OFF_MAX)
    oo = (-fixed.FIT_O_MAX, fixed.FIT_O_MAX)
    cases = []
    for _ in range(3000):
        p = [rnd.randint(*kd) for _ in range(3)] + [rnd.randint(*ko) for _ in range(3)] + \
            [rnd.randint(*oo) for _ in range(3)]
        cases.append((p, [rnd.randint(-w, w) for _ in range(3)]))
    for p in itertools.product(kd, kd, kd, ko, ko, ko, oo, oo, oo):
        if rnd.random() < 0.05:
            for u in itertools.product((-w, w), repeat=3):
                cases.append((list(p), list(u)))
    d = [0] * 9
    for p, u in cases:
        r, row = _rows_from_mul_shift(p, *u)
        assert model.residual(p, *u) == r
        assert model.residual_jacobian(p, *u, d) == r and d == row, (p, u)
