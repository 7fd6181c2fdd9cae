# The calibration applied to raw samples on the board, per sample and without allocating: the
# model of acal/core/model.py (a = K (v + o), a composed model's effects removed first: acal/core/effects.py)
# in the apply's formats (fixed.py "apply"), every product below 2**30 at every full scale.  Two
# viper loops a block: _apply_block (the base model; a single sample goes through it too) and
# _apply_composed (a composed model: the effects by their forms, terms made once per block's
# conditions by effects.block_terms, then the same clamp and products).
from acal.core.fixed import (N_PARAMS, APPLY_FROM_SAMPLE_SHIFT, APPLY_PARAM_SHIFT, APPLY_OUT_SHIFT,
                        APPLY_OUT_Q, APPLY_IN_MAX, APPLY_W_MAX, APPLY_D_Q, APPLY_C_Q, PARAM_Q,
                        PARAM_ONE, apply_range_shift)
from acal.core import effects
from acal.core.wide import mul_shift
from acal.core.bins import int32s, conditions, COND
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from acal.core.model import identity, in_bounds, effects_within


class Calibration:
    """A calibration applied to raw samples, per sample and without allocating.

    range_g: the sensor's full scale (2, 4, 8 or 16 g), shift e (fixed.apply_range_shift).
    set(p) takes Q24 parameters and keeps them in the apply's formats (fixed.py "apply": the
    base model's K - I in Q(18 - e) and K o in Q(28 - e) g; a composed model's K in Q14 and
    offsets in Q(14 - e) g), so the products stay below 2**30 at every full scale.  Samples in
    are Q10 g; calibrated samples out are Q(13 - e) g (self.out_q, fixed.APPLY_OUT_Q - e: a
    still sensor's sub-mg mean kept, and an int16 at every full scale).

    kinds: a composed model's effects (acal.core.effects ids).  Their parameters follow the nine in
    p and are kept in their per-sample form (acal/core/effects.py); the feeder keeps the conditions
    `now` current (bins.conditions(1), given or a zeroed one of its own: C_TEMP Q2 degC, C_TIME
    64 s units, C_SUPPLY mV, the board's), and the effects are removed at now - ref, column by
    column, `ref` (the same columns) the references the fit used (set()); a step at
    dt >= step_time."""

    def __init__(self, kinds=(), range_g=2, now=None):
        self.kinds = tuple(kinds)
        self.e = apply_range_shift(range_g)  # fixed.py: the format by full scale
        self.out_q = APPLY_OUT_Q - self.e
        self.in_max = APPLY_IN_MAX << self.e
        n = N_PARAMS + 3 * len(self.kinds)
        self.k = int32s(n)   # an int32 array: _apply_block's typed pointer
        self.w = int32s(3)   # one sample (apply()), or a reading after its effects, Q(14 - e)
        self.now = conditions(1) if now is None else now
        self.ref = conditions(1)   # the fit's references, now's columns (set())
        self.step_time = 0
        # the effects' forms and terms at the block's conditions (effects.block_terms), in the
        # order they are removed (the last effect first), 4 ints each: made when a condition
        # changes (per block, not per sample), read by _apply_composed's one viper loop
        self.terms = int32s(4 * len(self.kinds))
        self.terms_valid = False
        self.at = conditions(1)    # the conditions the terms were made at
        self.rel = conditions(1)   # and relative to the references (now - ref)
        # what the apply's loops read of the calibration's format, in this order: the clamp (Q10
        # g), the base model's shift, a composed model's, e, APPLY_W_MAX, the terms' count (an
        # array: a viper loop's every load of an attribute or a module's constant is a call)
        self.form = int32s(6)
        for i, v in enumerate((self.in_max, APPLY_D_Q - self.e, APPLY_FROM_SAMPLE_SHIFT - self.e,
                               self.e, APPLY_W_MAX, 4 * len(self.kinds))):
            self.form[i] = v
        self.x = 0
        self.y = 0
        self.z = 0
        self.dither = 0   # the base apply's output dither's phase (fixed.py APPLY_DITHER_STEP)
        p = [0] * n
        identity(p)
        self.set(p)

    def set(self, p, ref=None, step_time=0):
        """Take Q24 parameters, the references the fit used (`ref`, now's columns, copied;
        None: zeros) and a step's time (64 s units from ref[C_TIME]); ValueError outside the
        bounds (the range proof needs them)."""
        if not in_bounds(p) or (self.kinds and not effects_within(p, self.kinds, 1)):
            raise ValueError("parameters outside the calibration bounds")
        if not self.kinds:
            _base_params(p, self.k, self.e)
        for i in range(N_PARAMS if self.kinds else 0):   # a composed model's: K and o in Q14
            shift = APPLY_PARAM_SHIFT if i < 6 else APPLY_PARAM_SHIFT + self.e
            self.k[i] = (p[i] + (1 << (shift - 1))) >> shift
        for j in range(len(self.kinds)):
            effects.apply_params(self.kinds[j], p, N_PARAMS + 3 * j, self.k, N_PARAMS + 3 * j)
        for c in range(COND):
            self.ref[c] = 0 if ref is None else ref[c]
        self.step_time = step_time
        self.terms_valid = False

    def apply(self, x, y, z):
        """Correct one sample (Q10 g); the result is in self.x, self.y, self.z (Q(13 - e) g).
        A reading past the full scale is clamped to it first (the chip cannot read more; the
        range bound holds for any input).  apply_samples on a one-sample buffer."""
        w = self.w
        w[0] = x
        w[1] = y
        w[2] = z
        self.apply_samples(w, 0, 1)
        self.x = w[0]
        self.y = w[1]
        self.z = w[2]

    def apply_samples(self, buf, start, n, src=None):
        """Correct n interleaved samples x y z ... (Q10 g in, Q(13 - e) g out) of an int array
        in place, from sample `start` (given src, an int array: read from src at the same
        indices, the copy and the apply in one pass)."""
        # The block's loop reads the calibration itself: a call with its formats as arguments
        # took a frame of over 11 words, which MicroPython takes from the heap on every call
        # (docs/method-and-formats.md "Frames").
        if n <= 0:
            return
        if src is None:
            src = buf
        if self.kinds:   # one viper loop a block: the effects' terms made once for its conditions
            self._terms_now()
            _apply_composed(self, src, buf, start, n)
        else:
            _apply_block(self, src, buf, start, n)

    def _terms_now(self):
        # the effects' terms, remade when a condition changed since they were made
        c = self.now
        t = self.at
        moved = not self.terms_valid
        for j in range(COND):
            if c[j] != t[j]:
                moved = True
        if moved:
            self._block_terms()

    def _block_terms(self):
        # The effects' forms and terms (effects.block_terms) at the current conditions, last
        # effect first: at d = now - ref, column by column.
        kinds = self.kinds
        c = self.now
        r = self.ref
        d = self.rel
        for i in range(COND):
            d[i] = c[i] - r[i]
        n = len(kinds)
        for j in range(n):
            effects.block_terms(kinds[n - 1 - j], self.k, N_PARAMS + 3 * (n - 1 - j), self.terms,
                                4 * j, d, self.step_time, self.e)
        self.terms_valid = True
        for i in range(COND):
            self.at[i] = c[i]


