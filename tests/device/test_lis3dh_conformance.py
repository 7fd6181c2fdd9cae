"""docs/lis3dh-conformance.md, row by row: each row's check runs against the Python chip model
(simulate/chip/vlis3dh.py), the Node one (bridge/scripts/lis3dh.mjs) and the driver
(device/acal/logger/lis3dh.py, and lis3dh_cp.py over busio).  The expectations are the datasheet's
(DocID17530) and ST's lis3dh_reg.h, written out here: register addresses, bit positions and
mg/digit from those, not from either model or the driver.  And the old driver's fifo_level(),
kept below as a fixture, fails on a chip that sets WTM where the datasheet does."""
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from accelcal.locations import CHIP_DIR, script
from accelcal.simulate.stimulus import write_stimulus
from conftest import ROOT

sys.path.insert(0, str(CHIP_DIR))
from vbus import BusioI2C, I2C  # noqa: E402
from vclock import Clock  # noqa: E402
from vlis3dh import SimLIS3DH, Stimulus  # noqa: E402

from acal.logger import lis3dh, lis3dh_cp, lis3dh_spi  # noqa: E402
from lis3dh_models import js_model, python_model  # noqa: E402

# lis3dh_reg.h
WHO_AM_I, TEMP_CFG, CTRL1, CTRL3, CTRL4, CTRL5 = 0x0F, 0x1F, 0x20, 0x22, 0x23, 0x24
STATUS, OUT_X_L, FIFO_CTRL, FIFO_SRC, OUT_ADC3_L = 0x27, 0x28, 0x2E, 0x2F, 0x0C
BYPASS, FIFO, STREAM, STREAM_TO_FIFO = 0x00, 0x40, 0x80, 0xC0      # FM[1:0] << 6
WTM, OVRN, EMPTY = 0x80, 0x40, 0x20
ODR_HZ = {1: 1, 2: 10, 3: 25, 4: 50, 5: 100, 6: 200, 7: 400, 9: 1344}   # lis3dh_odr_t
P = 2500          # 400 Hz (ODR code 7): the stimulus' rate too, so conversion n reads sample n
DOC = ROOT / "docs" / "lis3dh-conformance.md"
FILES = {"python": CHIP_DIR / "vlis3dh.py", "node": Path(script("lis3dh.mjs")),
         "driver": ROOT / "device" / "acal" / "logger" / "lis3dh.py"}


def table_rows():
    rows = []
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) == 8 and cells[0] not in ("check",):
            rows.append(dict(zip(("check", "register", "bits", "field", "says", "where", "models",
                                  "driver"), cells)))
    return rows


ROWS = table_rows()


# ---------------------------------------------------------------- the stimulus and the models
def x_g(k):
    return 0.004 * (k % 256)      # 4 mg a sample: each conversion's x tells which sample it is


