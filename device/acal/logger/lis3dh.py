# ST LIS3DH driver over a machine.I2C-style bus (readfrom_mem_into / writeto_mem), integer-only.
# Register names follow the datasheet (DocID17530).  Samples come out in Q10 g (fixed.py).
#
# Register fields as ST's datasheet and lis3dh_reg.h give them (docs/lis3dh-conformance.md, each
# row checked against this driver and both chip models).  Two ways to read:
#   read_sample()  - the output registers: 12 bits in high-resolution mode (1 mg/digit at +-2 g),
#                    one bus transaction a sample (the emulated Pico at 100 Hz loses 8-9 % so).
#   read_fifo()    - the 32-level FIFO in stream mode, drained when its watermark is passed: what
#                    the app uses by default, nothing lost, but it keeps 10 bits (4 mg steps at
#                    +-2 g, the HR value's two low bits dropped).  A 10-bit code r of an HR
#                    conversion stands for the four 12-bit digits 4r..4r+3: it is read as their
#                    middle, 4r + 1.5, not 4r, so the truncation's -1.5 digit bias does not reach
#                    rest means (docs/boards-and-logs.md "Acquisition").
# FIFO_SRC_REG (2Fh): bit 7 WTM (unread > FTH), bit 6 OVRN_FIFO (32 unread: the next conversion
# overwrites the oldest), bit 5 EMPTY, bits 4:0 FSS (unread, 0..31): the level is 32 when
# OVRN_FIFO is set, else FSS -- never WTM, which says nothing about how many.
# Buses: LIS3DH takes a bus with machine.I2C's register calls (readfrom_mem_into, writeto_mem; the
# sub-address's bit 7 asks for auto-increment, DocID17530 6.1.1).  lis3dh_spi.SPIRegisters gives
# those calls over a machine.SPI and a chip-select Pin (its own module: a board with the chip on
# I2C loads none of it).
# Temperature: OUT_ADC3 gives the change from an unknown chip reference, 1 digit/degC; an absolute
# value needs one reference reading (the board file's TEMP_REF_C), else it stays relative.
try:
    from micropython import const
except ImportError:
    def const(x):
        return x

from acal.core.fixed import SAMPLE_MAX
from acal.core.emit import viper, ptr8, ptr32

# The FIFO's codes convert by fifo_codes_q10: viper on ports with emitters, CPython on the host.
# A port without emitters (CircuitPython) converts faster through two tables built once per
# configuration (lis3dh_cp.FifoTables, 4 kB: 1.9 ms a drain of 25 samples on the emulated Feather
# instead of fifo_codes_q10's 3.1 ms as bytecode): LIS3DH(tables=True), which the app passes
# where the board file says FIFO_TABLES = True (boards/feather_rp2040.py).  The tables' code is
# lis3dh_cp's, which only CircuitPython boards get: a board with emitters holds none of it.

ADDRESS = const(0x18)        # SDO/SA0 low; 0x19 when high
WHO_AM_I_VALUE = const(0x33)

_STATUS_REG_AUX = const(0x07)
_OUT_ADC3_L = const(0x0C)
_WHO_AM_I = const(0x0F)
_TEMP_CFG_REG = const(0x1F)
_CTRL_REG1 = const(0x20)
_CTRL_REG4 = const(0x23)
_CTRL_REG5 = const(0x24)
_STATUS_REG = const(0x27)
_OUT_X_L = const(0x28)
_FIFO_CTRL_REG = const(0x2E)
_FIFO_SRC_REG = const(0x2F)
_AUTO_INC = const(0x80)
# SPI's first byte (DocID17530 6.2): bit 7 RW (1: read), bit 6 MS (1: the address increments)
_SPI_READ = const(0x80)
_SPI_MS = const(0x40)
_SPI_AD = const(0x3F)
# FIFO_SRC_REG bits
_WTM = const(0x80)
_OVRN_FIFO = const(0x40)
_FSS = const(0x1F)
FIFO_DEPTH = const(32)
_STREAM = const(0x80)        # FIFO_CTRL_REG FM[1:0] = 10

