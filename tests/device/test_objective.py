"""acal/paper/objective.py, the paper objective and its update in 14-bit limbs, against the long-int
formula it replaces (kept here as the reference, in CPython's exact ints): the same integers on
random and worst-case inputs across the fit region and the points' domain (+-16 g), the formula
outside it; the optimiser run on them the same run as the one on the formula.  Their ranges:
tests/device/test_ranges.py; on the 32-bit port under heap_lock: tests/device/test_heap.py."""
import itertools
from array import array

import numpy as np
import pytest

from acal.core import fixed as F, model
from acal.paper import objective, optimiser
from acal.paper.objective import (BASE, CACHE, GRADIENT, LIMBS, MAX_POINTS, PLAIN, QUOTIENT_MAX,
                            objective_limbs, update)
from acal.paper.optimiser import Optimiser
from accelcal import simulate
from accelcal.fixedpoint import g_to_point

H = F.H_PARAM
U_MAX = 1 << 28      # 16 g in Q24


def to_limbs(v, f, at):
    """An objective (an int >= 0, below 2**73) into limbs f[at:at+LIMBS] (14 bits each, the
    top one holding the rest), as the device's objective() writes them."""
    for j in range(LIMBS - 1):
        f[at + j] = v & 0x3FFF
        v >>= 14
    f[at + LIMBS - 1] = v


def reference(p, u, n):
    """The paper objective as the device computed it before: Python ints, longs past 2**30."""
    total = 0
    for i in range(0, 3 * n, 3):
        ux, uy, uz = u[i] + p[6], u[i + 1] + p[7], u[i + 2] + p[8]
        ax = (p[0] * ux) >> 20
        ay = (p[3] * ux + p[1] * uy) >> 20
        az = (p[4] * ux + p[5] * uy + p[2] * uz) >> 20
        r = (ax * ax + ay * ay + az * az - (1 << 56)) >> 26
        total += (r * r) >> 20
    return total


def limbs(p, u, n, mode=PLAIN, cache=None):
    out = array("i", [0] * (9 * LIMBS))
    cache = out if cache is None else cache
    assert objective_limbs(array("i", u), n, out, 0, array("i", p), mode, cache, 0) == 0
    if mode == GRADIENT:
        return [objective.from_limbs(out, LIMBS * j) for j in range(9)]
    return objective.from_limbs(out, 0)


def region_bounds():
    """Per parameter (lo, hi): the fit region widened by the gradient's step."""
    return ([(F.FIT_K_DIAG_MIN, F.FIT_K_DIAG_MAX + H)] * 3 +
            [(-F.FIT_K_OFF_MAX - H, F.FIT_K_OFF_MAX + H)] * 3 +
            [(-F.FIT_O_MAX - H, F.FIT_O_MAX + H)] * 3)


def test_random_inputs_across_the_fit_region_and_point_domain(rng):
    b = region_bounds()
    for trial in range(4000):
        n = int(rng.integers(0, MAX_POINTS + 1)) if trial % 8 == 0 else int(rng.integers(9, 37))
        lim = int(rng.choice([U_MAX, 1 << 26, 1 << 25, 3 << 22]))   # 16, 4, 2, 0.75 g
        u = [int(x) for x in rng.integers(-lim, lim, 3 * n)]
        p = [int(rng.integers(lo, hi + 1)) for lo, hi in b]
        assert limbs(p, u, n) == reference(p, u, n), (p, u, n)


def test_unit_points_of_a_real_sensor(rng):
    # rest means of sensors inside the paper's error ranges, at parameters near the truth and p0
    for _ in range(200):
        truth, v = simulate.paper_scenario(rng, 36, 5e-3)
        u = [int(c) << 8 for c in g_to_point(v).ravel()]
        p = [int(round(x * F.PARAM_ONE)) for x in truth]
        p0 = [F.PARAM_ONE] * 3 + [0] * 6
        for q in (p, p0):
            assert limbs(q, u, 36) == reference(q, u, 36)


def test_worst_corners():
    # every corner of the widened fit region with points at the domain's extremes, all alike
    # (the largest |a|, r and sums: 128 of them) or mixed
    b = region_bounds()
    ext = (-U_MAX, U_MAX - 1)
    k = 0
    for p in itertools.product(*b):
        p = list(p)
        u = [ext[(k >> j) & 1] for j in range(3)] * MAX_POINTS
        mixed = [ext[(k * 7 + j) % 3 == 0] for j in range(3 * 20)] + [0, 0, 0, 1, -1, 65536 << 8]
        assert limbs(p, u, MAX_POINTS) == reference(p, u, MAX_POINTS)
        assert limbs(p, mixed, 22) == reference(p, mixed, 22)
        k += 1


def test_outside_the_domain_the_formula_answers():
    p = [F.PARAM_ONE] * 3 + [0] * 6
    u = [U_MAX, 0, 0] + [0, U_MAX >> 2, 0] * 8
    out = array("i", [7] * LIMBS)
    assert objective_limbs(array("i", u), 9, out, 0, array("i", p), PLAIN, out, 0) == 2
    wide = list(p)
    wide[0] = F.FIT_K_DIAG_MAX + H + 1
    assert objective_limbs(array("i", u[3:] * 2), 9, out, 0, array("i", wide), PLAIN, out, 0) == 1
    long_p = [1 << 40] + p[1:]
    for q, v in ((p, u), (wide, u[3:] * 2), (long_p, u[3:] * 2)):
        assert model.objective(q, array("i", v), 9) == reference(q, v, 9)
        assert model.objective(q, v, 9) == reference(q, v, 9)   # a list: the formula
    inside = u[3:] * 2
    assert model.objective(p, array("i", inside), 16) == reference(p, inside, 16)


