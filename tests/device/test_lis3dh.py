"""The LIS3DH drivers against the register-level simulated chip: our MicroPython driver, the real
adafruit_lis3dh, and the CircuitPython variant read the same registers identically."""
import sys

import numpy as np
import pytest


from accelcal.locations import CHIP_DIR  # noqa: E402
sys.path.insert(0, str(CHIP_DIR))
from vbus import BusioI2C, I2C  # noqa: E402
from vclock import Clock  # noqa: E402
from vlis3dh import SimLIS3DH, Stimulus  # noqa: E402

import adafruit_lis3dh  # noqa: E402
from acal.logger import lis3dh, lis3dh_cp, lis3dh_spi  # noqa: E402
from accelcal.simulate.stimulus import write_stimulus  # noqa: E402

G = adafruit_lis3dh.STANDARD_GRAVITY


@pytest.fixture
def chip(tmp_path, rng):
    n = 4000
    t = np.arange(n) / 400
    xyz = np.column_stack([0.3 * np.sin(t), 0.5 * np.cos(3 * t), 0.8 + 0 * t]) + rng.normal(scale=0.002, size=(n, 3))
    temp = 20 + 0.01 * np.arange(n)
    path = tmp_path / "stim.bin"
    write_stimulus(path, 400, xyz, temp)
    clock = Clock()
    return SimLIS3DH(Stimulus(str(path)), clock), clock, xyz


def test_who_am_i_and_wrong_address(chip):
    c, clock, _ = chip
    with pytest.raises(lis3dh.LIS3DHError, match="no LIS3DH at 0x19"):
        lis3dh.LIS3DH(I2C({0x18: c}), address=0x19)


@pytest.mark.parametrize("range_g,divider,const", [(2, 16380, adafruit_lis3dh.RANGE_2_G),
                                                   (4, 8190, adafruit_lis3dh.RANGE_4_G),
                                                   (16, 1365, adafruit_lis3dh.RANGE_16_G)])
def test_adafruit_and_ours_read_the_same_registers(chip, range_g, divider, const):
    c, clock, _ = chip
    ours = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400, range_g=range_g)
    theirs = adafruit_lis3dh.LIS3DH_I2C(BusioI2C({0x18: c}), address=0x18)
    # adafruit's constructor reboots and sets 400 Hz, HR, BDU: put our range back through it.
    theirs.range = const
    assert theirs.range == const and theirs.data_rate == adafruit_lis3dh.DATARATE_400_HZ
    ours.high_res = True
    n = 0
    for _ in range(300):
        clock.sleep_us(2500)
        ax, ay, az = theirs.acceleration
        raw = [round(a / G * divider) for a in (ax, ay, az)]
        d = ours.dither
        ours.read_sample()
        exp = [ours._to_q10(r, ours._shift, ours._so_mg, d) for r in raw]
        assert [ours.x, ours.y, ours.z] == exp
        n += 1
    assert n == 300
    assert theirs.read_adc_raw(3) >> 8 == ours.temperature()


def test_circuitpython_driver_matches_micropython_driver(chip):
    c, clock, xyz = chip
    mp = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400)
    cp = lis3dh_cp.make(BusioI2C({0x18: c}), rate_hz=400)
    for k in range(200):
        clock.sleep_us(2500)
        mp.read_sample()
        cp.read_sample()
        assert (mp.x, mp.y, mp.z) == (cp.x, cp.y, cp.z)
    with pytest.raises(lis3dh.LIS3DHError):
        lis3dh_cp.make(BusioI2C({0x18: c}), address=0x19)


def test_register_reads_match_stimulus_to_a_digit(chip):
    c, clock, xyz = chip
    d = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400, range_g=2)
    got, k = [], []
    for i in range(1000):
        clock.sleep_us(2500)
        assert d.data_ready()
        d.read_sample()
        got.append((d.x, d.y, d.z))
        k.append(c.generated)
    # a 1 mg digit (rounded: <= 0.5 mg) read as Q10 g (floor with a dither in [0, 1) LSB:
    # < 0.98 mg either way)
    err = np.array(got) / 1024 - xyz[np.array(k)]
    assert np.abs(err).max() < 0.0015