# CTRL_REG1 ODR codes by rate in Hz.
ODR_CODES = {1: 1, 10: 2, 25: 3, 50: 4, 100: 5, 200: 6, 400: 7}
RANGES_G = (2, 4, 8, 16)
_SO_MG = (1, 2, 4, 12)       # mg/digit at 12 bits, by range
# mg -> Q10 g: x 1.024 = 16777 / 16384 (error 1.4e-5); mg <= 24 576 keeps the product < 2**30.
_MG_Q10_MUL = const(16777)
_MG_Q10_SHIFT = const(14)
# FIFO codes in half digits (Q1): x 1.024 / 2 = 16777 / 32768; |(8 r + 3) * 12| <= 49 188 (r: a
# 10-bit code, |r| <= 512; 12 mg at +-16 g) keeps the product below 8.3e8 < 2**30.
_HALF_MG_Q10_SHIFT = const(15)
# The rounding onto Q10 is the format's (acal.core.fixed: DITHER_*): floor with a dither d of the
# sample's index, d = (i * 10127) & 16383 in 2**-14 LSB (the driver's i: samples read since it was
# made), added in place of the half: (mg * _MG_Q10_MUL + d) >> 14, and in half digits d << 1
# before the >> 15.  Both sums stay below 2**30 (4.12e8 + 16383; 8.3e8 + 32766).  Viper does
# not fold an imported name: the values are fixed.DITHER_STEP and DITHER_MASK (test_lis3dh).
_DITHER_STEP = const(10127)
_DITHER_MASK = const(16383)


class LIS3DHError(Exception):
    pass


def spi_command(memaddr, read):
    """SPI's first byte (DocID17530 6.2) for an I2C sub-address memaddr: a read is RW | MS | AD5:0,
    MS (the address increments) where memaddr's bit 7 asks for it, as over I2C (6.1.1); a write
    RW = 0, AD5:0.  Both SPI register classes (lis3dh_spi's, lis3dh_cp's) frame their bytes so."""
    if read:
        return _SPI_READ | (_SPI_MS if memaddr & _AUTO_INC else 0) | (memaddr & _SPI_AD)
    return memaddr & _SPI_AD


def answers(regs, address=ADDRESS):
    """True when WHO_AM_I reads 0x33 on regs (a bus with the register calls); a bus error is
    False."""
    b = bytearray(1)
    try:
        regs.readfrom_mem_into(address, _WHO_AM_I, b)
    except OSError:
        return False
    return b[0] == WHO_AM_I_VALUE


def open_bus(bus, spi, i2c):
    """The LIS3DH's register bus for a board's setting bus: "spi" (spi()), "i2c" (i2c()) or
    "auto": spi() if WHO_AM_I answers 0x33 there, else i2c() (with nothing on SPI, MISO reads
    what it floats to; a Pico's pads pull it down: 0).  spi and i2c: the board's functions."""
    if bus not in ("auto", "spi", "i2c"):
        raise ValueError("bus must be 'auto', 'spi' or 'i2c'")
    if bus != "i2c":
        s = spi()
        if bus == "spi" or answers(s):
            return s
    return i2c()


