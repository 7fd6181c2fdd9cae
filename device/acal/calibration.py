# The calibration applied to raw samples on the board, per sample and without allocating: the
# model of acal/model.py (a = K (v + o), a composed model's effects removed first: acal/effects.py)
# in the apply's formats (fixed.py "apply"), every product below 2**30 at every full scale.
from acal.fixed import (N_PARAMS, APPLY_FROM_SAMPLE_SHIFT, APPLY_PARAM_SHIFT, APPLY_OUT_SHIFT,
                        APPLY_IN_MAX, APPLY_W_MAX, apply_range_shift)
from acal import effects
from acal.bins import int32s
from acal.emit import SIGN_SHIFT, viper, ptr32
from acal.model import identity, in_bounds, effects_within


class Calibration:
    """A calibration applied to raw samples, per sample and without allocating.

    set(p) takes Q24 parameters and keeps them in Q14 (APPLY_Q): the products of the per-sample
    path then stay below 2**30 at +-2 g.  Samples in and out are Q10 g.

    kinds: a composed model's effects (acal.effects ids).  Their parameters follow the nine in
    p and are kept in their per-sample form (acal/effects.py); the feeder keeps `temp` (int degC),
    `time` (64 s units) and `supply` (mV, the board's) current, and the effects are removed with
    dT = temp - ref_temp, dt = time - ref_time and dV = supply - ref_supply, the references the
    fit used (set()); a step at dt >= step_time."""

    def __init__(self, kinds=(), range_g=2):
        self.kinds = tuple(kinds)
        self.e = apply_range_shift(range_g)  # fixed.py: the format by full scale
        if self.kinds and self.e:
            raise ValueError("a composed model applies at +-2 g full scale")
        self.in_max = APPLY_IN_MAX << self.e
        self.n_params = N_PARAMS + 3 * len(self.kinds)
        self.k = int32s(self.n_params)   # an int32 array: _apply_block's typed pointer
        self.w = [0, 0, 0]
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
        shift = APPLY_PARAM_SHIFT + self.e
        half = 1 << (shift - 1)
        for i in range(N_PARAMS):
            self.k[i] = (p[i] + half) >> shift
        for j in range(len(self.kinds)):
            effects.apply_params(self.kinds[j], p, N_PARAMS + 3 * j, self.k, N_PARAMS + 3 * j)
        self.ref_temp = ref_temp
        self.ref_time = ref_time
        self.step_time = step_time
        self.ref_supply = ref_supply
        self.r_valid = False

    def apply(self, x, y, z):
        """Correct one sample; the result is in self.x, self.y, self.z (Q10 g).  A reading past
        the full scale is clamped to it first (the chip cannot read more; the range bound
        holds for any input)."""
        k = self.k
        m = self.in_max
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
        e = self.e
        if self.kinds:
            w = self.w
            self._remove_effects(x, y, z)
            ux = w[0] + k[6]
            uy = w[1] + k[7]
            uz = w[2] + k[8]
        else:
            s = APPLY_FROM_SAMPLE_SHIFT - e
            ux = (x << s) + k[6]
            uy = (y << s) + k[7]
            uz = (z << s) + k[8]
        s = APPLY_OUT_SHIFT - 2 * e
        half = 1 << (s - 1)
        self.x = (k[0] * ux + half) >> s
        self.y = (k[3] * ux + k[1] * uy + half) >> s
        self.z = (k[4] * ux + k[5] * uy + k[2] * uz + half) >> s

    def _remove_effects(self, x, y, z):
        # The effects, last first (the reverse of the order they act in), in Q14, into self.w;
        # after each one clamped to +-2.048 g (fixed.APPLY_W_MAX): the next effect's products
        # and the 9-parameter apply then stay below 2**30 in every order (a drift removed over
        # months can move a reading by several g, and temp_scale multiplies what it leaves).
        w = self.w
        w[0] = x << APPLY_FROM_SAMPLE_SHIFT
        w[1] = y << APPLY_FROM_SAMPLE_SHIFT
        w[2] = z << APPLY_FROM_SAMPLE_SHIFT
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
                effects.offset_sample(self.k, N_PARAMS + 3 * j, w, r[j])
            else:
                effects.correct_sample(kinds[j], self.k, N_PARAMS + 3 * j, w, x, y, z, dT, dt)
            for i in range(3):
                if w[i] > APPLY_W_MAX:
                    w[i] = APPLY_W_MAX
                elif w[i] < -APPLY_W_MAX:
                    w[i] = -APPLY_W_MAX
            j -= 1

    def apply_samples(self, buf, start, n, src=None):
        """Correct n interleaved samples x y z ... of an int array in place, from sample `start`
        (given src, an int array: read from src at the same indices, the copy and the apply in
        one pass).  The last sample's result is also in self.x, self.y, self.z."""
        if src is None:
            src = buf
        i = 3 * start
        end = 3 * (start + n)
        if not self.kinds:
            if n > 0:
                e = self.e
                _apply_block(src, buf, i, end, self.k, self.in_max, APPLY_FROM_SAMPLE_SHIFT - e,
                             APPLY_OUT_SHIFT - 2 * e, SIGN_SHIFT)
                self.x = buf[end - 3]
                self.y = buf[end - 2]
                self.z = buf[end - 1]
            return
        while i < end:
            self.apply(src[i], src[i + 1], src[i + 2])
            buf[i] = self.x
            buf[i + 1] = self.y
            buf[i + 2] = self.z
            i += 3


@viper
def _apply_block(source, dest, i: int, end: int, coef, m: int, s: int, o: int, w: int):
    # Calibration.apply over the samples source[i:end] (flat x y z, Q10 g) into dest, for a
    # model without effects: the per-sample hot loop, viper on ports with emitters (acal/emit.py;
    # w: emit.SIGN_SHIFT).  The same integers as apply(): readings clamped to +-m, u in Q14
    # (<< s), products of Q14 parameters rounded down by o bits; every value below 2**30 at
    # every full scale (tests/device/test_ranges.py traces them).
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