def test_the_drivers_dither_is_the_formats(chip):
    """The driver rounds onto Q10 with the format's dither (acal.core.fixed.DITHER_STEP), one
    a sample in the order it reads them, by either read, as the host rounds a recording's
    samples (fixedpoint.dither): the same sequence from its first sample; and viper's copies of
    the constants are the format's."""
    from acal.core import fixed
    from accelcal.fixedpoint import dither
    assert (lis3dh._DITHER_STEP, lis3dh._DITHER_MASK) == (fixed.DITHER_STEP, fixed.DITHER_MASK)
    c, clock, xyz = chip
    d = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400)
    seen = []
    for _ in range(50):
        clock.sleep_us(2500)
        seen.append(d.dither)
        d.read_sample()
    f = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400, fifo=True)
    for n in (20, 7):
        clock.sleep_us(2500 * n)
        seen.append(f.dither)
        f.read_fifo([0] * 96, 0, f.fifo_level())
    assert seen[:50] == dither(0, 50).tolist()
    assert seen[50:] == [0, int(dither(20, 1)[0])] and f.dither == dither(27, 1)[0]


def test_fifo_keeps_10_bits_and_counts_overrun(chip):
    c, clock, xyz = chip
    d = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400, fifo=True)
    clock.sleep_us(2500 * 20)
    n = d.fifo_level()
    assert n == 20 and not d.overrun
    out = [0] * 96
    d.read_fifo(out, 0, n)
    q = np.array(out[:3 * n]) / 1.024 - 1.5   # Q10 g back to mg, less the middle of a code
    # 4 mg steps at +-2 g, to Q10's floor with a dither in [0, 1) LSB (< 0.98 mg either way) and
    # 16777 / 16384 for 1.024 (0.03 LSB low at most)
    assert np.abs(q - 4 * np.round(q / 4)).max() <= 1.01
    assert d.fifo_level() == 0
    clock.sleep_us(2500 * 40)  # 40 samples into 32 places: 8 overwritten
    assert d.fifo_level() == 32 and d.overrun and c.dropped == 8


class _IndexStimulus:
    """A stimulus that records which sample the chip reads."""
    rate_hz = 0

    def __init__(self, rate_hz):
        self.rate_hz = rate_hz
        self.k = []
        self.x = self.y = self.z = self.temp_mc = 0

    def load(self, k):
        self.k.append(k)
        return True