class LIS3DH:
    """rate_hz: output data rate (1..400); range_g: 2, 4, 8 or 16; high_res: 12-bit outputs;
    fifo: stream-mode FIFO; fth: its watermark, FTH (0..31): FIFO_SRC_REG's WTM (self.wtm after
    fifo_level()) says more than fth samples wait; tables: the FIFO's codes convert through
    lis3dh_cp.FifoTables (use_fifo_tables: for ports without emitters).  After read_sample() the
    sample is in x, y, z (Q10 g)."""

    def __init__(self, i2c, address=ADDRESS, rate_hz=100, range_g=2, high_res=True, fifo=False,
                 fth=0, tables=False):
        if rate_hz not in ODR_CODES:
            raise ValueError("rate_hz must be one of 1, 10, 25, 50, 100, 200, 400")
        if range_g not in RANGES_G:
            raise ValueError("range_g must be 2, 4, 8 or 16")
        if not 0 <= fth <= 31:
            raise ValueError("fth must be 0..31")
        self.i2c = i2c
        self.address = address
        self.rate_hz = rate_hz
        self.range_g = range_g
        self.high_res = high_res
        self.fifo = fifo
        self.fth = fth
        self._one = bytearray(1)
        self._two = bytearray(2)
        self._xyz = bytearray(6)
        self._fifo_buf = bytearray(6 * 32)
        # Preallocated views: slicing a memoryview allocates, so take all 33 lengths once (the
        # conversion reads the buffer itself from a sample's index: no views for it).
        mv = memoryview(self._fifo_buf)
        self._fifo_views = [mv[0:6 * n] for n in range(33)]
        self.x = 0
        self.y = 0
        self.z = 0
        self.dither = 0      # the next sample's dither (2**-14 LSB): the Q10 rounding's
        self.overrun = False
        self.wtm = False
        bits = 12 if high_res else 10
        self._shift = 16 - bits
        self._so_mg = _SO_MG[RANGES_G.index(range_g)] << (12 - bits)
        # the FIFO keeps 10 bits whatever the mode: 4 12-bit digits a code; in HR mode a code
        # is read as the middle of its four (+1.5 digits = 3 half digits), else it is exact
        self._fifo_so_mg = _SO_MG[RANGES_G.index(range_g)]    # mg a 12-bit digit
        self._fifo_mid = 3 if high_res else 0
        self.fifo_tables = None   # lis3dh_cp.FifoTables (use_fifo_tables)
        if tables:
            self.use_fifo_tables()
        self.check()
        self.configure()

    # --- registers --------------------------------------------------------------------------
    def _read_u8(self, reg):
        self.i2c.readfrom_mem_into(self.address, reg, self._one)
        return self._one[0]

    def _write_u8(self, reg, value):
        self._one[0] = value
        self.i2c.writeto_mem(self.address, reg, self._one)

    def check(self):
        """Raise LIS3DHError unless WHO_AM_I answers 0x33."""
        try:
            who = self._read_u8(_WHO_AM_I)
        except OSError as e:
            raise LIS3DHError("no LIS3DH at 0x%02x (%s)" % (self.address, e))
        if who != WHO_AM_I_VALUE:
            raise LIS3DHError("WHO_AM_I at 0x%02x is 0x%02x, not 0x33" % (self.address, who))

    def configure(self):
        """Reboot the chip's registers, then set rate, range, resolution, BDU, FIFO, temperature."""
        self._write_u8(_CTRL_REG5, 0x80)  # BOOT
        self._write_u8(_CTRL_REG1, (ODR_CODES[self.rate_hz] << 4) | 0x07)
        self._write_u8(_CTRL_REG4, 0x80 | (RANGES_G.index(self.range_g) << 4) | (0x08 if self.high_res else 0))
        self._write_u8(_TEMP_CFG_REG, 0xC0)  # ADC_EN, TEMP_EN (needs BDU, set above)
        if self.fifo:
            self._write_u8(_CTRL_REG5, 0x40)        # FIFO_EN
            self._write_u8(_FIFO_CTRL_REG, _STREAM | self.fth)

    # --- samples ----------------------------------------------------------------------------
    @staticmethod
    def _s16(lo, hi):
        v = lo | (hi << 8)
        return v - 0x10000 if v & 0x8000 else v

    def _to_q10(self, raw, shift, so_mg, d):
        # d: the sample's dither (2**-14 LSB, the format's rounding: fixed.DITHER_STEP)
        mg = (raw >> shift) * so_mg
        v = (mg * _MG_Q10_MUL + d) >> _MG_Q10_SHIFT
        if v > SAMPLE_MAX:
            return SAMPLE_MAX
        if v < -SAMPLE_MAX:
            return -SAMPLE_MAX
        return v

    def data_ready(self):
        """True when the output registers hold a sample not read yet (STATUS_REG ZYXDA);
        overrun tells whether one was missed (ZYXOR)."""
        s = self._read_u8(_STATUS_REG)
        self.overrun = bool(s & 0x80)
        return bool(s & 0x08)

    def read_sample(self):
        """Read the output registers into x, y, z (Q10 g)."""
        b = self._xyz
        self.i2c.readfrom_mem_into(self.address, _OUT_X_L | _AUTO_INC, b)
        d = self.dither
        self.dither = (d + _DITHER_STEP) & _DITHER_MASK
        # (no locals for the shift and scale: a frame of over 11 words comes from the heap)
        self.x = self._to_q10(self._s16(b[0], b[1]), self._shift, self._so_mg, d)
        self.y = self._to_q10(self._s16(b[2], b[3]), self._shift, self._so_mg, d)
        self.z = self._to_q10(self._s16(b[4], b[5]), self._shift, self._so_mg, d)

    def fifo_level(self):
        """Samples waiting in the FIFO (0..32), from FSS and OVRN_FIFO; overrun: the FIFO is
        full (OVRN_FIFO: samples converted from now on overwrite the oldest until it is read);
        wtm: more than fth samples wait (WTM)."""
        s = self._read_u8(_FIFO_SRC_REG)
        self.overrun = bool(s & _OVRN_FIFO)
        self.wtm = bool(s & _WTM)
        return FIFO_DEPTH if s & _OVRN_FIFO else s & _FSS

    def read_fifo(self, out, start, n):
        """Pop n <= 32 samples into the int array out (x y z ..., Q10 g) from sample index start,
        with one bus transaction (the FIFO rolls over OUT_Z_H -> OUT_X_L).  n must not pass the
        level fifo_level() gave: past the stored samples the chip's answer is not defined."""
        self.read_fifo_raw(n)
        self.fifo_convert(out, start, 0, n)

    def read_fifo_raw(self, n):
        """read_fifo's bus transaction alone: n samples' codes wait for fifo_convert."""
        self.i2c.readfrom_mem_into(self.address, _OUT_X_L | _AUTO_INC, self._fifo_views[n])

    @viper
    def fifo_convert(self, out, start: int, first: int, n: int):
        """Samples first..first+n-1 of the last read_fifo_raw into the int array out (Q10 g)
        from sample index start; samples are converted in the order read (each takes the next
        dither)."""
        # a viper loop on ports with emitters (fifo_codes_q10): 92 us a sample as a bytecode
        # loop on the emulated Pico; CircuitPython's tables (above).  Viper itself too: as
        # bytecode, its call with nine arguments took a frame of 16 words, which MicroPython
        # takes from the heap on every call (docs/method-and-formats.md "Frames").
        i = 3 * first
        if self.fifo_tables:   # (viper compares no object with None)
            self.dither = self.fifo_tables.convert(self._fifo_buf, i, i + 3 * n, out, 3 * start,
                                                   self.dither)
            return
        self.dither = fifo_codes_q10(self._fifo_buf, i, i + 3 * n, out, 3 * start,
                                     self._fifo_mid, int(self._fifo_so_mg) * _MG_Q10_MUL,
                                     SAMPLE_MAX, self.dither)

    def use_fifo_tables(self):
        """Convert FIFO codes through two tables (lis3dh_cp.FifoTables, 4 kB) from now on: for
        ports without emitters, where they take ~60 % of fifo_codes_q10's time; the same values."""
        from acal.logger.lis3dh_cp import FifoTables
        self.fifo_tables = FifoTables(self._fifo_mid, self._fifo_so_mg * _MG_Q10_MUL, SAMPLE_MAX)

    def temperature(self):
        """Temperature change from the chip's reference, whole degC (OUT_ADC3, 8 bits)."""
        self.i2c.readfrom_mem_into(self.address, _OUT_ADC3_L | _AUTO_INC, self._two)
        return self._s16(self._two[0], self._two[1]) >> 8


