# A simulated ST LIS3DH at register level (datasheet DocID17530), fed by a stimulus file.
# MicroPython-compatible: it runs inside the virtual board (MicroPython unix port) behind the fake
# buses of vbus.py, and under CPython for the tests (where the real adafruit_lis3dh reads it).
#
# Stimulus file (written by accelcal.simulate.wearer): 16-byte header b"ACST" version u16, rate_hz u16,
# n_samples u32, reserved u32; then per sample four int32: x, y, z in ug (what the sensing element
# sees, sensor errors and noise included) and temperature in m degC; version 2 adds a fifth, the
# board's supply in mV (the simulated battery, what the virtual board's supply_mv() reads).
#
# Behaviour modelled: WHO_AM_I; CTRL_REG1 ODR/LPen/axes; CTRL_REG4 FS/HR/BDU; CTRL_REG5 FIFO_EN and
# BOOT; TEMP_CFG_REG ADC_EN/TEMP_EN and OUT_ADC3 (relative temperature, 1 digit/degC, 8 bits);
# output registers left-justified at 12 (HR), 10 (normal) or 8 (low-power) bits; STATUS_REG
# ZYXDA/ZYXOR; a 32-level FIFO in bypass, FIFO and stream modes that keeps 10 bits per axis (the
# datasheet's FIFO resolution; two more bits are lost against HR output registers), OVRN and
# the FSS level in FIFO_SRC_REG; multi-byte reads auto-increment when bit 7 of the sub-address is
# set, and in FIFO mode roll over from OUT_Z_H back to OUT_X_L, popping the next sample.
import struct

WHO_AM_I_VALUE = 0x33
_ODR_HZ = (0, 1, 10, 25, 50, 100, 200, 400, 1600, 1344)
_SO_MG = (1, 2, 4, 12)  # mg/digit at 12 bits for FS = 2, 4, 8, 16 g

_REG_STATUS_AUX = 0x07
_REG_OUT_ADC1_L = 0x08
_REG_WHO_AM_I = 0x0F
_REG_TEMP_CFG = 0x1F
_REG_CTRL1 = 0x20
_REG_CTRL4 = 0x23
_REG_CTRL5 = 0x24
_REG_STATUS = 0x27
_REG_OUT_X_L = 0x28
_REG_FIFO_CTRL = 0x2E
_REG_FIFO_SRC = 0x2F


class Stimulus:
    """Sequential reader of a stimulus file, a block at a time."""

    BLOCK_BYTES = 4096    # read a block at a time (256 samples of version 1, 204 of version 2)

    def __init__(self, path):
        self.f = open(path, "rb")
        head = self.f.read(16)
        if len(head) != 16 or head[:4] != b"ACST":
            raise ValueError("not a stimulus file: " + path)
        version, self.rate_hz, self.n = struct.unpack("<HHI", head[4:12])
        # version 2: each sample also holds the board's supply (mV), for supply_mv()
        self.has_supply = version == 2
        self.size = 20 if self.has_supply else 16
        self.block = bytearray(self.BLOCK_BYTES)   # whole samples of either version
        self.first = -1
        self.count = 0
        self.x = self.y = self.z = self.temp_mc = self.supply_mv = 0

    def load(self, k):
        """Make sample k current (x, y, z in ug, temp_mc); False past the end."""
        if k >= self.n:
            return False
        if not (self.first <= k < self.first + self.count):
            self.first = k
            self.f.seek(16 + self.size * k)
            self.count = self.f.readinto(self.block) // self.size
            # (a version-2 block's tail, 16 bytes, holds part of a sample: never read)
        # Decoded by hand: struct.unpack_from would allocate a tuple per sample, and the virtual
        # board's acquisition path is checked for allocations with the heap locked.
        j = self.size * (k - self.first)
        self.x = _i32(self.block, j)
        self.y = _i32(self.block, j + 4)
        self.z = _i32(self.block, j + 8)
        self.temp_mc = _i32(self.block, j + 12)
        if self.has_supply:
            self.supply_mv = _i32(self.block, j + 16)
        return True


def _i32(b, j):
    # little-endian int32, its top byte signed first: no int past 2**30 for values within
    # +-2**30 (16 g is 1.6e7 ug), so nothing allocates on a 32-bit port
    top = b[j + 3]
    if top & 0x80:
        top -= 256
    return (top << 24) + (b[j] | (b[j + 1] << 8) | (b[j + 2] << 16))