def _base_params(p, k, e):
    # The base model's apply formats (fixed.py "apply", APPLY_D_Q, APPLY_C_Q) from Q24 p into
    # k[0:9]: D = K - I in Q(18 - e), rounded; c = K o in Q(28 - e) g, each row's products exact
    # floors in Q(29 - e) (wide.mul_shift: |p| < 2**29, every intermediate a small int), summed
    # and rounded once (the output's rounding is the loop's dither).
    ds = PARAM_Q - APPLY_D_Q + e
    for i in range(6):
        k[i] = (p[i] - (PARAM_ONE if i < 3 else 0) + (1 << (ds - 1))) >> ds
    cs = 2 * PARAM_Q - APPLY_C_Q + e - 1
    k[6] = (mul_shift(p[0], p[6], cs) + 1) >> 1
    k[7] = (mul_shift(p[3], p[6], cs) + mul_shift(p[1], p[7], cs) + 1) >> 1
    k[8] = (mul_shift(p[4], p[6], cs) + mul_shift(p[5], p[7], cs) + mul_shift(p[2], p[8], cs)
            + 1) >> 1


@viper
def _apply_block(cal, source, dest, start: int, n: int):
    # The apply's one implementation (Calibration.apply_samples): n samples source[3 start:]
    # (flat x y z) into dest, viper on ports with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
    # Readings clamped to +-m (Q10 g), a = ((x << s) + D x + c) >> o: s = 18 - e, D = K - I in
    # Q(18 - e), c = K o in Q(28 - e) g (_base_params, cal.k), rounded by 15 bits to Q(13 - e) g
    # with the dither r (Q15, cal.dither: the phase of the first sample, the next block's kept;
    # fixed.py APPLY_DITHER_STEP and _MASK are the literals below); every value below 2**30 at
    # every full scale (tests/device/test_ranges.py traces them).
    src = ptr32(source)
    dst = ptr32(dest)
    k = ptr32(cal.k)
    f = ptr32(cal.form)
    w = int(SIGN_SHIFT)
    m = int(f[0])
    s = int(f[1])
    r = int(cal.dither)
    i = 3 * start
    end = 3 * (start + n)
    dxx = int(k[0]) << w >> w
    dyy = int(k[1]) << w >> w
    dzz = int(k[2]) << w >> w
    dxy = int(k[3]) << w >> w
    dxz = int(k[4]) << w >> w
    dyz = int(k[5]) << w >> w
    cx = int(k[6]) << w >> w
    cy = int(k[7]) << w >> w
    cz = int(k[8]) << w >> w
    while i < end:
        x = int(src[i]) << w >> w
        y = int(src[i + 1]) << w >> w
        z = int(src[i + 2]) << w >> w
        if x > m:
            x = m
        elif x < -m:
            x = -m
        if y > m:
            y = m
        elif y < -m:
            y = -m
        if z > m:
            z = m
        elif z < -m:
            z = -m
        dst[i] = ((x << s) + dxx * x + cx + r) >> 15
        dst[i + 1] = ((y << s) + dxy * x + dyy * y + cy + r) >> 15
        dst[i + 2] = ((z << s) + dxz * x + dyz * y + dzz * z + cz + r) >> 15
        r = (r + 13573) & 32767
        i += 3
    cal.dither = r