@pytest.fixture(scope="module")
def stim(tmp_path_factory):
    n = 40000
    k = np.arange(n)
    xyz = np.column_stack([x_g(k), 0.5 + 0 * k, -0.9 + 0 * k])   # no half-digit ties
    path = tmp_path_factory.mktemp("conf") / "stim.bin"
    write_stimulus(path, 400, xyz, 20.0 + k // 400)     # 20 degC, one more each second
    return path


class Script:
    """Register operations at times (us), as both models' test drivers take them."""

    def __init__(self):
        self.ops, self.t, self.n = [], 0, 0

    def at(self, t):
        self.t = t
        return self

    def w(self, reg, *vals):
        self.ops.append([self.t, "w", reg | (0x80 if len(vals) > 1 else 0), list(vals)])

    def r(self, reg, n=1):
        self.ops.append([self.t, "r", reg | (0x80 if n > 1 else 0), n])
        self.n += 1
        return self.n - 1

    def s(self, *frame):
        """One SPI transaction (CS low, these bytes on SDI, CS high): its SDO bytes."""
        self.ops.append([self.t, "s", 0, list(frame)])
        self.n += 1
        return self.n - 1

    def start(self, ctrl4=0x88, ctrl5=0x40, fifo_ctrl=STREAM, ctrl1=0x77, ctrl3=0):
        """At t = 0: the settings, the ODR last (its time line starts there)."""
        self.at(0)
        for reg, v in ((CTRL4, ctrl4), (CTRL3, ctrl3), (CTRL5, ctrl5), (FIFO_CTRL, fifo_ctrl),
                       (CTRL1, ctrl1)):
            self.w(reg, v)
        return self


def s16(lo, hi):
    v = lo | hi << 8
    return v - 0x10000 if v & 0x8000 else v


def xyz16(b, i=0):
    return [s16(b[i + 2 * a], b[i + 2 * a + 1]) for a in range(3)]


def src(u, fth=0):
    """FIFO_SRC_REG for u unread sets, as the datasheet's section 5.1 gives its bits."""
    return (WTM if u > fth else 0) | (OVRN if u == 32 else 0) | (EMPTY if u == 0 else 0) | min(u, 31)


def fifo_xs(reads_of_sets):
    """The sample numbers a FIFO read gave (x's top 10 bits: k % 256 at +-2 g)."""
    out = []
    for b in reads_of_sets:
        for i in range(0, len(b), 6):
            v = xyz16(b, i)[0]
            assert v & 0x3F == 0                          # 10 bits kept
            out.append(v >> 6)
    return out


# ---------------------------------------------------------------- checks on the models
def m_who_am_i(run):
    s = Script()
    i = s.r(WHO_AM_I)
    assert run(s)[i] == [0x33]


def m_ctrl1_odr(run):
    for code, hz in [(0, 0)] + sorted(ODR_HZ.items()):
        period = 10 ** 6 // hz if hz else 10 ** 6
        s = Script().start(fifo_ctrl=FIFO, ctrl1=code << 4 | 7)
        i = s.at(20 * period + period // 2).r(FIFO_SRC)
        assert run(s)[i] == [src(20 if hz else 0)], (code, hz)


def m_ctrl1_lpen(run):
    s = Script().start(ctrl4=0x80, ctrl5=0, ctrl1=0x7F)        # LPen, HR = 0: 8 bits, 16 mg
    i = s.at(100 * P + P // 2).r(OUT_X_L, 6)
    b = run(s)[i]
    assert b[0] == b[2] == b[4] == 0
    assert xyz16(b) == [25 << 8, 31 << 8, -56 << 8]              # 400, 500, -900 mg / 16


def m_ctrl4_hr(run):
    for ctrl4, bits in ((0x88, 12), (0x80, 10)):
        s = Script().start(ctrl4=ctrl4, ctrl5=0)
        i = s.at(100 * P + P // 2).r(OUT_X_L, 6)
        want = (400, 500, -900) if bits == 12 else (100, 125, -225)     # 1 or 4 mg a digit
        assert xyz16(run(s)[i]) == [d << (16 - bits) for d in want]


def m_ctrl4_fs(run):
    for fs, so in enumerate((1, 2, 4, 12)):               # Table 4; lis3dh_from_fs*_hr_to_mg
        s = Script().start(ctrl4=0x88 | fs << 4, ctrl5=0)
        i = s.at(7 * P + P // 2).r(OUT_X_L, 6)
        assert xyz16(run(s)[i])[1:] == [round(500 / so) << 4, round(-900 / so) << 4], fs


def m_ctrl4_bdu(run):
    for ctrl4 in (0x88, 0x08):
        s = Script().start(ctrl4=ctrl4, ctrl5=0)
        lo = s.at(40 * P + P // 2).r(OUT_X_L)
        hi = s.at(48 * P + P // 2).r(OUT_X_L + 1)
        r = run(s)
        k = 40 if ctrl4 & 0x80 else 48                    # BDU: the high byte of sample 40
        assert r[hi] == [((4 * k) << 4) >> 8], ctrl4
        assert r[lo] == [((4 * 40) << 4) & 0xFF]


def m_outputs(run):
    s = Script().start(ctrl5=0)
    i = s.at(200 * P + P // 2).r(OUT_X_L, 6)
    b = run(s)[i]
    assert b[4:6] == [(-900 << 4) & 0xFF, ((-900 << 4) & 0xFFFF) >> 8]    # two's complement
    assert xyz16(b) == [800 << 4, 500 << 4, -900 << 4]


def m_status_zyxda(run):
    s = Script().start(ctrl5=0)
    a = s.at(P // 2).r(STATUS)
    b = s.at(P + P // 2).r(STATUS)
    s.r(OUT_X_L, 6)
    c = s.r(STATUS)
    r = run(s)
    assert [r[a][0] & 0x08, r[b][0] & 0x08, r[c][0] & 0x08] == [0, 0x08, 0]


def m_status_zyxor(run):
    s = Script().start(ctrl5=0)
    a = s.at(P + P // 2).r(STATUS)
    b = s.at(3 * P + P // 2).r(STATUS)
    s.r(OUT_X_L, 6)
    c = s.r(STATUS)
    r = run(s)
    assert [r[a][0] & 0x80, r[b][0] & 0x80, r[c][0] & 0x80] == [0, 0x80, 0]


def m_ctrl5_boot(run):
    s = Script().start()
    s.at(10 * P).w(CTRL5, 0x80)
    regs = [s.r(reg) for reg in (CTRL1, CTRL4, CTRL5, FIFO_CTRL, FIFO_SRC)]
    r = run(s)
    assert [r[i][0] for i in regs] == [0x07, 0, 0, 0, EMPTY]    # defaults; the FIFO emptied


def m_ctrl5_fifo_en(run):
    for ctrl5, u in ((0x00, 0), (0x40, 10)):
        s = Script().start(ctrl5=ctrl5)
        i = s.at(10 * P + P // 2).r(FIFO_SRC)
        assert run(s)[i] == [src(u)], ctrl5


def m_fm_bypass(run):
    s = Script().start()
    a = s.at(10 * P + P // 2).r(FIFO_SRC)
    s.w(FIFO_CTRL, BYPASS)
    b = s.at(20 * P + P // 2).r(FIFO_SRC)
    s.w(FIFO_CTRL, STREAM)
    c = s.at(23 * P + P // 2).r(FIFO_SRC)
    d = s.r(OUT_X_L, 18)
    r = run(s)
    assert [r[a], r[b], r[c]] == [[src(10)], [src(0)], [src(3)]]
    assert fifo_xs([r[d]]) == [21, 22, 23]                # nothing from before the reset


def m_fm_fifo(run):
    s = Script().start(fifo_ctrl=FIFO)
    a = s.at(40 * P + P // 2).r(FIFO_SRC)
    d = s.r(OUT_X_L, 6 * 32)
    b = s.at(50 * P + P // 2).r(FIFO_SRC)                 # read out: still stopped
    s.w(FIFO_CTRL, BYPASS)
    s.w(FIFO_CTRL, FIFO)
    c = s.at(52 * P + P // 2).r(FIFO_SRC)
    r = run(s)
    assert r[a] == [src(32)] and fifo_xs([r[d]]) == list(range(1, 33))
    assert r[b] == [src(0)] and r[c] == [src(2)]


def m_fm_stream(run):
    s = Script().start()
    a = s.at(40 * P + P // 2).r(FIFO_SRC)
    d = s.r(OUT_X_L, 6 * 32)
    b = s.at(43 * P + P // 2).r(FIFO_SRC)
    r = run(s)
    assert r[a] == [src(32)] and fifo_xs([r[d]]) == list(range(9, 41))
    assert r[b] == [src(3)]


def _stream_to_fifo(run, fifo_ctrl, ctrl3):
    s = Script().start(fifo_ctrl=fifo_ctrl, ctrl3=ctrl3)
    d = s.at(40 * P + P // 2).r(OUT_X_L, 6 * 32)
    return fifo_xs([run(s)[d]])


def m_fm_stream_to_fifo(run):
    # INT1 = I1_WTM . WTM rises at 10 unread (FTH 9): FIFO mode from then, the first 32 kept
    assert _stream_to_fifo(run, STREAM_TO_FIFO | 9, 0x04) == list(range(1, 33))
    assert _stream_to_fifo(run, STREAM_TO_FIFO | 9, 0x00) == list(range(9, 41))  # pin low


def m_fifo_tr(run):
    # TR = 1: INT2 triggers, and INT2 has no FIFO source: stream throughout
    assert _stream_to_fifo(run, STREAM_TO_FIFO | 0x20 | 9, 0x04) == list(range(9, 41))


def m_fifo_fth(run):
    s = Script().start(fifo_ctrl=STREAM | 5)
    a = s.at(5 * P + P // 2).r(FIFO_SRC)
    b = s.at(6 * P + P // 2).r(FIFO_SRC)
    s.r(OUT_X_L, 6)
    c = s.r(FIFO_SRC)
    r = run(s)
    assert [r[a], r[b], r[c]] == [[5], [WTM | 6], [5]]


def m_fifo_wtm(run):
    for fth, u, want in ((0, 3, WTM | 3), (0, 0, EMPTY), (31, 31, 31), (31, 32, WTM | OVRN | 31),
                         (24, 24, 24), (24, 25, WTM | 25)):
        s = Script().start(fifo_ctrl=STREAM | fth)
        i = s.at(u * P + P // 2).r(FIFO_SRC)
        assert run(s)[i] == [want], (fth, u)


def m_fifo_ovrn(run):
    s = Script().start(fifo_ctrl=STREAM | 31)
    a = s.at(31 * P + P // 2).r(FIFO_SRC)
    b = s.at(32 * P + P // 2).r(FIFO_SRC)
    c = s.at(45 * P + P // 2).r(FIFO_SRC)
    s.r(OUT_X_L, 6)
    d = s.r(FIFO_SRC)
    r = run(s)
    assert [r[a], r[b], r[c], r[d]] == [[31], [WTM | OVRN | 31], [WTM | OVRN | 31], [31]]


def m_fifo_empty(run):
    s = Script().start(fifo_ctrl=STREAM | 31)
    a = s.at(P // 2).r(FIFO_SRC)
    b = s.at(P + P // 2).r(FIFO_SRC)
    s.r(OUT_X_L, 6)
    c = s.r(FIFO_SRC)
    r = run(s)
    assert [r[a], r[b], r[c]] == [[EMPTY], [1], [EMPTY]]


def m_fifo_fss(run):
    s = Script().start(fifo_ctrl=STREAM | 31)
    idx = [s.at(u * P + P // 2).r(FIFO_SRC) for u in range(33)]
    r = run(s)
    assert [r[i][0] & 0x1F for i in idx] == list(range(32)) + [31]


def m_fifo_10bit(run):
    for ctrl4, ctrl1 in ((0x88, 0x77), (0x80, 0x77), (0x80, 0x7F)):    # HR, normal, low-power
        s = Script().start(ctrl4=ctrl4, ctrl1=ctrl1)
        d = s.at(3 * P + P // 2).r(OUT_X_L, 18)
        b = run(s)[d]
        ys = [xyz16(b, i)[1] for i in (0, 6, 12)]
        bits = 8 if ctrl1 & 0x08 else 10                                 # 10, or the 8 there are
        so = 16 if bits == 8 else 4
        assert ys == [round(500 / so) << (16 - bits)] * 3, (ctrl4, ctrl1)


def m_fifo_rollover(run):
    s = Script().start()
    d = s.at(5 * P + P // 2).r(OUT_X_L, 6 * 3)
    a = s.r(FIFO_SRC)
    r = run(s)
    assert fifo_xs([r[d]]) == [1, 2, 3] and r[a] == [src(2)]


def m_fifo_read_past(run):
    s = Script().start(ctrl4=0x88)
    d = s.at(2 * P + P // 2).r(OUT_X_L, 6 * 4)
    a = s.r(FIFO_SRC)
    r = run(s)
    b = r[d]
    assert fifo_xs([b[:12]]) == [1, 2] and r[a] == [src(0)]
    assert xyz16(b, 12) == xyz16(b, 18) == [8 << 4, 500 << 4, -900 << 4]  # conversion 2, whole


def m_temp_cfg(run):
    for cfg, want in ((0xC0, 20 - 25), (0x80, 0), (0x40, 0), (0x00, 0)):
        s = Script().start()
        s.w(TEMP_CFG, cfg)
        i = s.at(P // 2 + P).r(OUT_ADC3_L, 2)
        assert run(s)[i] == [0, want & 0xFF], cfg


def m_out_adc3(run):
    s = Script().start()
    s.w(TEMP_CFG, 0xC0)
    idx = [s.at(t * 400 * P + P // 2).r(OUT_ADC3_L, 2) for t in (1, 5, 7, 9)]
    r = run(s)
    assert [s16(*r[i]) >> 8 for i in idx] == [21 - 25, 0, 27 - 25, 29 - 25]


def m_ctrl3_fifo_int(run):
    # INT1 = I1_OVERRUN . OVRN_FIFO: stream-to-FIFO keeps the first 32 (I1_WTM: m_fm_stream_to_fifo)
    assert _stream_to_fifo(run, STREAM_TO_FIFO | 31, 0x02) == list(range(1, 33))
    assert _stream_to_fifo(run, STREAM_TO_FIFO | 31, 0x00) == list(range(9, 41))


# SPI (DocID17530 6.2): the first byte's bit 7 RW (1 = read), bit 6 MS (1 = the address
# increments), bits 5:0 the address; SDO is not driven during it (the models: 0)
RW, MS = 0x80, 0x40


def m_spi_rw(run):
    s = Script()
    a = s.s(RW | WHO_AM_I, 0xFF)
    s.s(CTRL1, 0x57)                      # RW = 0: a write, nothing read out
    b = s.r(CTRL1)
    c = s.s(RW | CTRL1, 0)
    r = run(s)
    assert r[a] == [0, 0x33] and r[b] == [0x57] and r[c] == [0, 0x57]


def m_spi_ms(run):
    s = Script().start()
    a = s.at(20 * P + P // 2).s(RW | MS | OUT_X_L, *[0] * 12)       # two sets, rolling over
    b = s.s(RW | OUT_X_L, 0, 0, 0)                                 # MS = 0: OUT_X_L three times
    c = s.s(RW | MS | CTRL4, 0, 0)                                 # CTRL_REG4, CTRL_REG5
    r = run(s)
    assert fifo_xs([r[a][1:]]) == [1, 2]
    assert r[b][1:] == [(12 << 4) & 0xC0] * 3     # set 3's x (12 mg), its low byte, not popped
    assert r[c] == [0, 0x88, 0x40]


def m_spi_cs(run):
    s = Script()
    a = s.s(RW | WHO_AM_I, RW | WHO_AM_I, RW | WHO_AM_I)   # one command: the rest are data
    b = s.s(RW | MS | 0x0E, 0, 0)                          # CS high ended it: a new command
    r = run(s)
    assert r[a] == [0, 0x33, 0x33] and r[b] == [0, 0, 0x33]


# ---------------------------------------------------------------- checks on the driver
class Rec:
    """The chip behind a bus, every register operation logged."""

    def __init__(self, chip):
        self.chip, self.log = chip, []

    def read(self, reg, buf, start, end):
        self.log.append(("r", reg & 0x7F, end - start))
        return self.chip.read(reg, buf, start, end)

    def write(self, reg, data, start, end):
        self.log.append(("w", reg & 0x7F, bytes(data[start:end])))
        return self.chip.write(reg, data, start, end)

    def ours(self):
        """The writes since the driver's own configure began (its BOOT: adafruit_lis3dh's probe
        on CircuitPython writes first)."""
        w = [(reg, v[0]) for op, reg, v in self.log if op == "w"]
        boot = max(i for i, (reg, v) in enumerate(w) if reg == CTRL5 and v & 0x80)
        return w[boot:]


_SETTINGS = {}


class Drv:
    def __init__(self, stim, flavour):
        self.stim, self.flavour = stim, flavour

    def __call__(self, **settings):
        clock = Clock()
        chip = SimLIS3DH(Stimulus(str(self.stim)), clock)
        rec = Rec(chip)
        if self.flavour == "micropython":
            d = lis3dh.LIS3DH(I2C({0x18: rec}), **settings)
        else:
            d = lis3dh_cp.make(BusioI2C({0x18: rec}), **settings)
        return d, chip, clock, rec

    def every_setting(self):
        """What the driver writes over every configuration it offers (made once a flavour)."""
        if self.flavour not in _SETTINGS:
            _SETTINGS[self.flavour] = list(self._every_setting())
        return _SETTINGS[self.flavour]

    def _every_setting(self):
        fths = (0, 24, 31)
        for rate in lis3dh.ODR_CODES if self.flavour == "micropython" else (100, 400):
            for rng in lis3dh.RANGES_G:
                for hr in (True, False):
                    for fifo in (False, True):
                        for fth in fths if fifo else (0,):
                            d, chip, clock, rec = self(rate_hz=rate, range_g=rng, high_res=hr,
                                                       fifo=fifo, fth=fth)
                            yield dict(rate_hz=rate, range_g=rng, high_res=hr, fifo=fifo,
                                       fth=fth), rec.ours()


def last(writes, reg):
    return [v for r, v in writes if r == reg][-1] if any(r == reg for r, v in writes) else None


def d_who_am_i(drv):
    d, chip, clock, rec = drv()
    chip.regs[WHO_AM_I] = 0x32
    with pytest.raises(lis3dh.LIS3DHError):
        d.check()


def d_ctrl1_odr(drv):
    codes = {hz: code for code, hz in ODR_HZ.items()}
    for st, w in drv.every_setting():
        assert last(w, CTRL1) >> 4 == codes[st["rate_hz"]]


def d_ctrl1_lpen(drv):
    assert all(not last(w, CTRL1) & 0x08 for st, w in drv.every_setting())


def d_ctrl4_hr(drv):
    for st, w in drv.every_setting():
        assert bool(last(w, CTRL4) & 0x08) == st["high_res"]


def d_ctrl4_fs(drv):
    for st, w in drv.every_setting():
        assert (last(w, CTRL4) >> 4) & 3 == (2, 4, 8, 16).index(st["range_g"])
    for rng, so in ((2, 1), (16, 12)):
        d, chip, clock, rec = drv(rate_hz=400, range_g=rng)
        clock.sleep_us(10 * P)
        d.read_sample()   # Q10's floor with a dither in [0, 1) LSB (fixed.DITHER_STEP), and
        # 16777 / 16384 for 1.024 (0.03 LSB low at most at 2 g)
        for q, mg in ((d.y, round(500 / so) * so), (d.z, round(-900 / so) * so)):
            assert -1.03 < q - mg * 1.024 < 1, (q, mg)


def d_ctrl4_bdu(drv):
    assert all(last(w, CTRL4) & 0x80 for st, w in drv.every_setting())


def d_outputs(drv):
    for hr, so in ((True, 1), (False, 4)):
        d, chip, clock, rec = drv(rate_hz=400, high_res=hr)
        clock.sleep_us(100 * P + P // 2)
        d.read_sample()   # Q10's floor with a dither in [0, 1) LSB (fixed.DITHER_STEP), and
        # 16777 / 16384 for 1.024 (0.03 LSB low at most at 2 g)
        assert all(-1.03 < q - v * 1.024 < 1 for q, v in zip((d.x, d.y, d.z), (400, 500, -900)))


def d_status_zyxda(drv):
    d, chip, clock, rec = drv(rate_hz=400)
    clock.sleep_us(P // 2)
    assert not d.data_ready()
    clock.sleep_us(P)
    assert d.data_ready() and not d.overrun


def d_status_zyxor(drv):
    d, chip, clock, rec = drv(rate_hz=400)
    clock.sleep_us(3 * P + P // 2)
    assert d.data_ready() and d.overrun
    d.read_sample()
    clock.sleep_us(P)
    assert d.data_ready() and not d.overrun


def d_ctrl5_boot(drv):
    assert all(w[0] == (CTRL5, 0x80) for st, w in drv.every_setting())


def d_ctrl5_fifo_en(drv):
    for st, w in drv.every_setting():
        assert any(r == CTRL5 and v & 0x40 for r, v in w) == st["fifo"]


def d_fm_bypass(drv):
    for st, w in drv.every_setting():      # registers: the FIFO left in bypass after BOOT
        if not st["fifo"]:
            assert last(w, FIFO_CTRL) in (None, 0) and not last(w, CTRL5) & 0x40


def d_fm_fifo(drv):
    assert all(last(w, FIFO_CTRL) is None or last(w, FIFO_CTRL) & 0xC0 != FIFO
               for st, w in drv.every_setting())


def d_fm_stream(drv):
    for st, w in drv.every_setting():
        if st["fifo"]:
            assert last(w, FIFO_CTRL) & 0xC0 == STREAM


def d_fm_stream_to_fifo(drv):
    assert all(last(w, FIFO_CTRL) is None or last(w, FIFO_CTRL) & 0xC0 != STREAM_TO_FIFO
               for st, w in drv.every_setting())


def d_fifo_tr(drv):
    assert all(last(w, FIFO_CTRL) is None or not last(w, FIFO_CTRL) & 0x20
               for st, w in drv.every_setting())


def d_fifo_fth(drv):
    for st, w in drv.every_setting():
        if st["fifo"]:
            assert last(w, FIFO_CTRL) & 0x1F == st["fth"]
    with pytest.raises(ValueError):
        drv(fifo=True, fth=32)


def d_fifo_wtm(drv):
    for fth, u, wtm in ((0, 3, True), (24, 3, False), (24, 24, False), (24, 25, True)):
        d, chip, clock, rec = drv(rate_hz=400, fifo=True, fth=fth)
        clock.sleep_us(u * P + P // 2)
        assert (d.fifo_level(), d.wtm) == (u, wtm)


def d_fifo_ovrn(drv):
    d, chip, clock, rec = drv(rate_hz=400, fifo=True, fth=24)
    clock.sleep_us(40 * P + P // 2)
    n = d.fifo_level()
    assert (n, d.overrun) == (32, True) and chip.dropped == 8
    out = [0] * 96
    d.read_fifo(out, 0, n)
    clock.sleep_us(P)
    assert (d.fifo_level(), d.overrun) == (1, False)


def d_fifo_empty(drv):
    d, chip, clock, rec = drv(rate_hz=400, fifo=True)
    clock.sleep_us(P // 2)
    assert (d.fifo_level(), d.overrun, d.wtm) == (0, False, False)


def d_fifo_fss(drv):
    d, chip, clock, rec = drv(rate_hz=400, fifo=True, fth=31)
    got = []
    for u in range(33):
        clock.set_us(u * P + P // 2)
        got.append(d.fifo_level())
    assert got == list(range(33))


def _drain(drv, **settings):
    d, chip, clock, rec = drv(rate_hz=400, fifo=True, **settings)
    clock.sleep_us(20 * P + P // 2)
    n = d.fifo_level()
    out = [0] * 96
    d.read_fifo(out, 0, n)
    return d, n, out, rec


def d_fifo_10bit(drv):
    d, n, out, rec = _drain(drv)
    # 4 mg codes, each read as the middle of its four 1 mg digits (HR): 4 r + 1.5 mg, to Q10's
    # floor with a dither in [0, 1) LSB (< 0.98 mg either way; fixed.DITHER_STEP) and 16777 /
    # 16384 for 1.024 (0.03 LSB low at most)
    xs = np.array(out[0:3 * n:3]) / 1.024 - 1.5
    assert n == 20 and np.abs(xs - [4 * (k % 256) for k in range(1, 21)]).max() <= 1.01
    assert abs(out[1] / 1.024 - 501.5) <= 1.01 and abs(out[2] / 1.024 - -898.5) <= 1.01
    d, n, out, rec = _drain(drv, high_res=False)     # normal mode: the FIFO's 10 bits are exact
    assert abs(out[1] / 1.024 - 500) <= 1.01 and abs(out[2] / 1.024 - -900) <= 1.01


def d_fifo_rollover(drv):
    d, n, out, rec = _drain(drv)
    reads = [(reg, k) for op, reg, k in rec.log if op == "r" and reg == OUT_X_L]
    assert reads == [(OUT_X_L, 6 * n)]             # the whole drain, one transaction


def d_fifo_read_past(drv):
    for fth in (0, 24):
        d, n, out, rec = _drain(drv, fth=fth)
        ops = [(reg, k) for op, reg, k in rec.log if op == "r" and reg in (FIFO_SRC, OUT_X_L)]
        assert ops[-2:] == [(FIFO_SRC, 1), (OUT_X_L, 6 * 20)]   # what FSS said, no more


def d_temp_cfg(drv):
    for st, w in drv.every_setting():
        regs = [r for r, v in w]
        assert last(w, TEMP_CFG) == 0xC0 and regs.index(CTRL4) < regs.index(TEMP_CFG)  # BDU first


def d_out_adc3(drv):
    d, chip, clock, rec = drv(rate_hz=400)
    for t, want in ((1, -4), (7, 2)):
        clock.set_us(t * 400 * P + P // 2)
        assert d.temperature() == want


def d_ctrl3_fifo_int(drv):
    assert all(CTRL3 not in [r for r, v in w] for st, w in drv.every_setting())


class Frames:
    """The chip's SPI front end, every transaction's SDI bytes logged, and any byte clocked
    with CS high caught."""

    def __init__(self, chip):
        self.chip, self.frames, self.low = chip, [], False

    def spi_select(self, low):
        assert low != self.low               # CS toggles: no transaction inside another
        self.low = low
        if low:
            self.frames.append([])
        self.chip.spi_select(low)

    def spi_byte(self, v):
        assert self.low, "a byte clocked with CS high"
        self.frames[-1].append(v)
        return self.chip.spi_byte(v)


def spi_driver(drv, **settings):
    """The driver over SPI (lis3dh_spi.SPIRegisters on machine.SPI, or lis3dh_cp's on busio), its
    transactions logged; after a drain of 20 sets, a register sample and a temperature."""
    from vbus import BusioSPI, DigitalInOut, Pin, SPI
    clock = Clock()
    fr = Frames(SimLIS3DH(Stimulus(str(drv.stim)), clock))
    if drv.flavour == "micropython":
        regs = lis3dh_spi.SPIRegisters(SPI(fr), Pin(fr))
    else:
        regs = lis3dh_cp.BusioSPIRegisters(BusioSPI(fr), DigitalInOut(fr))
    d = lis3dh.LIS3DH(regs, rate_hz=400, fifo=True, fth=24, **settings)
    clock.set_us(20 * P + P // 2)
    n = d.fifo_level()
    d.read_fifo([0] * 96, 0, n)
    d.read_sample()
    d.temperature()
    assert n == 20 and not fr.low
    return fr.frames


def d_spi_rw(drv):
    frames = spi_driver(drv)
    writes = [f for f in frames if not f[0] & RW]
    assert writes and all(len(f) == 2 for f in writes)            # a register a write
    assert [f[0] & 0x3F for f in writes][:2] == [CTRL5, CTRL1] and writes[0][1] == 0x80   # BOOT
    reads = [f[0] & 0x3F for f in frames if f[0] & RW]
    assert reads[0] == WHO_AM_I and reads[-4:] == [FIFO_SRC, OUT_X_L, OUT_X_L, OUT_ADC3_L]


def d_spi_ms(drv):
    frames = spi_driver(drv)
    firsts = [(f[0], len(f) - 1) for f in frames if f[0] & RW]
    assert firsts[0] == (RW | WHO_AM_I, 1) and firsts[-4:] == [
        (RW | FIFO_SRC, 1), (RW | MS | OUT_X_L, 6 * 20), (RW | MS | OUT_X_L, 6),
        (RW | MS | OUT_ADC3_L, 2)]                              # MS only where bytes follow


def d_spi_cs(drv):
    frames = spi_driver(drv)                                    # Frames checks CS around each
    assert len(frames) >= 8 and all(len(f) >= 2 for f in frames)


# ---------------------------------------------------------------- the rows
def test_every_row_has_its_checks_and_every_check_a_row():
    checks = {n[2:] for n in globals() if n.startswith(("m_", "d_"))}
    rows = [r["check"] for r in ROWS]
    assert len(rows) == len(set(rows)) >= 27
    assert set(rows) == checks
    for r in rows:
        assert f"m_{r}" in globals() and f"d_{r}" in globals(), r


def _camel(name):
    name = name.lstrip("_")
    return name if name.isupper() else re.sub(r"_([a-z0-9])", lambda m: m.group(1).upper(), name)


@pytest.mark.parametrize("row", ROWS, ids=[r["check"] for r in ROWS])
def test_the_rows_names_are_in_the_files(row):
    texts = {k: p.read_text() for k, p in FILES.items()}
    m = row["models"].strip("`")
    assert re.search(rf"\b{re.escape(m)}\b", texts["python"]), (m, "vlis3dh.py")
    assert re.search(rf"\b{re.escape(_camel(m))}\b", texts["node"]), (_camel(m), "lis3dh.mjs")
    d = row["driver"].strip("`")
    assert re.search(rf"\b{re.escape(d)}\b", texts["driver"]), (d, "lis3dh.py")


@pytest.mark.parametrize("row", ROWS, ids=[r["check"] for r in ROWS])
def test_python_model(row, stim):
    globals()["m_" + row["check"]](lambda s: python_model(stim, s.ops)["reads"])


@pytest.fixture(scope="module")
def node():
    if not shutil.which("node"):
        pytest.skip("Node is not on PATH")


@pytest.mark.parametrize("row", ROWS, ids=[r["check"] for r in ROWS])
def test_node_model(row, stim, node, tmp_path):
    globals()["m_" + row["check"]](lambda s: js_model(stim, s.ops, tmp_path)["reads"])


@pytest.mark.parametrize("flavour", ["micropython", "circuitpython"])
@pytest.mark.parametrize("row", ROWS, ids=[r["check"] for r in ROWS])
def test_driver(row, flavour, stim):
    globals()["d_" + row["check"]](Drv(stim, flavour))


# ---------------------------------------------------------------- the old driver, caught
def old_fifo_level(d):
    """The driver's fifo_level() before issue 46, kept to show the conformance catches it: it
    took bit 7 (WTM) for 'full'."""
    s = d._read_u8(0x2F)
    d.overrun = bool(s & 0x40)
    return 32 if s & 0x80 else s & 0x1F


@pytest.mark.parametrize("fth", [0, 2])
def test_a_chip_setting_wtm_where_the_datasheet_does_fails_the_old_driver(stim, fth):
    """FTH = 0 (the old driver's) and 3 unread: WTM is set (3 > 0), and the old reading makes 32
    of 3, 29 samples never converted; the new one reads FSS."""
    d, chip, clock, rec = Drv(stim, "micropython")(rate_hz=400, fifo=True, fth=fth)
    clock.sleep_us(3 * P + P // 2)
    assert old_fifo_level(d) == 32 != 3
    assert d.fifo_level() == 3 == chip.fifo_level
