# Physical effects beyond the paper's 9 parameters, in integers: their application on the device.
# host/accelcal/model/effects.py declares each effect once for the host (names, units, bounds,
# physics, plots) and converts its parameters to and from the integers here.
#
# An effect is removed from a reading v (g) before the 9-parameter correction a = K (w + o):
#   TEMP_OFFSET  w = v - c dT          dT: degC from the model's reference temperature
#   TEMP_OFFSET2 w = v - e dT^2        the zero-g level's curvature in temperature
#   TEMP_SCALE   w = v - s dT v        (first order: (s dT)^2 < 1e-4 of the reading)
#   DRIFT        w = v - d dt          dt: time from the model's reference time
#   NONLINEAR    w = v - q v^2         per axis, v^2 with its sign lost (a quadratic response)
# and the generic offsets, w = v - p x with a regressor x the device computes (SHAPES below):
#   STEP         x = [dt >= ts]        the offsets jump once, at ts (a shock); ts is found by
#                                      acal/core/changepoint.py and kept beside the parameters
#   TIME_OFFSET2..4   x = (dt / 2**13)^2..4     the offset ageing along a curve in time
#   TEMP_OFFSET3..4   x = (dT / 16)^3..4        higher powers of temperature
#   SUPPLY_OFFSET     x = dV / 1024             an integer the board supplies (its supply in mV:
#                                               the zero-g level following the battery)
# Three parameters per effect (x, y, z), in this order.
#
# Formats.  dT: Q2 degC (fixed.TEMP_Q: quarter degrees).  dt: int, units of 64 s (DT_UNIT_S).
#   dV: int mV from the reference.
#   Fit (Q24 g readings u, model.objective): every parameter in Q24 per its normalised regressor -
#   c and s per 16 degC, e per 64 degC^2, d per 2048 dt units (131 072 s, 1.52 days), q per g - so
#   that each is of the size of an offset and takes the offsets' learning rate (the parameters
#   keep these per-degC units whatever the temperature's format: dT's two fraction bits enter
#   the shifts, 2 more per power of dT).
#     c: (c * dT) >> 6;  e: (e * dT^2) >> 10;  s: (((s * dT) >> 6) * u) >> 24;  d: (d * dt) >> 11;
#     q: (q * ((u*u) >> 24)) >> 24
#   With whole degrees fed as dT << 2 every form equals the whole-degree one it replaced.
#   Apply (per sample, Q(14 - e) g readings at range shift e, fixed.py "apply",
#   calibration.Calibration): c, e and d in Q14 (param >> 10), s and q in Q18 (param >> 6), each
#   product shifted e bits further (q's v^2 e bits before it), so that at +-2.048 * 2**e g, |dT| <= 32
#   degC (128 in Q2) and |dt| < 2**20 units (776 days; both clamped) and inside BOUNDS every product stays
#   below 2**30 at every full scale (tests/device/test_effects.py runs the worst case).
#   The generic offsets (regressor()): x in Q16, from dT clamped to +-32 degC (dT / 16 is
#   dT << 10 in Q16 from Q2; x <= 2**20 for (dT/16)^4), dt clamped to +-GENERIC_TIME_MAX (2**14 units, 12.1 days: (dt/2**13)^4 <= 16)
#   or dV clamped to +-1024 mV (fixed.SOURCES: x <= 2**16);
#   p per unit x in Q24, bounded by 0.05 g; fit u -= floor(p x 2**-16) (wide), apply with p in
#   Q16 (param >> 8) and x in Q12 (x >> 4): w -= (k x) >> (14 + e), k x < 2**28 at the bound.
#   The fit form keeps below 2**30 too (the default profile's fit allocates nothing on a 32-bit
#   port): for readings |u| <= 2.048 g (model.FIT_W_MAX, clamped), |dT| <= 32 degC, |dt| <=
#   FIT_TIME_MAX and parameters within 4x BOUNDS (the fit region: c dT <= 5.4e6 * 128 < 2**30) - or, for the Jacobian rows of
#   gaussnewton.py, parameters below 2**22 - the wide products go through acal/core/wide.py, whose
#   floors equal the plain (a * b) >> s.
from acal.core.wide import mul_shift
# the sources of the regressors and their SOURCES rows stand with their columns (fixed.py
# "conditions"): a board quantity's is there, its effect's row here
from acal.core.fixed import (TEMP_DT_MAX, SOURCES, SOURCE_TEMP, SOURCE_TIME, SOURCE_STEP,
                             SOURCE_SUPPLY)
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from array import array
try:
    from micropython import const