def test_the_gradients_objectives_from_the_cache(rng):
    """The objectives at p + h e_k taken from the one at p (objective_limbs' cache) are the
    formula's, for points of a real sensor and points with |a| past 2 g or |a|^2 far from 1 g^2
    (the limbs' path) mixed in."""
    b = region_bounds()
    for trial in range(300):
        n = int(rng.integers(9, 40))
        u = [int(x) for x in rng.normal(scale=0.58, size=3 * n) * (1 << 24)]
        for i in rng.integers(0, n, int(rng.integers(0, 4))):
            u[3 * i:3 * i + 3] = [int(x) for x in rng.integers(-U_MAX, U_MAX, 3)]
        p = [int(rng.integers(lo, hi - H + 1)) for lo, hi in b]
        if trial % 3 == 0:   # near p0: the shortcuts' domain
            p = [F.PARAM_ONE + int(x) for x in rng.integers(-(1 << 21), 1 << 21, 3)] + \
                [int(x) for x in rng.integers(-(1 << 20), 1 << 20, 6)]
        cache = array("i", [0] * (CACHE * n))
        assert limbs(p, u, n, BASE, cache) == reference(p, u, n)
        want = []
        for k in range(9):
            q = list(p)
            q[k] += H
            want.append(reference(q, u, n))
        assert limbs(p, u, n, GRADIENT, cache) == want, trial


def test_update_is_the_gradient_step(rng):
    """par[k] -= floor(2 alpha[k] (F_k - F) / den) from the objectives' limbs, exactly while a
    step is below 2**27 in size and saturated, with its sign, above; and its verdict on the fit
    region is model.in_fit_region's."""
    import random
    r = random.Random(int(rng.integers(1 << 30)))
    b = region_bounds()
    for trial in range(3000):
        f = array("i", [0] * (10 * LIMBS))
        top = r.choice([1 << 14, 1 << 44, 1 << 60, 1 << 72])
        fs = [r.randrange(top) for _ in range(10)]
        if trial % 3 == 0:
            fs[:9] = [max(0, fs[9] + r.randrange(-(1 << 30), 1 << 30)) for _ in range(9)]
        for k in range(10):
            to_limbs(fs[k], f, LIMBS * k)
        alpha = [r.randrange(512) for _ in range(9)]
        den = r.randrange(1, 1 << 15)
        p = [r.randrange(lo - (1 << 20), hi - H + (1 << 20)) for lo, hi in b]
        par = array("i", p)
        out = update(f, 9 * LIMBS, par, array("i", alpha), 9, den, 0)
        for k in range(9):
            step = (2 * alpha[k] * (fs[k] - fs[9])) // den
            if abs(step) < QUOTIENT_MAX - 2048:
                assert par[k] == p[k] - step, (k, fs, alpha, den)
            else:
                assert p[k] - par[k] == (QUOTIENT_MAX if step > 0 else -QUOTIENT_MAX)
        assert out == (not model.in_fit_region(list(par)))


def reference_run(pts, n, iterations, alphas):
    """The optimiser as it was before the limbs (optimiser.py): the objective and the update in
    Python ints."""
    u = [c << 8 for c in pts[:3 * n]]
    p = [F.PARAM_ONE] * 3 + [0] * 6
    alpha = [alphas[0]] * 3 + [alphas[1]] * 3 + [alphas[2]] * 3
    f0 = start = reference(p, u, n)
    for it in range(1, iterations + 1):
        df = []
        for i in range(9):
            p[i] += H
            df.append(reference(p, u, n) - f0)
            p[i] -= H
        for k in range(9):
            p[k] -= (alpha[k] * F.UPDATE_MUL * df[k]) // (F.ALPHA_DEN * n)
        if not model.in_fit_region(p):
            return optimiser.DIVERGED, it, None, start, p
        f0 = reference(p, u, n)
    status = optimiser.DIVERGED if f0 > start else \
        (optimiser.OK if model.in_bounds(p) else optimiser.OUT_OF_BOUNDS)
    return status, iterations, f0, start, p


@pytest.mark.parametrize("alphas", [(3, 8, 2), (30, 80, 20), (9, 20, 6)])
def test_the_optimiser_runs_as_on_the_formula(rng, alphas):
    """Status, iterations, the objectives and the parameters as the long-int optimiser gives them
    (a diverged run's parameters may differ where a step was past 2**27: they are not a result)."""
    for trial in range(6):
        n = (18, 36)[trial % 2]
        _, v = simulate.paper_scenario(rng, n, (1e-3, 5e-3, 2e-2)[trial % 3])
        pts = [int(c) for c in g_to_point(v).ravel()]
        o = Optimiser(n, alphas)
        status = o.run(pts, n, 50)
        want = reference_run(pts, n, 50, alphas)
        assert (status, o.iterations, o.objective_start) == want[:2] + want[3:4]
        if status != optimiser.DIVERGED or want[2] is not None:
            assert o.objective == want[2] and o.p == want[4]


def test_points_past_16_g_are_refused():
    o = Optimiser(18)
    pts = [65536, 0, 0] * 17 + [1 << 20, 0, 0]
    assert o.run(pts, 18, 50) == optimiser.DIVERGED and o.iterations == 0
    pts[-3] = (1 << 20) - 1
    assert o.run(pts, 18, 5) != optimiser.DIVERGED or o.iterations > 0


def test_limits_refused_where_set():
    with pytest.raises(ValueError):
        Optimiser(MAX_POINTS + 1)
    with pytest.raises(ValueError):
        Optimiser(18, (3, 512, 2))
    o = Optimiser(18)
    assert o.objective == 0 and o.objective_start == 0
    with pytest.raises(AttributeError):
        o.objective_end
