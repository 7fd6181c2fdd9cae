# The calibration applied to raw samples on the board, per sample and without allocating: the
# model of acal/core/model.py (a = K (v + o), a composed model's effects removed first: acal/core/effects.py)
# in the apply's formats (fixed.py "apply"), every product below 2**30 at every full scale.  One
# implementation of the clamp and the products, _apply_block: a single sample and a composed
# model's readings (after their effects) go through it too.
from acal.core.fixed import (N_PARAMS, APPLY_FROM_SAMPLE_SHIFT, APPLY_PARAM_SHIFT, APPLY_OUT_SHIFT,
                        APPLY_OUT_Q, APPLY_IN_MAX, APPLY_W_MAX, apply_range_shift)
from acal.core import effects
from acal.core.bins import int32s
from acal.core.emit import SIGN_SHIFT, viper, ptr32
from acal.core.model import identity, in_bounds, effects_within


class Calibration:
    """A calibration applied to raw samples, per sample and without allocating.

    range_g: the sensor's full scale (2, 4, 8 or 16 g), shift e (fixed.apply_range_shift).
    set(p) takes Q24 parameters and keeps them in the apply's formats (fixed.py: K in Q14, the
    offsets in Q(14 - e) g), so the products stay below 2**30 at every full scale.  Samples in
    are Q10 g; calibrated samples out are Q(13 - e) g (self.out_q, fixed.APPLY_OUT_Q - e: a
    still sensor's sub-mg mean kept, and an int16 at every full scale).

    kinds: a composed model's effects (acal.core.effects ids).  Their parameters follow the nine in
    p and are kept in their per-sample form (acal/core/effects.py); the feeder keeps `temp` (Q2 degC),
    `time` (64 s units) and `supply` (mV, the board's) current, and the effects are removed with
    dT = temp - ref_temp, dt = time - ref_time and dV = supply - ref_supply, the references the
    fit used (set()); a step at dt >= step_time."""

    def __init__(self, kinds=(), range_g=2):
        self.kinds = tuple(kinds)
        self.e = apply_range_shift(range_g)  # fixed.py: the format by full scale
        self.out_q = APPLY_OUT_Q - self.e
        self.in_max = APPLY_IN_MAX << self.e
        self.n_params = N_PARAMS + 3 * len(self.kinds)
        self.k = int32s(self.n_params)   # an int32 array: _apply_block's typed pointer
        self.w = int32s(3)   # one sample (apply()), or a reading after its effects, Q(14 - e)
        self.temp = 0
        self.time = 0
        self.supply = 0
        self.ref_temp = 0
        self.ref_time = 0
        self.ref_supply = 0
        self.step_time = 0
        # the generic offsets' regressors (Q12), computed when temp, time or supply changes,
        # not per sample (effects.regressor: up to three wide products)
        self.r = [0] * len(self.kinds)
        self.generic = [effects.is_generic(k) for k in self.kinds]
        self.r_valid = False
        self.r_temp = 0
        self.r_time = 0
        self.r_supply = 0
        self.x = 0
        self.y = 0
        self.z = 0
        p = [0] * self.n_params
        identity(p)
        self.set(p)

    def set(self, p, ref_temp=0, ref_time=0, step_time=0, ref_supply=0):
        """Take Q24 parameters (and a step's time, 64 s units from ref_time; the supply's
        reference, mV); ValueError outside the bounds (the range proof needs them)."""
        if not in_bounds(p) or (self.kinds and not effects_within(p, self.kinds, 1)):
            raise ValueError("parameters outside the calibration bounds")
        for i in range(N_PARAMS):
            shift = APPLY_PARAM_SHIFT if i < 6 else APPLY_PARAM_SHIFT + self.e
            self.k[i] = (p[i] + (1 << (shift - 1))) >> shift
        for j in range(len(self.kinds)):
            effects.apply_params(self.kinds[j], p, N_PARAMS + 3 * j, self.k, N_PARAMS + 3 * j)
        self.ref_temp = ref_temp
        self.ref_time = ref_time
        self.step_time = step_time
        self.ref_supply = ref_supply
        self.r_valid = False

    def apply(self, x, y, z):
        """Correct one sample (Q10 g); the result is in self.x, self.y, self.z (Q(13 - e) g).
        A reading past the full scale is clamped to it first (the chip cannot read more; the
        range bound holds for any input).  apply_samples on a one-sample buffer."""
        w = self.w
        w[0] = x
        w[1] = y
        w[2] = z
        self.apply_samples(w, 0, 1)

    def apply_samples(self, buf, start, n, src=None):
        """Correct n interleaved samples x y z ... (Q10 g in, Q(13 - e) g out) of an int array
        in place, from sample `start` (given src, an int array: read from src at the same
        indices, the copy and the apply in one pass).  The last sample's result is also in
        self.x, self.y, self.z."""
        if n <= 0:
            return
        if src is None:
            src = buf
        i = 3 * start
        end = 3 * (start + n)
        if not self.kinds:
            _apply_block(src, buf, i, end, self.k, self.in_max, APPLY_FROM_SAMPLE_SHIFT - self.e,
                         APPLY_OUT_SHIFT, SIGN_SHIFT)
        else:
            # the readings after their effects, Q(14 - e) g, into buf; then the block applied
            # there in place (shift 0; already clamped): one viper call a block, not a sample
            w = self.w
            j = i
            while j < end:
                self._remove_effects(src[j], src[j + 1], src[j + 2])
                buf[j] = w[0]
                buf[j + 1] = w[1]
                buf[j + 2] = w[2]
                j += 3
            _apply_block(buf, buf, i, end, self.k, APPLY_W_MAX, 0, APPLY_OUT_SHIFT, SIGN_SHIFT)
        self.x = buf[end - 3]
        self.y = buf[end - 2]
        self.z = buf[end - 1]

    def _remove_effects(self, x, y, z):
        # The effects, last first (the reverse of the order they act in), in Q(14 - e), into
        # self.w; the reading first clamped to the full scale, and after each effect to
        # +-2.048 * 2**e g (fixed.APPLY_W_MAX): the next effect's products and the 9-parameter
        # apply then stay below 2**30 in every order (a drift removed over months can move a
        # reading by several g, and temp_scale multiplies what it leaves).
        w = self.w
        e = self.e
        s = APPLY_FROM_SAMPLE_SHIFT - e
        m = self.in_max   # the reading to the full scale first: the effects read it (q v^2)
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
        w[0] = x << s
        w[1] = y << s
        w[2] = z << s
        dT = self.temp - self.ref_temp
        dt = self.time - self.ref_time
        kinds = self.kinds
        r = self.r
        if not self.r_valid or self.temp != self.r_temp or self.time != self.r_time or \
                self.supply != self.r_supply:
            dV = self.supply - self.ref_supply
            for j in range(len(kinds)):
                if self.generic[j]:
                    r[j] = effects.regressor(kinds[j], dT, dt, self.step_time, dV) >> 4
            self.r_valid = True
            self.r_temp = self.temp
            self.r_time = self.time
            self.r_supply = self.supply
        j = len(kinds) - 1
        while j >= 0:
            if self.generic[j]:   # correct_sample's form, with the regressor kept
                effects.offset_sample(self.k, N_PARAMS + 3 * j, w, r[j], e)
            else:
                effects.correct_sample(kinds[j], self.k, N_PARAMS + 3 * j, w, x, y, z, dT, dt,
                                       0, 0, e)
            for i in range(3):   # inline: a call per effect costs the chip ~12 us
                if w[i] > APPLY_W_MAX:
                    w[i] = APPLY_W_MAX
                elif w[i] < -APPLY_W_MAX:
                    w[i] = -APPLY_W_MAX
            j -= 1