except ImportError:
    def const(x):
        return x

# The forms (what an effect does to a reading u, the fit's and the apply's alike) and the sources
# of their regressors.
FORM_OFFSET = const(1)      # u -= p x            x: the regressor, from its source to its power
FORM_SCALE = const(2)       # u -= (p x) u        a gain (first order)
FORM_NONLINEAR = const(3)   # u -= p u^2          per axis, u^2 with its sign lost
SOURCE_READING = const(0)   # the reading itself (FORM_NONLINEAR); the others: fixed.SOURCES
GENERIC_TIME_MAX = const(16384)   # dt units (12.1 days) either side of the reference
GENERIC_TIME_SHIFT = const(13)    # the time regressor's unit: 2**13 dt units (6.07 days)
GENERIC_BOUND = const(838861)     # 0.05 g per unit of x, Q24
DT_UNIT_S = const(64)
APPLY_DT_MAX = TEMP_DT_MAX        # Q2 degC (32 degC) either side of the reference
APPLY_TIME_MAX = const(1048575)   # dt units
FIT_TIME_MAX = const(262143)      # dt units (194 days) in the fit: d dt stays below 2**29
_G = GENERIC_TIME_MAX
TEMP_OFFSET = const(1)
TEMP_SCALE = const(2)
DRIFT = const(3)
NONLINEAR = const(4)
TEMP_OFFSET2 = const(5)
STEP = const(6)
TIME_OFFSET2 = const(7)
TIME_OFFSET3 = const(8)
TIME_OFFSET4 = const(9)
TEMP_OFFSET3 = const(10)
TEMP_OFFSET4 = const(11)
SUPPLY_OFFSET = const(12)

