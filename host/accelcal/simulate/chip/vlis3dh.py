# A simulated ST LIS3DH at register level (datasheet DocID17530), fed by a stimulus file.
# MicroPython-compatible: it runs inside the virtual board (MicroPython unix port) behind the fake
# buses of vbus.py, and under CPython for the tests (where the real adafruit_lis3dh reads it).
#
# Stimulus file (written by accelcal.simulate.wearer): 16-byte header b"ACST" version u16, rate_hz u16,
# n_samples u32, reserved u32; then per sample four int32: x, y, z in ug (what the sensing element
# sees, sensor errors and noise included) and temperature in m degC; version 2 adds a fifth, the
# board's supply in mV (the simulated battery, what the virtual board's supply_mv() reads).
#
# The register map and its behaviour are written from ST's datasheet (DocID17530 Rev 2: section 5.1
# the FIFO, 3.2.1 operating modes, 8.x the registers) and ST's own register header (lis3dh_reg.h,
# STMicroelectronics/lis3dh-pid), not from the driver; docs/lis3dh-conformance.md lists each field,
# where the datasheet says it, and tests/device/test_lis3dh_conformance.py checks every row here,
# in bridge/scripts/lis3dh.mjs and in the driver.  Modelled:
#  * WHO_AM_I (0Fh) 0x33; BOOT (CTRL_REG5 bit 7) reloads every register's default and empties the
#    FIFO;
#  * CTRL_REG1 ODR[3:0] (conversions on the clock), LPen; CTRL_REG4 BDU, FS[1:0], HR: outputs
#    left-justified two's complement at 12 (HR), 10 (normal) or 8 (low-power) bits, 1/2/4/12 mg a
#    digit at 12 bits for +-2/4/8/16 g (ST's conversions: 16 g HR is 12 mg/digit, not 8);
#  * BDU: an axis is held from the read of its low byte to the read of its high byte;
#  * STATUS_REG ZYXDA (bit 3: a set converted, not yet read out) and ZYXOR (bit 7: a set
#    overwrote an unread one), both cleared by reading OUT_Z_H in bypass mode;
#  * TEMP_CFG_REG bits 7:6 both set (ADC and temperature) -> OUT_ADC3: the temperature change
#    from the chip's reference, 1 digit/degC, in OUT_ADC3_H (OUT_ADC3_L reads 0);
#  * the FIFO (CTRL_REG5 FIFO_EN, FIFO_CTRL_REG FM[1:0], TR, FTH[4:0]; FIFO_SRC_REG WTM, OVRN_FIFO,
#    EMPTY, FSS[4:0]): 32 sets of 10 bits per axis (the top 10 of the left-justified output, in
#    every operating mode); bypass (or FIFO_EN = 0) empties it; FIFO mode stops collecting when
#    full, until bypass is written (reading it out does not restart it); stream mode overwrites the oldest; stream-to-FIFO runs as stream while its trigger pin
#    (INT1 when TR = 0, INT2 when TR = 1) is low and as FIFO while it is high.  With u unread
#    sets: FSS = u (31 when u = 32), OVRN_FIFO = (u == 32), EMPTY = (u == 0), WTM = (u > FTH).
#    INT1 is CTRL_REG3's I1_WTM AND WTM, OR I1_OVERRUN AND OVRN_FIFO (the only sources
#    modelled; INT2 has no FIFO source and stays low);
#  * reads: the sub-address auto-increments when its bit 7 is set; in a FIFO mode it rolls over
#    from OUT_Z_H (2Dh) to OUT_X_L (28h), and reading OUT_Z_H pops the set.
#  * the SPI front end (6.2, spi_select/spi_byte), on the same registers: CS low starts a
#    transaction whose first byte is RW (bit 7, 1 = read), MS (bit 6, 1 = the address
#    increments, with the FIFO's roll-over as above), AD5:0; each byte after it reads a register
#    out on SDO or writes the byte clocked in.  SDO while the first byte (or a write's data) is
#    clocked in, and with CS high, is not driven: the models give 0 (what the RP2040's default
#    pad pull-down reads).  The SPI clock's mode and speed are the bus's (vbus.py, lis3dh.mjs).
# Where the datasheet is silent the model assumes, and says so: a read of the outputs with the
# FIFO empty (EMPTY = 1) returns the latest conversion (what bypass would show) and pops nothing;
# FSS saturates at 31 with OVRN_FIFO marking the 32nd; the per-axis XDA..ZOR bits, the
# interrupt generators, click, BLE, self-test and the high-pass filter are not modelled (read 0,
# or as written).
import struct

WHO_AM_I_VALUE = 0x33
_ODR_HZ = (0, 1, 10, 25, 50, 100, 200, 400, 1600, 1344)
_SO_MG = (1, 2, 4, 12)  # mg/digit at 12 bits for FS = 2, 4, 8, 16 g

