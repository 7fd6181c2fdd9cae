"""acal/wide.py, the products and quotients the default profile's fit needs past 2^30, against
CPython's exact integers: random operands over the whole domain and its edges, and the same
integers, with the heap locked, on the 32-bit MicroPython (where any int past 2^30 would
allocate)."""
import random

from acal.wide import div_shift, mul_shift

LIM = 1 << 29


def mul_cases(n, seed=1):
    rnd = random.Random(seed)
    edges = [0, 1, -1, LIM - 1, -(LIM - 1), 0x7FFF, -0x8000, 1 << 15, -(1 << 15)]
    out = []
    for s in (16, 17, 24, 26, 29, 30, 31, 40, 58):
        for a in edges:
            for b in edges:
                if abs((a * b) >> s) < LIM:
                    out.append((a, b, s))
    while len(out) < n:
        s = rnd.randint(16, 60)
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
from acal.wide import mul_shift, div_shift
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