# THE TABLE: every effect kind, declared once; the fit (correct_u, correct_kinds), the apply
# (block_terms), the host (accelcal/model/effects.py device_kind, bridge/twin.py) and the log
# (model_code) read it and switch on the form, never on the kind.  A row:
#   id: (name, source, power, form, post, ps, rs, reach, bound)
# The regressor x, Q16 (regressor()): the source clamped, as dT / 16 (dT << 10), dt / 2**13
# (dt << 3) or dV / 1024 (dV << 6) - a step 1.0 (65536) from ts on - raised to `power` (each
# power an exact floor, wide.mul_shift), then << post.  Fit (Q24, u in Q24 g): offset
# u -= floor(p x 2**-16), scale u -= floor(floor(p x 2**-16) u 2**-24), nonlinear as the formats
# say.  Apply: k = p >> ps (rounded), r = x >> rs (an exact int: dT, dT^2, dt or Q12), and the
# terms block_terms makes from them.  reach: a time source's clamp (fit, apply), dt units.
# bound: |p| in Q24 (per normalised regressor; host: model/effects.py's float bound, one number).
# Adding an effect of an existing form is one row here (a free id <= KIND_MAX: the log's
# 4 bits) plus its host declaration (model/effects.py CATALOGUE) and its test.
EFFECTS = {
    TEMP_OFFSET: ("temp_offset", SOURCE_TEMP, 1, FORM_OFFSET, 0, 10, 10, 0, 1342177),  # 5 mg/degC
    TEMP_SCALE: ("temp_scale", SOURCE_TEMP, 1, FORM_SCALE, 0, 6, 10, 0, 536871),      # 0.2 %/degC
    DRIFT: ("drift", SOURCE_TIME, 1, FORM_OFFSET, 2, 10, 5, (FIT_TIME_MAX, APPLY_TIME_MAX),
        509033),                                                             # 20 mg/day
    NONLINEAR: ("nonlinear", SOURCE_READING, 2, FORM_NONLINEAR, 0, 6, 0, 0, 838861),  # 5 %/g
    TEMP_OFFSET2: ("temp_offset2", SOURCE_TEMP, 2, FORM_OFFSET, 2, 10, 6, 0, 1073742),   # 1 mg/degC^2
    STEP: ("step", SOURCE_STEP, 1, FORM_OFFSET, 0, 8, 4, 0, GENERIC_BOUND),
    TIME_OFFSET2: ("time_offset2", SOURCE_TIME, 2, FORM_OFFSET, 0, 8, 4, (_G, _G), GENERIC_BOUND),
    TIME_OFFSET3: ("time_offset3", SOURCE_TIME, 3, FORM_OFFSET, 0, 8, 4, (_G, _G), GENERIC_BOUND),
    TIME_OFFSET4: ("time_offset4", SOURCE_TIME, 4, FORM_OFFSET, 0, 8, 4, (_G, _G), GENERIC_BOUND),
    TEMP_OFFSET3: ("temp_offset3", SOURCE_TEMP, 3, FORM_OFFSET, 0, 8, 4, 0, GENERIC_BOUND),
    TEMP_OFFSET4: ("temp_offset4", SOURCE_TEMP, 4, FORM_OFFSET, 0, 8, 4, 0, GENERIC_BOUND),
    SUPPLY_OFFSET: ("supply_offset", SOURCE_SUPPLY, 1, FORM_OFFSET, 0, 8, 4, 0, GENERIC_BOUND),
}
# The log packs a model as KIND_BITS per effect into BOOT's 16-bit model field (model_code):
# ids 1..KIND_MAX (three are left after SUPPLY_OFFSET) and at most MODEL_EFFECTS_MAX effects.
KIND_BITS = const(4)
KIND_MAX = const(15)
MODEL_EFFECTS_MAX = const(4)
X_Q = const(12)                   # the generic regressor's format
# The table's rows as ints for the code that runs per point (correct_kinds, regressor): a kind's
# _ROW ints at _ROWS[_ROW * kind] (an int32 array, below) - its bytes (_R_BYTES: form << 6 |
# source << 3 | power, then the post shift, the source's column and its shift (SOURCES), a
# byte each from the low one) and its clamp on the source's value in the fit (_R_REACH: the
# time reach); the apply's clamp in _REACH_APPLY (regressor).  One array, not one a field:
# correct_kinds takes a global and a typed pointer a call (each ~2 us on the emulated Pico).
# Defined before their first use: MicroPython folds a const only below its definition.
_ROW = const(2)
_R_BYTES = const(0)
_R_REACH = const(1)
# What the rest of the package reads, derived from the table (tables(): again after a row is
# added at run time, as a test does): the names, the bounds, and the generic offsets' shapes -
# (source, power) of the offsets whose parameter is per unit of the Q16 regressor (rs 4: apply
# in Q12), which a declared effect of that shape runs as (host: model/effects.py device_kind).
NAMES = {}
BOUNDS = {}
SHAPES = {}


def is_generic(kind):
    """True for a generic offset (SHAPES: a regressor from a source, to a power), the kinds
    regressor() serves; the one test of it (a new kind is generic by its entry in SHAPES)."""
    return kind in SHAPES


def condition_of(kind):
    """The condition an effect's regressor reads, its column in a point's conditions (bins.COND,
    fixed.C_*: a step's is the time's; -1 none, NONLINEAR): with bins.DIFFERS, the threshold
    question that pipeline.spanned asks of the bins' points and discover.testable of the fit
    points."""
    source = EFFECTS[kind][1]
    return SOURCES[source][0] if source in SOURCES else -1


def uses_source(kinds, source):
    """True when a model has a generic offset whose regressor comes from `source`."""
    for k in kinds:
        if is_generic(k) and SHAPES[k][0] == source:
            return True
    return False


def time_from_first(kinds):
    """True when a model's reference time is its earliest point's rather than the middle of
    their range: a power of time above 1 has an origin (ageing since the recording began) that
    moving the reference would turn into a linear part the model may lack."""
    return uses_source(kinds, SOURCE_TIME)


