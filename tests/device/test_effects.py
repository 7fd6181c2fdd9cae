"""The effects' integer application (device/acal/core/effects.py) against the host's float form
(host/accelcal/model/effects.py, the same first-order model), bit-identical under MicroPython, and
inside 2**30 on the per-sample path at the worst case."""
import itertools
from pathlib import Path

import numpy as np
import pytest

from acal.core import effects as deff
from acal.core.fixed import TEMP_Q
from acal.core.fixed import C_TEMP, C_TIME, C_SUPPLY, SOURCES, SOURCE_SUPPLY
from acal.core.bins import COND
from accelcal.model.effects import CATALOGUE, device_effects
from accelcal.bridge.boardlog import model_kinds
from accelcal.bridge.ranges import Tracer, traced
from conftest import effect_orders, relative, run_both
import effects_per_sample
from effects_per_sample import correct_sample

DT_UNIT = deff.DT_UNIT_S
TEMP_ONE = 1 << TEMP_Q   # the device's dT is Q2 degC
SUPPLY_MAX = SOURCES[SOURCE_SUPPLY][2]   # mV: the supply's clamp, its regressor's unit


def inputs(rng, n=400):
    v = rng.uniform(-2.0, 2.0, (n, 3))
    dT = rng.integers(-20 * TEMP_ONE, 20 * TEMP_ONE + 1, n)   # Q2 degC: quarter degrees
    dt = rng.integers(0, 12 * 86400 // DT_UNIT, n)   # inside the generic offsets' clamp
    dV = rng.integers(-SUPPLY_MAX, SUPPLY_MAX + 1, n)   # mV, inside the clamp
    return v, dT, dt, dV


STEP_AT = 5 * 86400 // DT_UNIT    # a step's time in the tests, 64 s units


def rel(dT, dt, dV):
    """The relative conditions (now - ref, the columns fixed.C_*) the effect code reads."""
    d = [0] * COND
    d[C_TEMP], d[C_TIME], d[C_SUPPLY] = dT, dt, dV
    return d


@pytest.mark.parametrize("name", device_effects())
def test_fit_and_apply_forms_match_the_float_model(name, rng):
    e = CATALOGUE[name]
    theta = rng.uniform(-e.bound, e.bound, 3)
    p = e.to_int(theta)
    v, dT, dt, dV = inputs(rng)
    ref = {"T0": 0.0, "t0": 0.0, "ts": STEP_AT * float(DT_UNIT), "supply_mv0": 0.0}
    want = e.correct(v, e.from_int(p), dT / TEMP_ONE, dt * float(DT_UNIT), ref,
                     {"supply_mv": dV.astype(float)})
    k = [0, 0, 0]
    deff.apply_params(e.kind, p, 0, k, 0)
    for (x, y, z), a, b, c_v, w in zip(v, dT, dt, dV, want):
        u = [int(round(c * 2 ** 24)) for c in (x, y, z)]
        deff.correct_u(e.kind, p, 0, u, rel(int(a), int(b), int(c_v)), 0, 0, STEP_AT)
        # Q24: rounding only (the generic offsets' powers: each a floor in Q16)
        assert np.abs(np.array(u) / 2 ** 24 - w).max() < (2e-7 if e.kind not in deff.SHAPES else 5e-6)
        s = [int(round(c * 1024)) for c in (x, y, z)]
        acc = [c << 4 for c in s]
        correct_sample(e.kind, k, 0, acc, s[0], s[1], s[2], rel(int(a), int(b), int(c_v)),
                            STEP_AT)
        # Q14 out, Q10 in (the sample's own rounding, 0.5 mg, is the larger part for q v^2).
        exact = e.correct(np.array([s]) / 1024.0, e.from_int(p), np.array([a / TEMP_ONE]),
                          np.array([b * float(DT_UNIT)]), ref,
                          {"supply_mv": np.array([float(c_v)])})[0]
        assert np.abs(np.array(acc) / 2 ** 14 - exact).max() < 3e-4


@pytest.mark.parametrize("e", [0, 1, 2, 3])
def test_apply_path_stays_small_at_the_worst_case(e):
    # at every full scale (2.048 * 2**e g, readings in Q(14 - e) g: fixed.py "apply")
    tr = Tracer()
    T = traced(tr)
    edge = 2097 << e  # the full scale in Q10
    for kind, sign, temp, far in itertools.product(deff.NAMES, (-1, 1), (-400, 400),
                                                   (0, 10 ** 7, -(10 ** 7))):
        k = [0, 0, 0]
        deff.apply_params(kind, [sign * deff.BOUNDS[kind]] * 3, 0, k, 0)
        for x in (-edge, edge):
            acc = [T(x << (4 - e))] * 3
            correct_sample(kind, [T(c) for c in k], 0, acc, T(x), T(x), T(x),
                                rel(T(temp), T(far), T(far // 100)), T(0), e)   # supply past its clamp too
    assert tr.ops > 100 and tr.max_abs < 2 ** 30, tr.max_abs


@pytest.mark.parametrize("name", device_effects())
def test_apply_form_at_larger_full_scales_matches_the_float_model(name, rng):
    """The per-sample form at +-4, 8 and 16 g (readings in Q(14 - e) g, each product shifted e
    bits further) against the float model, to the coarser format's rounding."""
    e_ = CATALOGUE[name]
    theta = rng.uniform(-e_.bound, e_.bound, 3)
    p = e_.to_int(theta)
    k = [0, 0, 0]
    deff.apply_params(e_.kind, p, 0, k, 0)
    ref = {"T0": 0.0, "t0": 0.0, "ts": STEP_AT * float(DT_UNIT), "supply_mv0": 0.0}
    for e in (1, 2, 3):
        v, dT, dt, dV = inputs(rng, 100)
        s = np.rint(v * (1 << e) * 1024).astype(int)     # across the full scale
        want = e_.correct(s / 1024.0, e_.from_int(p), dT / TEMP_ONE, dt * float(DT_UNIT), ref,
                          {"supply_mv": dV.astype(float)})
        for row, a, b, c_v, w in zip(s.tolist(), dT.tolist(), dt.tolist(), dV.tolist(), want):
            acc = [c << (4 - e) for c in row]
            correct_sample(e_.kind, k, 0, acc, row[0], row[1], row[2], rel(a, b, c_v), STEP_AT,
                                e)
            # floors in Q(14 - e) and q v^2's in Q(10 - e) g^2: a few LSB of Q(14 - e)
            assert np.abs(np.array(acc) / 2 ** (14 - e) - w).max() < 3e-4 * 2 ** e


SCRIPT = r'''
from acal.core import effects
from acal.core.bins import COND
from acal.core.fixed import C_TEMP, C_TIME, C_SUPPLY
d = [0] * COND
out = []
for kind in sorted(effects.NAMES):
    p = [rnd(effects.BOUNDS[kind]) for _ in range(3)]
    k = [0, 0, 0]
    effects.apply_params(kind, p, 0, k, 0)
    for _ in range(100):
        u = [rnd(1 << 25) for _ in range(3)]
        dT = rnd(160)
        dt = rnd(1 << 15)
        dV = rnd(1500)
        d[C_TEMP], d[C_TIME], d[C_SUPPLY] = dT, dt, dV
        effects.correct_u(kind, p, 0, u, d, 0, 0, 1000)
        x, y, z = rnd(2097), rnd(2097), rnd(2097)
        w = [x << 4, y << 4, z << 4]
        correct_sample(kind, k, 0, w, x, y, z, d, 1000)
        out.append(" ".join(map(str, u + w)))
print("\n".join(out))
'''


def test_micropython_gives_the_same_integers(tmp_path, mp):
    # the per-sample apply (tests' alone: effects_per_sample.py) defined in the script itself
    got, host = run_both(Path(effects_per_sample.__file__).read_text() + SCRIPT, tmp_path, mp)
    from acal.core import effects
    assert got.split() == host.split() and len(got.splitlines()) == 100 * len(effects.NAMES)



EACH_SCRIPT = r"""
from array import array
from acal.core import effects
from acal.core.bins import COND
kinds = sorted(effects.NAMES)
for trial in range(60):
    m = 1 + trial % 4                              # 1..4 effects, any kinds, any order
    ids = array("i", [kinds[rnd(len(kinds) * 8) % len(kinds)] for _ in range(m)])
    offs = array("i", [rnd(1 << 22) for _ in range(3)])   # the offsets' rows >> 8, point_row's
    u = [rnd(1 << 25) for _ in range(3)]
    d = array("i", [rnd(160), rnd(1 << 15), rnd(1500)] + [0] * (COND - 3))
    ts = rnd(1 << 15)
    alone = []
    for k in range(m):                             # one call a kind (the row before)
        a = array("i", u)
        effects.correct_kinds(ids, k, k + 1, offs, 0, a, d, 0, ts, 0)
        alone += list(a)
    each = array("i", u + [7] * (3 * m))
    effects.correct_kinds(ids, 0, m, offs, 0, each, d, 0, ts, -1)
    print(list(each[:3]) == u, " ".join(map(str, alone)), " ".join(map(str, each[3:])))
"""


def test_each_kind_alone_in_one_call_is_one_call_a_kind(tmp_path):
    """correct_kinds with clamp < 0 (normal_sums.point_row's effect columns in one call): kind i's
    result from the reading as given, with the same three parameters, lands in reading[3 + 3 i:]
    and equals a call with that kind alone, for every kind (forms, sources, a step) in models of
    1-4 effects; the reading's first three ints are left as they were; CPython and the real
    MicroPython give the same integers."""
    got, host = run_both(EACH_SCRIPT, tmp_path)
    assert got == host and len(host.splitlines()) == 60
    for line in host.splitlines():
        same, rest = line.split(" ", 1)
        ints = rest.split()
        assert same == "True" and ints[:len(ints) // 2] == ints[len(ints) // 2:], line

def test_apply_stays_small_in_every_composition_and_order():
    """The per-sample apply of a composed model (calibration.Calibration) at the worst case: every
    set of effects in every order (conftest.effect_orders) at every full scale, parameters at the
    corners of their bounds and of the calibration bounds, readings at and past full scale
    (+-2.048 * 2**e g), dT and dt at and past their clamps
    (a drift removed over years, then temp_scale multiplying what is left): below 2**30."""
    from acal.core import calibration
    from acal.core.calibration import Calibration
    tr = Tracer()
    T = traced(tr)
    base = [20971520] * 3 + [2097152] * 3 + [4194304] * 3   # k 1.25, k_ij 0.125, o 0.25 g
    calibration.int = lambda v: v   # viper's cast in _apply_composed: the traced ints pass
    try:
        # +-2 and +-16 g: the readings' bound is one at every range, and of the products that
        # change with it only q v^2's grows, largest at 16 g (test_apply_path_stays_small_at_the_
        # worst_case runs every range, effect by effect)
        for order, range_g, sign in itertools.product(effect_orders(), (2, 16), (-1, 1)):
            cal = Calibration(order, range_g)
            p = [sign * v if i >= 3 else v for i, v in enumerate(base)]
            p += [sign * deff.BOUNDS[k] for k in order for _ in range(3)]
            cal.set(p, None, -sign * 10)      # a step on either side of the reference
            cal.k = [T(v) for v in cal.k]
            cal.w = [0, 0, 0]                 # lists: what is stored there stays traced
            cal.terms = [0] * len(cal.terms)
            for temp, time, supply in ((-400, -(10 ** 7), -(10 ** 6)), (400, 10 ** 7, 10 ** 6),
                                       (5, 3, 7)):
                cal.now[C_TEMP], cal.now[C_TIME], cal.now[C_SUPPLY] = T(temp), T(time), T(supply)
                for x in (-2097 << cal.e, 16383):   # at and past the full scale (clamped)
                    cal.apply(T(x), T(-x), T(x))
                    assert max(abs(cal.x), abs(cal.y), abs(cal.z)) <= 28236   # an int16
    finally:
        del calibration.int
    assert tr.ops > 10000 and tr.max_abs < 2 ** 30, tr.max_abs


@pytest.mark.parametrize("name", device_effects())
def test_the_host_and_device_bounds_are_one_bound(name):
    """Each effect's fit bound is declared on the host (float, its unit) and on the device (Q24 per
    normalised regressor): the two must be the same number."""
    e = CATALOGUE[name]
    assert deff.NAMES[e.kind] == name
    assert e.to_int([e.bound])[0] == deff.BOUNDS[e.kind]
    assert set(deff.NAMES.values()) == {n for n in device_effects() if not CATALOGUE[n].declared_in}


def test_effect_kinds_fit_the_logs_model_field():
    """The log packs a model as 4 bits per effect into BOOT's 16-bit field: every id fits
    KIND_MAX, the longest model round-trips, and past either limit model_code refuses rather
    than wrap.  is_generic() is the one test of a generic offset: exactly SHAPES's kinds."""
    import struct
    from acal.core import effects as E
    from acal.logger import log
    assert all(0 < k <= E.KIND_MAX == (1 << E.KIND_BITS) - 1 for k in E.NAMES)
    longest = tuple(sorted(E.NAMES)[-E.MODEL_EFFECTS_MAX:])
    code = E.model_code(longest)
    assert model_kinds(code) == longest
    struct.pack(log.FORMATS[log.BOOT][-3:-1], code, 0)          # the field holds it
    with pytest.raises(ValueError):
        E.model_code(tuple(sorted(E.NAMES)[:E.MODEL_EFFECTS_MAX + 1]))
    with pytest.raises(ValueError):
        E.model_code((E.KIND_MAX + 1,))
    assert {k for k in E.NAMES if E.is_generic(k)} == set(E.SHAPES)
    assert not any(E.is_generic(k) for k in (E.TEMP_OFFSET, E.TEMP_SCALE, E.DRIFT, E.NONLINEAR,
                                             E.TEMP_OFFSET2))


def test_an_effect_of_an_existing_form_is_one_table_row(rng):
    """Issue 48: a kind the package does not have - an offset in the square of the board's supply
    (id 13) - declared by one row of effects.EFFECTS and nothing else is parsed, fitted (the fit's
    form, its viper copy, a composed Gauss-Newton fit of simulated points) and applied (the
    block's viper loop, the host twin) through the table, each against the float form
    v - theta (dV / 1024)^2."""
    from array import array
    from acal.core.calibration import Calibration
    from acal.core.gaussnewton import GaussNewton
    from accelcal import simulate
    from accelcal.bridge import twin
    new = 13
    deff.EFFECTS[new] = ("supply_offset2", deff.SOURCE_SUPPLY, 2, deff.FORM_OFFSET, 0, 8, 4, 0,
                         deff.GENERIC_BOUND)
    deff.tables()
    try:
        assert deff.parse_model("base+supply_offset2") == (new,)
        assert model_kinds(deff.model_code((new,))) == (new,)
        theta = np.array([0.03, -0.02, 0.04])                 # g per (dV / 1024)^2
        p = [int(round(c * 2 ** 24)) for c in theta]
        dV = rng.integers(-1024, 1025, 300)
        v = rng.uniform(-1.5, 1.5, (300, 3))
        x2 = ((dV / 1024.0) ** 2)[:, None]
        for row, d, w in zip(v, dV.tolist(), v - theta * x2):     # the fit's form, Q24
            u = [int(round(c * 2 ** 24)) for c in row]
            a = array("i", u)
            deff.correct_u(new, p, 0, u, rel(0, 0, d), 0, 0, 0)
            deff.correct_kinds(array("i", [new]), 0, 1, array("i", p), 0, a,
                               array("i", rel(0, 0, d)), 0, 0, 0)
            assert list(a) == u and np.abs(np.array(u) / 2 ** 24 - w).max() < 2e-6
        ident = [1 << 24] * 3 + [0] * 6
        cal = Calibration((new,))                              # the apply: a block per dV
        cal.set(ident + p)
        q = np.rint(v * 1024).astype(int)
        got = []
        for row, d in zip(q.tolist(), dV.tolist()):
            cal.now[C_SUPPLY] = d
            cal.apply(*row)
            got.append((cal.x, cal.y, cal.z))
        got = np.array(got)
        assert np.array_equal(got, twin.apply_params(ident + p, q, (new,), relative(len(q), 0, 0, dV)))
        assert np.abs(got / 2 ** cal.out_q - (q / 1024 - theta * x2)).max() < 3e-4
        n = 36                                                  # the fit, on simulated points
        truth = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
        dv = rng.integers(-1000, 1001, n)
        pts = simulate.uncorrect(truth, simulate.unit_points(rng, n)) + \
            theta * ((dv / 1024.0) ** 2)[:, None] + rng.normal(scale=0.0005, size=(n, 3))
        gn = GaussNewton(n, kinds=(new,), reject=False)
        from acal.core.status import OK
        assert gn.run(np.rint(pts * 65536).astype(int).ravel().tolist(), n, 20,
                      [c for d in dv.tolist() for c in (0, 0, d)]) == OK
        # 0.03-0.04 g recovered to ~1 mg (0.5 mg noise on 36 points)
        assert np.abs(np.array(gn.p[9:12]) / 2 ** 24 - theta).max() < 0.004, gn.p[9:12]
    finally:
        del deff.EFFECTS[new]
        deff.tables()
    assert new not in deff.NAMES


def test_the_globals_table_has_room(tmp_path):
    """MicroPython grows a module's globals table only when it is full (py/map.c: ... 73, 97
    slots), and a lookup probes on to the name's slot or an empty one: effects' table, which the
    fit's effect code reads per point, is grown to at least ROOM_NAMES names (97 slots) at the
    module's end on the real interpreter, whatever the table above it declares."""
    from accelcal.bridge import runtime
    f = tmp_path / "room.py"
    f.write_text("from acal.core import effects\nprint(len(effects.__dict__), effects.ROOM_NAMES)\n")
    names, room = map(int, runtime.run_micropython_script(str(f)).split())
    assert room == 74 and 74 <= names < 97, names