@viper
def _apply_composed(cal, source, dest, start: int, n: int):
    # A composed model's apply (Calibration.apply_samples), n samples source[3 start:] (flat x y z,
    # Q10 g) into dest, viper on ports with emitters: each reading clamped to the full scale +-m,
    # v = x << s in Q(14 - e) g; the effects removed by their forms (effects.py "the apply's
    # forms": cal.terms[0:nt], 4 ints an effect, last effect first), v clamped to +-wm
    # (APPLY_W_MAX) after each (fixed.py: a reading's range, so the next product and K's stay
    # below 2**30); then
    # a = K (v + o) rounded to Q(13 - e) g as _apply_block.  Bit-identical to the per-sample form
    # (tests/device/effects_per_sample.py; tests/device/test_composed_app.py under MicroPython, tests/bridge/test_rp2040.py
    # and test_rv32.py on the chips); every value below 2**30
    # (tests/device/test_effects.py traces it at the worst case).
    # Its setup (K's nine loads, the clamp to +-m) repeats _apply_block's on purpose (duplicates
    # D1): a viper function cannot return nine locals, and a shared helper or one loop with a
    # `nt` test per sample costs the base model's apply a call or a branch per sample, the
    # hot path every board runs; the two loops stay two, tied by test_composed_app's integers.
    src = ptr32(source)
    dst = ptr32(dest)
    k = ptr32(cal.k)
    t = ptr32(cal.terms)
    f = ptr32(cal.form)
    w = int(SIGN_SHIFT)
    m = int(f[0])
    s = int(f[2])
    e = int(f[3])
    wm = int(f[4])
    nt = int(f[5])
    i = 3 * start
    end = 3 * (start + n)
    kxx = int(k[0]) << w >> w
    kyy = int(k[1]) << w >> w
    kzz = int(k[2]) << w >> w
    kxy = int(k[3]) << w >> w
    kxz = int(k[4]) << w >> w
    kyz = int(k[5]) << w >> w
    ox = int(k[6]) << w >> w
    oy = int(k[7]) << w >> w
    oz = int(k[8]) << w >> w
    sq = 10 + e
    while i < end:
        x = int(src[i]) << w >> w
        y = int(src[i + 1]) << w >> w
        z = int(src[i + 2]) << w >> w
        if x > m:
            x = m
        elif x < 0 - m:
            x = 0 - m
        if y > m:
            y = m
        elif y < 0 - m:
            y = 0 - m
        if z > m:
            z = m
        elif z < 0 - m:
            z = 0 - m
        vx = x << s
        vy = y << s
        vz = z << s
        j = 0
        while j < nt:
            form = int(t[j])
            ax = int(t[j + 1]) << w >> w
            ay = int(t[j + 2]) << w >> w
            az = int(t[j + 3]) << w >> w
            if form == 1:                    # FORM_OFFSET
                vx -= ax
                vy -= ay
                vz -= az
            elif form == 2:                  # FORM_SCALE
                vx -= (ax * vx) >> 18
                vy -= (ay * vy) >> 18
                vz -= (az * vz) >> 18
            else:                            # FORM_NONLINEAR
                vx -= (ax * ((x * x) >> sq)) >> 14
                vy -= (ay * ((y * y) >> sq)) >> 14
                vz -= (az * ((z * z) >> sq)) >> 14
            if vx > wm:
                vx = wm
            elif vx < 0 - wm:
                vx = 0 - wm
            if vy > wm:
                vy = wm
            elif vy < 0 - wm:
                vy = 0 - wm
            if vz > wm:
                vz = wm
            elif vz < 0 - wm:
                vz = 0 - wm
            j += 4
        vx += ox
        vy += oy
        vz += oz
        dst[i] = (kxx * vx + 16384) >> 15
        dst[i + 1] = (kxy * vx + kyy * vy + 16384) >> 15
        dst[i + 2] = (kxz * vx + kyz * vy + kzz * vz + 16384) >> 15
        i += 3