def parse_model(spec):
    """'base' or 'base+NAME+...' (NAMES) -> the effect ids in order; ValueError otherwise."""
    parts = spec.split("+")
    if parts[0] != "base":
        raise ValueError("a model is 'base' or 'base+EFFECT+...': " + spec)
    kinds = []
    for name in parts[1:]:
        kind = 0
        for k in NAMES:
            if NAMES[k] == name:
                kind = k
        if not kind or kind in kinds:
            raise ValueError("unknown or repeated effect in " + spec + ": " + name)
        kinds.append(kind)
    return tuple(kinds)


def model_code(kinds):
    """The effect ids as one int for the log: kinds[i] in bits 4i..4i+3; ValueError past
    MODEL_EFFECTS_MAX effects or an id past KIND_MAX (the log's field would wrap).  Its inverse
    is the host's (accelcal/model/effects.py model_kinds): a board never reads a model code."""
    if len(kinds) > MODEL_EFFECTS_MAX:
        raise ValueError("the log holds a model of at most 4 effects")
    code = 0
    for i in range(len(kinds)):
        if not 0 < kinds[i] <= KIND_MAX:
            raise ValueError("an effect id the log cannot hold")
        code |= kinds[i] << (KIND_BITS * i)
    return code


def regressor(kind, d, da, ts, fit=True):
    """An offset's or a scale's regressor x (Q16, |x| <= 2**25) at the relative conditions
    d[da:da + bins.COND] (now - ref by column: dT Q2 degC, dt 64 s units, dV mV...), with a step
    at ts (64 s units, as dt): the table's row and its source's (SOURCES), clamped as the formats
    above say (a time source to its reach in the fit, or in the apply: fit False); each power an
    exact floor (acal/core/wide.py)."""
    row = EFFECTS[kind]
    t = _ROW * kind
    b = _ROWS[t + _R_BYTES]
    v = d[da + ((b >> 16) & 255)]
    if row[1] == SOURCE_STEP:
        return 65536 if v >= ts else 0
    clamp = _ROWS[t + _R_REACH] if fit else _REACH_APPLY[kind]
    if v > clamp:
        v = clamp
    elif v < -clamp:
        v = -clamp
    base = v << (b >> 24)
    x = base
    for _ in range(row[2] - 1):
        x = mul_shift(x, base, 16)        # <= 2**20
    return x << row[4]


def correct_u(kind, p, j, u, d, da=0, at=0, ts=0):
    """Remove effect `kind` (parameters p[j:j+3], Q24) from the reading u[at:at+3] (Q24 g) in
    place; the fit's form, by the table's form.  d[da:da + bins.COND]: the relative conditions
    (regressor), clamped as the apply clamps them (a time source to its fit reach: see the
    formats above); ts: a step's time (as dt).  Every intermediate stays below 2**30
    (acal/core/wide.py)."""
    form = EFFECTS[kind][3]
    if form == FORM_NONLINEAR:
        for i in range(3):
            v = u[at + i]
            u[at + i] = v - mul_shift(p[j + i], mul_shift(v, v, 24), 24)
        return
    x = regressor(kind, d, da, ts)
    for i in range(3):
        g = mul_shift(p[j + i], x, 16)
        if form == FORM_SCALE:
            g = mul_shift(g, u[at + i], 24)
        u[at + i] -= g


def apply_params(kind, p, j, k, m):
    """The per-sample form of parameters p[j:j+3] (Q24) into k[m:m+3]: p >> ps, rounded."""
    shift = EFFECTS[kind][5]
    half = 1 << (shift - 1)
    for i in range(3):
        k[m + i] = (p[j + i] + half) >> shift