class SimLIS3DH:
    """clock: an object with now_us(); stimulus: a Stimulus; temp_ref_mc: the temperature at
    which OUT_ADC3 reads 0 (the chip's unknown reference, m degC)."""

    def __init__(self, stimulus, clock, temp_ref_mc=25000):
        self.stim = stimulus
        self.clock = clock
        self.temp_ref_mc = temp_ref_mc
        self.regs = bytearray(0x40)
        self.fifo = [[0, 0, 0] for _ in range(32)]
        self.dropped = 0        # ground truth: samples the FIFO overwrote (stream mode)
        self.generated = 0      # ground truth: samples produced since the ODR was set
        self.exhausted = False
        # The stimulus is the world's time line, from the moment the board powers up (the clock
        # may start anywhere: a test puts its ticks' wrap where it wants it).  Times are kept as
        # whole seconds and microseconds, as the clock keeps them (vclock.py: 32-bit faithful).
        self.epoch_s = clock.s
        self.epoch_us = clock.us
        self._reset()

    def _reset(self):
        for i in range(len(self.regs)):
            self.regs[i] = 0
        self.regs[_REG_WHO_AM_I] = WHO_AM_I_VALUE
        self.regs[_REG_CTRL1] = 0x07
        self.fifo_level = 0
        self.fifo_head = 0
        self.ovrn = False
        self._start()
        self.out = [0, 0, 0]
        self.new_data = False
        self.overrun = False

    def _start(self):
        # Sampling (re)starts now: the ODR's time line begins here.
        self.start_s = self.clock.s
        self.start_us = self.clock.us
        self.generated = 0

    # --- what the configuration implies -----------------------------------------------------
    def odr_hz(self):
        return _ODR_HZ[(self.regs[_REG_CTRL1] >> 4) & 0x0F] if (self.regs[_REG_CTRL1] >> 4) < 10 else 0

    def bits(self):
        if self.regs[_REG_CTRL1] & 0x08:
            return 8
        return 12 if self.regs[_REG_CTRL4] & 0x08 else 10

    def so_mg(self):
        """mg per digit at the current resolution."""
        return _SO_MG[(self.regs[_REG_CTRL4] >> 4) & 3] << (12 - self.bits())

    def fifo_mode(self):
        if not self.regs[_REG_CTRL5] & 0x40:
            return 0
        return (self.regs[_REG_FIFO_CTRL] >> 6) & 3

    # --- sample production -------------------------------------------------------------------
    def _raw(self, ug):
        # Round to the digit of the current resolution, clip, left-justify in 16 bits.
        bits = self.bits()
        step = self.so_mg() * 1000
        d = (ug + step // 2) // step if ug >= 0 else -((-ug + step // 2) // step)
        lim = 1 << (bits - 1)
        if d >= lim:
            d = lim - 1
        elif d < -lim:
            d = -lim
        return (d << (16 - bits)) & 0xFFFF

    def catch_up(self):
        """Produce every sample due by the clock's current time."""
        hz = self.odr_hz()
        if hz == 0:
            return
        # Sample n is converted at start + n * period (period = 10**6 // hz us, and sps whole
        # periods a second leave `defect` us: 64 at 1344 Hz, else 0); it reads the stimulus
        # sample k = floor(t * rate_hz / 10**6) of its time t since the epoch.  In seconds and
        # microseconds, so every int stays below 2**30 for 124 days at 100 Hz.
        period = 1000000 // hz
        sps = 1000000 // period
        defect = 1000000 - sps * period
        ds = self.clock.s - self.start_s
        due = ds * sps + (ds * defect + self.clock.us - self.start_us) // period
        rate = self.stim.rate_hz
        while self.generated < due:
            n = self.generated + 1
            a = n // sps
            t_s = self.start_s - self.epoch_s + a
            t_us = self.start_us - self.epoch_us + (n - a * sps) * period - a * defect
            t_s += t_us // 1000000
            t_us %= 1000000
            k = t_s * rate + ((t_us // 1000) * rate + ((t_us % 1000) * rate) // 1000) // 1000
            if not self.stim.load(k):
                # The stimulus is over: the chip goes on converting its last input (the run
                # stops when the board sees `exhausted`), so every sample is still accounted.
                self.exhausted = True
            self.generated += 1
            out = self.out  # filled in place: no allocation per sample
            out[0] = self._raw(self.stim.x)
            out[1] = self._raw(self.stim.y)
            out[2] = self._raw(self.stim.z)
            if self.new_data:
                self.overrun = True
            self.new_data = True
            mode = self.fifo_mode()
            if mode:
                if self.fifo_level < 32:
                    slot = self.fifo[(self.fifo_head + self.fifo_level) % 32]
                    self.fifo_level += 1
                elif mode == 2:  # stream: the oldest sample is overwritten
                    slot = self.fifo[self.fifo_head]
                    self.fifo_head = (self.fifo_head + 1) % 32
                    self.dropped += 1
                    self.ovrn = True
                else:  # FIFO mode stops collecting when full
                    slot = None
                    self.dropped += 1
                    self.ovrn = True
                if slot is not None:
                    # The FIFO keeps 10 bits: the two LSBs of a 12-bit HR value are lost.
                    slot[0] = out[0] & 0xFFC0
                    slot[1] = out[1] & 0xFFC0
                    slot[2] = out[2] & 0xFFC0

    # --- register access ---------------------------------------------------------------------
    def read(self, reg, buf, start, end):
        """Read end-start bytes from sub-address reg (bit 7: auto-increment)."""
        self.catch_up()
        inc = reg & 0x80
        reg &= 0x7F
        i = start
        while i < end:
            buf[i] = self._read_byte(reg)
            i += 1
            if inc:
                reg += 1
                if reg == _REG_OUT_X_L + 6 and self.fifo_mode():
                    reg = _REG_OUT_X_L
        return end - start

    def _read_byte(self, reg):
        if _REG_OUT_X_L <= reg < _REG_OUT_X_L + 6:
            k = reg - _REG_OUT_X_L
            if self.fifo_mode():
                if self.fifo_level == 0:
                    src = self.out
                else:
                    src = self.fifo[self.fifo_head]
                v = src[k >> 1]
                if k == 5 and self.fifo_level > 0:
                    self.fifo_head = (self.fifo_head + 1) % 32
                    self.fifo_level -= 1
                    self.ovrn = False
            else:
                v = self.out[k >> 1]
                if k == 5:
                    self.new_data = False
                    self.overrun = False
            return (v >> 8) & 0xFF if k & 1 else v & 0xFF
        if reg == _REG_STATUS:
            return (0x08 if self.new_data else 0) | (0x80 if self.overrun else 0)
        if reg == _REG_FIFO_SRC:
            level = self.fifo_level
            return (0x40 if self.ovrn else 0) | (0x20 if level == 0 else 0) | (level & 0x1F if level < 32 else 0x1F) | (0x80 if level >= 32 else 0)
        if _REG_OUT_ADC1_L <= reg < _REG_OUT_ADC1_L + 6:
            if reg >= 0x0C and (self.regs[_REG_TEMP_CFG] & 0xC0) == 0xC0:
                # Relative temperature, 1 digit/degC, two's complement in the high byte.
                d = (self.stim.temp_mc - self.temp_ref_mc + 500) // 1000
                d = max(-128, min(127, d))
                return (d & 0xFF) if reg == 0x0D else 0
            return 0
        if reg == _REG_STATUS_AUX:
            return 0x44 if (self.regs[_REG_TEMP_CFG] & 0xC0) == 0xC0 else 0
        return self.regs[reg]

    def write(self, reg, data, start, end):
        inc = reg & 0x80
        reg &= 0x7F
        i = start
        while i < end:
            self._write_byte(reg, data[i])
            i += 1
            if inc:
                reg += 1

    def _write_byte(self, reg, v):
        self.catch_up()
        if reg == _REG_CTRL5 and v & 0x80:  # BOOT: reload defaults
            self._reset()
            return
        if reg in (_REG_WHO_AM_I, _REG_STATUS, _REG_FIFO_SRC) or _REG_OUT_X_L <= reg < _REG_OUT_X_L + 6:
            return  # read-only
        old_odr = self.odr_hz()
        self.regs[reg] = v
        if reg == _REG_CTRL1 and self.odr_hz() != old_odr:
            self._start()
        if reg == _REG_FIFO_CTRL or reg == _REG_CTRL5:
            if self.fifo_mode() == 0:  # bypass empties the FIFO
                self.fifo_level = 0
                self.fifo_head = 0
                self.ovrn = False