@viper
def _apply_block(source, dest, i: int, end: int, coef, m: int, s: int, o: int, w: int):
    # The apply's one implementation (Calibration.apply_samples): the samples source[i:end]
    # (flat x y z) into dest, viper on ports with emitters (acal/core/emit.py; w: emit.SIGN_SHIFT).
    # Readings clamped to +-m, u = (x << s) + o in Q(14 - e) g, the Q14 products rounded by o
    # bits to Q(13 - e) g (fixed.py "apply"); every value below 2**30 at every full scale
    # (tests/device/test_ranges.py traces them).
    src = ptr32(source)
    dst = ptr32(dest)
    k = ptr32(coef)
    kxx = int(k[0]) << w >> w
    kyy = int(k[1]) << w >> w
    kzz = int(k[2]) << w >> w
    kxy = int(k[3]) << w >> w
    kxz = int(k[4]) << w >> w
    kyz = int(k[5]) << w >> w
    ox = int(k[6]) << w >> w
    oy = int(k[7]) << w >> w
    oz = int(k[8]) << w >> w
    half = 1 << (o - 1)
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
        ux = (x << s) + ox
        uy = (y << s) + oy
        uz = (z << s) + oz
        dst[i] = (kxx * ux + half) >> o
        dst[i + 1] = (kxy * ux + kyy * uy + half) >> o
        dst[i + 2] = (kxz * ux + kyz * uy + kzz * uz + half) >> o
        i += 3