# The apply's forms: what an effect does to a reading w (Q(14 - e) g) once the block's relative
# conditions (constant within a block, the feeder sets them per block) are known,
# with three per-axis terms a (block_terms), k = p >> ps and r = x >> rs:
#   FORM_OFFSET     w -= a = (k r) >> (26 - ps - rs + e)     the offset, Q(14 - e) g
#   FORM_SCALE      w -= (a w) >> 18, a = (k r) >> (22 - ps - rs)   the gain, Q18
#   FORM_NONLINEAR  w -= (a ((s s) >> (10 + e))) >> 14, a = k (Q18 per g), s the reading (Q10 g)
# Each a is the very integer the per-sample form made, so the block's apply is bit-identical to it.


def block_terms(kind, k, m, out, at, d, ts=0, e=0):
    """Effect `kind`'s form and terms (per-sample parameters k[m:m+3]) at the relative conditions
    d (now - ref, bins.COND columns: regressor) and the step's time ts, into out[at] (the form)
    and out[at+1:at+4] (the terms, above), at the full scale's shift e; clamped as the formats
    say."""
    row = EFFECTS[kind]
    form = row[3]
    if form == FORM_NONLINEAR:
        r, s = 1, 0
    else:
        r = regressor(kind, d, 0, ts, False) >> row[6]
        s = (26 + e if form == FORM_OFFSET else 22) - row[5] - row[6]
    out[at] = form
    for i in range(3):
        out[at + 1 + i] = (k[m + i] * r) >> s


# correct_u's integers for the default fit, viper on ports with emitters (acal/core/emit.py):
# _ROWS (above), made by tables() with the names, bounds and shapes above.
_ROWS = array("i", bytearray(4 * _ROW * (KIND_MAX + 1)))
_REACH_APPLY = array("i", bytearray(4 * (KIND_MAX + 1)))


def tables():
    """NAMES, BOUNDS, SHAPES and the viper fit's codes, from EFFECTS and SOURCES (at import;
    again after a row is added at run time)."""
    NAMES.clear()
    BOUNDS.clear()
    SHAPES.clear()
    for k in range(KIND_MAX + 1):
        _ROWS[_ROW * k + _R_BYTES] = 0
    for k in EFFECTS:
        name, source, power, form, post, ps, rs, reach, bound = EFFECTS[k]
        NAMES[k] = name
        BOUNDS[k] = bound
        if form == FORM_OFFSET and rs == 4:
            SHAPES[k] = (source, power)
        t = _ROW * k
        # the source's column, shift and clamp (regressor's; correct_kinds' the fit's): a clamp
        # of 0 in SOURCES is the row's reach, in the fit and in the apply
        column, shift, clamp = SOURCES[source] if source in SOURCES else (0, 0, 0)
        _ROWS[t + _R_BYTES] = ((form << 6) | (source << 3) | power | (post << 8) | (column << 16)
                               | (shift << 24))
        _ROWS[t + _R_REACH] = clamp or (reach[0] if reach else 0)
        _REACH_APPLY[k] = clamp or (reach[1] if reach else 0)


tables()