@viper
def fifo_codes_q10(b, i: int, end: int, out, at: int, mid: int, so: int, top: int,
                   dith: int) -> int:
    # The FIFO's codes in Q10 g: the little-endian 16-bit values i..end-1 of the bytearray b (x y
    # z a sample, i a multiple of 3), their top 10 bits in half 12-bit digits (h = (8 r + mid) x
    # mg a digit), (h * _MG_Q10_MUL + 2 d) >> 15 clamped to +-top, into the int array out from
    # index at: a viper loop on ports with emitters.  dith (d): the first sample's dither
    # (2**-14 LSB); returns the next one's (each sample's three values take one).
    # so = mg a 12-bit digit x _MG_Q10_MUL (<= 12 x 16777); |(8 r + 3) so| + 2 * 16383 <= 4099 x
    # 201324 + 32766 < 8.3e8 < 2**30 (r: a 10-bit code, -512..511; tests/device/test_ranges.py).
    # The sign is taken by hand and >> of a viper int is arithmetic, so a 64-bit word (the unix
    # port) gives the same values.
    p = ptr8(b)
    d = ptr32(out)
    at -= i
    k = 0
    while i < end:
        v = int(p[2 * i]) | (int(p[2 * i + 1]) << 8)
        if v & 0x8000:
            v -= 0x10000
        v = (((v >> 6) * 8 + mid) * so + (dith << 1)) >> _HALF_MG_Q10_SHIFT
        if v > top:
            v = top
        elif v < 0 - top:
            v = 0 - top
        d[at + i] = v
        i += 1
        k += 1
        if k == 3:
            k = 0
            dith = (dith + _DITHER_STEP) & _DITHER_MASK
    return dith