_REG_STATUS_AUX = 0x07
_REG_OUT_ADC1_L = 0x08
_REG_WHO_AM_I = 0x0F
_REG_TEMP_CFG = 0x1F
_REG_CTRL1 = 0x20
_REG_CTRL3 = 0x22
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
        self.out = [0, 0, 0]      # the latest conversion
        self.shown = [0, 0, 0]    # what the output registers show (BDU holds an axis here)
        self.held = [False, False, False]
        self.dropped = 0        # ground truth: samples the FIFO overwrote or refused
        self.generated = 0      # ground truth: samples produced since the ODR was set
        self.exhausted = False
        # The stimulus is the world's time line, from the moment the board powers up (the clock
        # may start anywhere: a test puts its ticks' wrap where it wants it).  Times are kept as
        # whole seconds and microseconds, as the clock keeps them (vclock.py: 32-bit faithful).
        self.epoch_s = clock.s
        self.epoch_us = clock.us
        self.spi_selected = False   # the SPI front end: CS low
        self._spi_cmd = -1          # this transaction's first byte (-1: not clocked in yet)
        self._spi_reg = 0
        self._reset()

    def _reset(self):
        for i in range(len(self.regs)):
            self.regs[i] = 0
        self.regs[_REG_WHO_AM_I] = WHO_AM_I_VALUE
        self.regs[_REG_CTRL1] = 0x07
        self.fifo_level = 0     # u: unread sets
        self.fifo_head = 0
        self.fifo_stopped = False   # FIFO mode filled up: nothing more until bypass
        self._start()
        for i in range(3):
            self.out[i] = 0
            self.shown[i] = 0
            self.held[i] = False
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
        """FM[1:0] when FIFO_EN is set, else 0 (bypass)."""
        if not self.regs[_REG_CTRL5] & 0x40:
            return 0
        return (self.regs[_REG_FIFO_CTRL] >> 6) & 3

    def fth(self):
        return self.regs[_REG_FIFO_CTRL] & 0x1F

    def wtm(self):
        return self.fifo_level > self.fth()

    def int1(self):
        c3 = self.regs[_REG_CTRL3]
        return bool((c3 & 0x04 and self.wtm()) or (c3 & 0x02 and self.fifo_level == 32))

    def _collecting_mode(self):
        # what the FIFO does with the next set: 1 FIFO (stops when full), 2 stream (overwrites)
        m = self.fifo_mode()
        if m == 3:  # stream-to-FIFO: by the trigger pin (TR: INT1 or INT2; INT2 stays low)
            pin = False if self.regs[_REG_FIFO_CTRL] & 0x20 else self.int1()
            return 1 if pin else 2
        return m

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
            for i in range(3):
                if not self.held[i]:
                    self.shown[i] = out[i]
            if self.new_data:
                self.overrun = True
            self.new_data = True
            self._store(out)

    def _store(self, out):
        mode = self._collecting_mode()
        if not mode:
            return
        if self.fifo_stopped and self.fifo_mode() == 1:
            self.dropped += 1
            return
        if self.fifo_level < 32:
            slot = self.fifo[(self.fifo_head + self.fifo_level) % 32]
            self.fifo_level += 1
            if self.fifo_level == 32 and self.fifo_mode() == 1:
                self.fifo_stopped = True
        elif mode == 2:  # stream: the oldest set is overwritten
            slot = self.fifo[self.fifo_head]
            self.fifo_head = (self.fifo_head + 1) % 32
            self.dropped += 1
        else:  # FIFO mode stops collecting when full
            self.dropped += 1
            return
        # The FIFO keeps 10 bits: the top 10 of the left-justified output.
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
            axis = k >> 1
            if self.fifo_mode():
                # empty: the latest conversion, nothing popped (the datasheet is silent)
                v = (self.fifo[self.fifo_head] if self.fifo_level else self.out)[axis]
                if k == 5 and self.fifo_level > 0:
                    self.fifo_head = (self.fifo_head + 1) % 32
                    self.fifo_level -= 1
            else:
                v = self.shown[axis]
                if self.regs[_REG_CTRL4] & 0x80:
                    self.held[axis] = not (k & 1)  # BDU: held from its low byte to its high
                if not self.held[axis]:
                    self.shown[axis] = self.out[axis]
                if k == 5:
                    self.new_data = False
                    self.overrun = False
            return (v >> 8) & 0xFF if k & 1 else v & 0xFF
        if reg == _REG_STATUS:
            return (0x08 if self.new_data else 0) | (0x80 if self.overrun else 0)
        if reg == _REG_FIFO_SRC:
            u = self.fifo_level
            return ((0x80 if u > self.fth() else 0) | (0x40 if u == 32 else 0)
                    | (0x20 if u == 0 else 0) | (31 if u == 32 else u))
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

    def spi_select(self, low):
        """CS: low (True) starts a transaction, high ends it."""
        self.spi_selected = low
        self._spi_cmd = -1

    def spi_byte(self, v):
        """One byte clocked in on SDI while CS is low; returns the byte clocked out on SDO."""
        if not self.spi_selected:
            return 0
        if self._spi_cmd < 0:   # the first byte: RW, MS, AD5:0
            self._spi_cmd = v
            self._spi_reg = v & 0x3F
            self.catch_up()
            return 0
        reg = self._spi_reg
        if self._spi_cmd & 0x40:   # MS: the next address, rolling over in a FIFO mode
            self._spi_reg = _REG_OUT_X_L if reg + 1 == _REG_OUT_X_L + 6 and self.fifo_mode() else reg + 1
        if self._spi_cmd & 0x80:
            return self._read_byte(reg)
        self._write_byte(reg, v)
        return 0

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
            if self.fifo_mode() == 0:  # bypass empties the FIFO and restarts it
                self.fifo_level = 0
                self.fifo_head = 0
                self.fifo_stopped = False