@viper
def correct_kinds(kind_ids, k0: int, k: int, params, j: int, reading, cond, cj: int, ts: int,
                  clamp: int):
    # Remove the effects kind_ids[k-1], ..., kind_ids[k0] (an int32 array of ids: the last
    # first, the reverse of the order they act in) from the reading (an int32 array of 3, Q24
    # g) in place, the parameters of kind_ids[i] at params[j + 3 (i - k0)] (an int32 array), at
    # the relative conditions cond[cj:cj + bins.COND] (an int32 array, regressor's d); after
    # each, the reading clamped to +-clamp when clamp > 0 (model.remove_effects' FIT_W_MAX).
    # clamp < 0: each kind alone instead (a Jacobian row's effect columns: normal_sums.point_row),
    # every one from the reading as given with the same parameters params[j:j + 3], kind_ids[i]'s
    # result into reading[3 + 3 (i - k0):6 + 3 (i - k0)] (reading then holds 3 + 3 (k - k0)
    # ints; its first three are left as they were): the values of k - k0 calls of one kind
    # each, in one call (a call's fixed cost, ~23 us on the emulated Pico, once).  The
    # integers of correct_u, by the table's form (tests/device/test_effects.py checks them against
    # it), each wide.mul_shift written out: P16(a, b) = mul_shift(a, b, 16) (t = 1) and P24 (t = 9);
    # every value below 2**30 as correct_u's (tests/device/test_ranges.py).
    ids = ptr32(kind_ids)
    p = ptr32(params)
    u = ptr32(reading)
    d = ptr32(cond)
    rows = ptr32(_ROWS)
    w = int(SIGN_SHIFT)
    each = clamp < 0
    if each:
        clamp = 0
    o = 0           # where the kind's result goes (each: its own three ints)
    at = j
    while k > k0:
        k -= 1
        kind = int(ids[k]) << w >> w
        if each:
            o = 3 + 3 * (k - k0)
        else:
            at = j + 3 * (k - k0)
        t = _ROW * kind
        row = int(rows[t + _R_BYTES])
        code = row & 255
        form = code >> 6
        source = (code >> 3) & 7
        x = 0
        if source != 0:                      # a condition's column (SOURCES), relative
            v = int(d[cj + ((row >> 16) & 255)]) << w >> w
            if source == 3:                  # SOURCE_STEP
                x = 65536 if v >= ts else 0
            else:                            # clamped and to Q16 as regressor
                r = int(rows[t + _R_REACH])
                if v > r:
                    v = r
                elif v < 0 - r:
                    v = 0 - r
                base = v << (row >> 24)
                x = base
                bh = base >> 15
                bl = base & 0x7FFF
                n = (code & 7) - 1
                while n > 0:
                    ah = x >> 15
                    al = x & 0x7FFF
                    m = ah * bl + al * bh
                    x = ((ah * bh) << 14) + (m >> 1) + (((m & 1) + ((al * bl) >> 15)) >> 1)
                    n -= 1
                x = x << ((row >> 8) & 255)
        bh = x >> 15
        bl = x & 0x7FFF
        c = 0
        while c < 3:
            a = int(p[at + c]) << w >> w
            r = int(u[c]) << w >> w
            if form == 3:                    # FORM_NONLINEAR: r - P24(a, P24(r, r))
                rh = r >> 15
                rl = r & 0x7FFF
                m = rh * rl + rl * rh
                s = ((rh * rh) << 6) + (m >> 9) + (((m & 511) + ((rl * rl) >> 15)) >> 9)
                ah = a >> 15
                al = a & 0x7FFF
                sh = s >> 15
                sl = s & 0x7FFF
                m = ah * sl + al * sh
                r -= ((ah * sh) << 6) + (m >> 9) + (((m & 511) + ((al * sl) >> 15)) >> 9)
            else:                            # g = P16(a, x); FORM_SCALE: r - P24(g, r)
                ah = a >> 15
                al = a & 0x7FFF
                m = ah * bl + al * bh
                g = ((ah * bh) << 14) + (m >> 1) + (((m & 1) + ((al * bl) >> 15)) >> 1)
                if form == 2:
                    ah = g >> 15
                    al = g & 0x7FFF
                    rh = r >> 15
                    rl = r & 0x7FFF
                    m = ah * rl + al * rh
                    g = ((ah * rh) << 6) + (m >> 9) + (((m & 511) + ((al * rl) >> 15)) >> 9)
                r -= g
            if clamp:
                if r > clamp:
                    r = clamp
                elif r < 0 - clamp:
                    r = 0 - clamp
            u[o + c] = r
            c += 1


# Room in this module's globals table, at the module's end: MicroPython fills a table to its last
# slot before it grows it (73, 97 ... slots), and a name looked up there probes on to its slot or
# an empty one.  At 69 names in 73 slots the discovery's longest fit step, whose effect code read
# five of these globals per call (correct_kinds reads one now, _ROWS: not re-measured), took
# 10 % longer on the emulated Pico than at 74 in 97: the table is
# grown to 97 slots here whatever the names above number (docs/notes/boards-and-logs.md "Every
# module's heap"; tests/device/test_effects.py test_the_globals_table_has_room).
ROOM_NAMES = 74   # names that make the table 97 slots
_ROOM = ROOM_NAMES - len(globals())
while _ROOM > 0:
    globals()["_room%d" % _ROOM] = None
    _ROOM -= 1