@pytest.mark.parametrize("odr", [1, 2, 3, 4, 5, 6, 7, 8, 9])
def test_sample_times_and_stimulus_indices_are_the_plain_formulas(odr, rng):
    """The simulated chip keeps time in seconds and microseconds (32-bit faithful); the samples
    it converts and the stimulus samples they read are the plain unbounded-int formulas: sample
    n at start + n * (10^6 // hz) us, reading stimulus sample floor(t * rate / 10^6), at every
    ODR (1344 Hz's period does not divide a second), from clocks started anywhere."""
    hz = (0, 1, 10, 25, 50, 100, 200, 400, 1600, 1344)[odr]
    period = 10 ** 6 // hz
    for start in (0, (1 << 30) - 777, 5 * 10 ** 11 + 123):
        rate = int(rng.choice([10, 25, 100, 1000]))
        stim = _IndexStimulus(rate)
        c = Clock(start_us=start)
        chip = SimLIS3DH(stim, c)
        c.sleep_us(12345)
        chip.write(0x20, bytearray([(odr << 4) | 7]), 0, 1)
        t0 = c.now_us()
        for _ in range(40):
            c.sleep_us(int(rng.integers(1, 3 * 10 ** 6)))
            chip.catch_up()
            assert chip.generated == (c.now_us() - t0) // period
        want = [((t0 + n * period - start) * rate) // 10 ** 6 for n in range(1, chip.generated + 1)]
        assert stim.k == want


# --- the FIFO's conversion as a viper loop (lis3dh.fifo_codes_q10) ------------------------------

FIFO_SCRIPT = r'''
from array import array
from acal.logger import lis3dh
b = bytearray(%r)
for so_mg in (1, 2, 4, 12):
    for mid in (0, 3):
        out = array("i", [7] * (len(b) // 2 + 2))
        nxt = lis3dh.fifo_codes_q10(b, 0, len(b) // 2, out, 1, mid, so_mg * 16777, %d, 16000)
        print(" ".join(str(v) for v in out), nxt)
        # from a sample inside the read on (the app's drain across its block's end)
        out = array("i", [7] * (len(b) // 2 + 2))
        nxt = lis3dh.fifo_codes_q10(b, 300, len(b) // 2, out, 1, mid, so_mg * 16777, %d, 16000)
        print(" ".join(str(v) for v in out), nxt)
'''


def fifo_to_q10(raw, mid, so_mg, d):
    """The documented conversion of one FIFO value, written out value by value (the reference
    lis3dh.fifo_codes_q10 and lis3dh_cp's tables are held to): raw the left-justified 16-bit
    value, its top 10 bits r in half 12-bit digits (8 r + mid, mid = 3 in HR mode: the middle of
    the code's four digits), so_mg mg a 12-bit digit, d the sample's dither (2**-14 LSB): Q10 g
    as (h * 16777 + 2 d) >> 15 (x 1.024 / 2), clamped to +-SAMPLE_MAX."""
    from acal.core.fixed import SAMPLE_MAX
    h = ((raw >> 6) * 8 + mid) * so_mg
    v = (h * 16777 + (d << 1)) >> 15
    return max(-SAMPLE_MAX, min(SAMPLE_MAX, v))


def fifo_codes_every_value(rng):
    # every 10-bit code, each with random bits below the 10 (the chip leaves them 0; a
    # read past the stored samples is undefined), as the little-endian bytes the bus gives
    raw = ((np.arange(-512, 512) << 6) | rng.integers(0, 64, 1024)) & 0xFFFF
    return raw, bytes(np.column_stack([raw & 0xFF, raw >> 8]).astype(np.uint8).ravel())


def test_fifo_conversion_is_the_documented_one_on_micropython(rng, tmp_path):
    """The viper loop read_fifo converts with, run by the MicroPython unix port as the boards'
    emitters compile it, gives fifo_to_q10 of every 10-bit code, at every range, in
    HR mode (a code read as its middle) and not, clamped at SAMPLE_MAX, with the dither of each
    sample (three values) from the one given (16000: it wraps), returning the next sample's;
    the cells around the destination are untouched; and from a value inside the read on."""
    from acal.core.fixed import SAMPLE_MAX
    from accelcal.bridge import runtime
    raw, data = fifo_codes_every_value(rng)
    f = tmp_path / "fifo.py"
    f.write_text(FIFO_SCRIPT % (data, SAMPLE_MAX, SAMPLE_MAX))
    got = [list(map(int, line.split())) for line in
           runtime.run_micropython_script(str(f)).strip().splitlines()]
    signed = [int(v) - 0x10000 if v & 0x8000 else int(v) for v in raw]
    dith = [(16000 + (j // 3) * 10127) & 16383 for j in range(len(signed))]
    nxt = (16000 + len(signed) // 3 * 10127) & 16383   # 341 whole samples of 1024 values
    late = signed[300:]
    nxt_late = (16000 + len(late) // 3 * 10127) & 16383
    want = []
    for so_mg in (1, 2, 4, 12):
        for mid in (0, 3):
            want.append([7] + [fifo_to_q10(v, mid, so_mg, e) for v, e in zip(signed, dith)]
                        + [7, nxt])
            want.append([7] + [fifo_to_q10(v, mid, so_mg, e) for v, e in zip(late, dith)]
                        + [7] * 301 + [nxt_late])
    assert got == want
    assert max(map(max, want)) == SAMPLE_MAX and min(map(min, want)) == -SAMPLE_MAX  # clamped
    # and CPython's run of the same source (the WebAssembly port and CircuitPython run it so)
    out = [7] * 1026
    assert lis3dh.fifo_codes_q10(data, 0, 1024, out, 1, 3, 12 * 16777, SAMPLE_MAX, 16000) == nxt
    assert out == want[-2][:-1]


def test_fifo_tables_give_the_same_values_for_every_code_and_dither(rng):
    """CircuitPython's conversion (no emitters: lis3dh_cp.fifo_tables and fifo_codes_table, as FifoTables.convert) gives
    what fifo_codes_q10 gives: the tables against the formula for every 10-bit code and every
    dither (2**14), at every range, HR or not, clamped at SAMPLE_MAX; and the loop over the
    every-code data of the test above, from the dither 16000 on, the same values and the same
    next dither, the cells around the destination untouched."""
    from acal.core.fixed import SAMPLE_MAX
    raw, data = fifo_codes_every_value(rng)
    u = np.arange(1024)
    r = np.where(u & 512, u - 1024, u).astype(np.int64)[:, None]
    d2 = 2 * np.arange(16384, dtype=np.int64)[None, :]
    for so_mg in (1, 2, 4, 12):
        for mid in (0, 3):
            so = so_mg * 16777
            v0, carry = lis3dh_cp.fifo_tables(mid, so, SAMPLE_MAX)
            want = np.clip(((r * 8 + mid) * so + d2) >> 15, -SAMPLE_MAX, SAMPLE_MAX)
            got = np.array(v0, dtype=np.int64)[:, None] + (d2 >= np.array(carry)[:, None])
            assert np.array_equal(got, want), (so_mg, mid)
            ref = [7] * 1026
            nxt = lis3dh.fifo_codes_q10(data, 0, 1024, ref, 1, mid, so, SAMPLE_MAX, 16000)
            out = [7] * 1026
            tables = lis3dh_cp.FifoTables(mid, so, SAMPLE_MAX)
            assert tables.convert(data, 0, 1023, out, 1, 16000) == \
                lis3dh.fifo_codes_q10(data, 0, 1023, [0] * 1024, 0, mid, so, SAMPLE_MAX, 16000)
            assert out[:1024] == ref[:1024] and out[1024:] == [7, 7]
            late = [7] * 1026     # from a sample inside the read on
            assert tables.convert(data, 300, 1023, out, 1, 16000) == \
                lis3dh.fifo_codes_q10(data, 300, 1023, late, 1, mid, so, SAMPLE_MAX, 16000)
            assert out[:724] == late[:724]
    assert nxt == (16000 + 341 * 10127) & 16383


def test_read_fifo_is_its_raw_read_and_conversions_in_parts(chip):
    """read_fifo_raw, then fifo_convert in parts (as the app converts a drain into its block,
    across the block's end), gives the values and the next dither of one conversion of the whole
    read, with the tables and without."""
    c, clock, _ = chip
    d = lis3dh.LIS3DH(I2C({0x18: c}), rate_hz=400, fifo=True)
    for _ in range(3):
        clock.sleep_us(60_000)
        n = d.fifo_level()
        assert n >= 20
        d.read_fifo_raw(n)
        first = d.dither
        whole = [7] * 99
        d.fifo_convert(whole, 1, 0, n)
        after = d.dither
        assert after != first and whole[:3] == [7] * 3 and whole[3 + 3 * n:] == [7] * (96 - 3 * n)
        for tables in (False, True):
            if tables:
                d.use_fifo_tables()
            d.dither = first
            parts = [7] * 99
            d.fifo_convert(parts, 1, 0, 7)
            d.fifo_convert(parts, 8, 7, n - 7)
            assert parts == whole and d.dither == after
        d.fifo_tables = None     # without the tables again


# ---------------------------------------------------------------- SPI (DocID17530 6.2)
from vbus import BusioSPI, DigitalInOut, Pin, SPI  # noqa: E402


def _two_chips(tmp_path, rng):
    """Two simulated chips on one stimulus and two clocks kept in step: one read over I2C,
    the other over SPI."""
    n = 4000
    t = np.arange(n) / 400
    xyz = np.column_stack([0.3 * np.sin(t), 1.5 * np.cos(3 * t), 0.8 + 0 * t]) + rng.normal(scale=0.002, size=(n, 3))
    write_stimulus(tmp_path / "stim.bin", 400, xyz, 20 + 0.01 * np.arange(n))
    a, b = Clock(), Clock()
    return (SimLIS3DH(Stimulus(str(tmp_path / "stim.bin")), a), a,
            SimLIS3DH(Stimulus(str(tmp_path / "stim.bin")), b), b)


def test_the_driver_on_spi_reads_what_it_reads_on_i2c(tmp_path, rng):
    """The same driver over SPIRegisters (machine.SPI + a CS Pin) and over I2C, on two chips fed
    alike: every register sample, every FIFO drain and level, the temperature agree."""
    ci, ki, cs_, ks = _two_chips(tmp_path, rng)
    for fifo in (False, True):
        i2c = lis3dh.LIS3DH(I2C({0x18: ci}), rate_hz=400, range_g=4, fifo=fifo, fth=11)
        spi = lis3dh.LIS3DH(lis3dh_spi.SPIRegisters(SPI(cs_), Pin(cs_)), rate_hz=400, range_g=4,
                            fifo=fifo, fth=11)
        a, b = [0] * 96, [0] * 96
        for k in range(120):
            ki.sleep_us(2500 * (1 + k % 40))
            ks.sleep_us(2500 * (1 + k % 40))
            if fifo:
                n = i2c.fifo_level()
                assert (n, i2c.overrun, i2c.wtm) == (spi.fifo_level(), spi.overrun, spi.wtm)
                i2c.read_fifo(a, 0, n)
                spi.read_fifo(b, 0, n)
                assert a[:3 * n] == b[:3 * n] and n > 0
            else:
                assert i2c.data_ready() == spi.data_ready()
                i2c.read_sample()
                spi.read_sample()
                assert (i2c.x, i2c.y, i2c.z) == (spi.x, spi.y, spi.z)
            assert i2c.temperature() == spi.temperature()
    assert ci.dropped == cs_.dropped > 0        # the FIFO filled and overran, alike


class _Wire:
    """A device that records each SPI transaction's bytes (CS low to high) and answers 0."""

    def __init__(self):
        self.frames, self.cur = [], None

    def spi_select(self, low):
        if low:
            self.cur = []
        else:
            self.frames.append(self.cur)

    def spi_byte(self, v):
        self.cur.append(v)
        return 0x33 if self.cur == [0x8F, 0] else 0


def test_the_driver_s_spi_first_byte_is_the_datasheet_s():
    """DocID17530 6.2: RW (bit 7) 1 to read, MS (bit 6) 1 to increment, AD5:0; a write is RW = 0,
    its address, its byte, all within one CS low."""
    w = _Wire()
    d = lis3dh.LIS3DH(lis3dh_spi.SPIRegisters(SPI(w), Pin(w)), rate_hz=100, fifo=True, fth=24)
    assert w.frames[0] == [0x8F, 0]                       # WHO_AM_I: read, one byte, no MS
    assert [0x24, 0x80] in w.frames and [0x2E, 0x80 | 24] in w.frames   # BOOT; stream, FTH 24
    w.frames.clear()
    d.fifo_level()
    d.read_fifo([0] * 96, 0, 2)
    d.read_sample()
    assert w.frames == [[0xAF, 0], [0xE8] + [0] * 12, [0xE8] + [0] * 6]


def test_adafruit_lis3dh_spi_reads_our_model(chip):
    """A third party's SPI protocol (adafruit_lis3dh.LIS3DH_SPI, over busio's API and
    adafruit_bus_device, SPI mode 0) on the simulated chip's SPI front end reads what our driver
    reads over SPI (mode 3, lis3dh_cp.BusioSPIRegisters)."""
    c, clock, _ = chip
    theirs = adafruit_lis3dh.LIS3DH_SPI(BusioSPI(c), DigitalInOut(c))
    assert theirs.data_rate == adafruit_lis3dh.DATARATE_400_HZ and theirs.range == adafruit_lis3dh.RANGE_2_G
    bus = BusioSPI(c)
    ours = lis3dh.LIS3DH(lis3dh_cp.BusioSPIRegisters(bus, DigitalInOut(c)), rate_hz=400)
    assert bus.mode == (1, 1) and bus.baudrate == lis3dh_cp.SPI_BAUD
    for _ in range(200):
        clock.sleep_us(2500)
        ax, ay, az = theirs.acceleration
        raw = [round(a / G * 16380) for a in (ax, ay, az)]
        d = ours.dither   # the sample's dither (the Q10 format's rounding, fixed.DITHER_STEP)
        ours.read_sample()
        assert [ours.x, ours.y, ours.z] == [ours._to_q10(r, ours._shift, ours._so_mg, d) for r in raw]
    assert theirs.read_adc_raw(3) >> 8 == ours.temperature()
