"""The LIS3DH on the emulated Pico's I2C0 (bridge/scripts/lis3dh.mjs): one chip behaviour, held to
the virtual board's Python model (simulate/chip/vlis3dh.py) register operation by register
operation; then the app on boards/pico.py, unchanged, reading it through the real machine.I2C."""
import shutil

import numpy as np
import pytest

from accelcal.simulate.stimulus import calibration_dance, write_stimulus
from conftest import ROOT, emulated_chip

from lis3dh_models import js_model, python_model

# register addresses (datasheet DocID17530), written out here rather than taken from either model
CTRL1, CTRL4, CTRL5, TEMP_CFG, FIFO_CTRL = 0x20, 0x23, 0x24, 0x1F, 0x2E
STATUS, OUT_X_L, FIFO_SRC, OUT_ADC3, WHO_AM_I = 0x27, 0x28, 0x2F, 0x0C, 0x0F
AUTO = 0x80


def random_ops(rng, n_ops=2500):
    """Register traffic a driver could make, at increasing times: configurations (every ODR
    including 1344 Hz, low-power, normal and high resolution, each range, each FIFO mode with
    any watermark and trigger, INT1's FIFO sources, BOOT), reads of every kind (outputs stopped
    between an axis's two bytes too: BDU), and waits from microseconds to past a full FIFO."""
    ops, t = [], 0
    fifo = [0, 0]  # CTRL_REG5, FIFO_CTRL_REG as written: multi-sample reads only with the FIFO on
    for _ in range(n_ops):
        t += int(rng.choice([0, 7, 333, 2500, 10000, 40000, 400000]))
        k = rng.integers(14)
        if k == 0:
            ops.append([t, "w", CTRL1, [int(rng.integers(0, 11)) << 4 | int(rng.choice([0x07, 0x0F]))]])
        elif k == 1:
            ops.append([t, "w", CTRL4, [int(rng.choice([0, 0x80])) | int(rng.integers(4)) << 4
                                        | int(rng.choice([0, 0x08]))]])
        elif k == 2:
            ops.append([t, "w", CTRL5, [int(rng.choice([0x00, 0x40, 0x40, 0x80]))]])
        elif k == 3:
            ops.append([t, "w", FIFO_CTRL, [int(rng.integers(4)) << 6 | int(rng.choice([0, 0x20]))
                                            | int(rng.choice([0, int(rng.integers(32))]))]])
        elif k == 4:
            ops.append([t, "w", TEMP_CFG | AUTO, [int(rng.choice([0, 0xC0])), 0]])
        elif k == 5:
            ops.append([t, "r", FIFO_SRC, 1])
        elif k == 6 and fifo[0] & 0x40 and fifo[1] >> 6:
            ops.append([t, "r", OUT_X_L | AUTO, 6 * int(rng.integers(1, 33))])
        elif k == 7:
            ops.append([t, "r", OUT_X_L | AUTO, 6])
        elif k == 8:
            ops.append([t, "r", OUT_ADC3 | AUTO, 2])
        elif k == 9:
            ops.append([t, "r", STATUS, 1])
        elif k == 10:
            reg = int(rng.choice(range(0x3D)))
            ops.append([t, "r", reg | AUTO, int(rng.integers(1, 4))])
        elif k == 12:
            ops.append([t, "w", 0x22, [int(rng.choice([0, 0x02, 0x04, 0x06]))]])  # CTRL_REG3
        elif k == 13:
            ops.append([t, "r", OUT_X_L + int(rng.integers(6)), 1])
        else:
            ops.append([t, "r", WHO_AM_I, 1])
        if ops[-1][1] == "w" and ops[-1][2] in (CTRL5, FIFO_CTRL):
            v = ops[-1][3][0]
            fifo[ops[-1][2] == FIFO_CTRL] = v
            if ops[-1][2] == CTRL5 and v & 0x80:
                fifo[:] = [0, 0]      # BOOT
    return ops


@pytest.fixture(scope="module")
def node():
    if not shutil.which("node"):
        pytest.skip("Node is not on PATH")
    return "node"


def test_js_model_reads_what_the_python_model_reads(tmp_path, node, rng):
    n = 40000
    t = np.arange(n) / 400
    xyz = np.column_stack([1.9 * np.sin(t), 2.5 * np.cos(3 * t), 0.8 + 0.01 * t])
    xyz += rng.normal(scale=0.003, size=(n, 3))
    stim = tmp_path / "stim.bin"
    write_stimulus(stim, 400, xyz, 20 + 0.001 * np.arange(n))
    ops = random_ops(rng)
    js = js_model(stim, ops, tmp_path)
    py = python_model(stim, ops)
    assert len(js["reads"]) == len(py["reads"]) > 1000
    first = next((i for i, (a, b) in enumerate(zip(js["reads"], py["reads"])) if a != b), None)
    assert first is None, f"read {first} differs: js {js['reads'][first]} python {py['reads'][first]}"
    assert js["dropped"] == py["dropped"] > 0          # stream overwrites happened, alike
    # the traffic reached every corner that matters: full FIFOs, watermarks passed and not
    src = [r[0] for r, o in zip(py["reads"], [o for o in ops if o[1] == "r"]) if o[2] == FIFO_SRC]
    assert any(v & 0x40 for v in src) and any(v & 0x80 and not v & 0x40 for v in src)
    assert any(0 < v & 0x1F and not v & 0x80 for v in src)


def as_spi(ops, rng):
    """The same traffic with about half the operations as SPI transactions (DocID17530 6.2,
    written here from the datasheet: RW bit 7, MS bit 6 for the I2C sub-address's bit 7, AD5:0;
    a read clocks random bytes out on SDI, which the chip must ignore)."""
    out = []
    for t, op, reg, arg in ops:
        if rng.random() < 0.5:
            out.append([t, op, reg, arg])
            continue
        first = (0x40 if reg & 0x80 else 0) | (reg & 0x3F)
        if op == "r":
            out.append([t, "s", 0, [0x80 | first] + [int(b) for b in rng.integers(0, 256, arg)]])
        else:
            out.append([t, "s", 0, [first] + list(arg)])
    return out


def test_spi_reads_what_i2c_reads_in_both_models(tmp_path, node, rng):
    """Half the random traffic over the SPI front end: both models give every read byte for
    byte as the same traffic all over I2C does (the SPI front end is the same register file)."""
    n = 40000
    t = np.arange(n) / 400
    xyz = np.column_stack([1.9 * np.sin(t), 2.5 * np.cos(3 * t), 0.8 + 0.01 * t])
    stim = tmp_path / "stim.bin"
    write_stimulus(stim, 400, xyz, 20 + 0.001 * np.arange(n))
    ops = random_ops(rng, 1500)
    spi = as_spi(ops, rng)
    i2c = python_model(stim, ops)["reads"]
    for got in (python_model(stim, spi), js_model(stim, spi, tmp_path)):
        reads = [r[1:] if o[1] == "s" else r
                 for o, r in zip([o for o in spi if o[1] != "w"], got["reads"])
                 if not (o[1] == "s" and not o[3][0] & 0x80)]    # an SPI write reads nothing
        assert reads == i2c
        assert all(r[0] == 0 for o, r in zip([o for o in spi if o[1] != "w"], got["reads"])
                   if o[1] == "s")          # SDO is not driven during the first byte
    assert sum(o[1] == "s" for o in spi) > 600


# ---------------------------------------------------------------- the app on the emulated Pico
RATE = 100
TRUTH = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])


@pytest.fixture(scope="module")
def pico():
    emulated_chip()
    from accelcal.board import emulated
    return emulated


def fifo_q10(xyz_g, index=None):
    """What the app gets from the FIFO for these accelerations: the chip rounds to its 12-bit
    digit (1 mg at 2 g, half away from zero), clips, keeps the top 10 bits; the driver reads a
    code as the middle of its four digits (4 r + 1.5 mg) and scales, rounding onto Q10 with the
    dither of each sample's index among those the driver read (index; None: 0, 1, 2, ...: the
    app read them all), acal.core.fixed.DITHER_STEP."""
    from accelcal.fixedpoint import dither
    from test_lis3dh import fifo_to_q10
    ug = np.rint(xyz_g * 1e6).astype(np.int64)
    d12 = np.sign(ug) * ((np.abs(ug) + 500) // 1000)
    d10 = np.clip(d12, -2048, 2047) >> 2
    i = np.arange(len(d10)) if index is None else np.asarray(index)
    dd = np.broadcast_to(dither(0, int(i.max()) + 1 if len(i) else 0)[i][:, None], d10.shape)
    q = np.vectorize(lambda d, e: fifo_to_q10(int(d) << 6, 3, 1, int(e)),
                     otypes=[np.int64])(d10, dd)
    # the middle, to Q10's floor with a dither in [0, 1) LSB (under 0.98 mg either way) and
    # 16777 / 16384 for 1.024 (at most 0.03 LSB low at 2 g)
    assert np.all(np.abs(q / 1.024 - (4 * d10 + 1.5)) <= 1.01)
    return q


# the paper's profile: the wear profile judges no segment still before 80 s of quiet ones
APP = """import acal.logger.app
app = acal.logger.app.main(seconds={seconds}, verbose=False, rate_hz=100, fifo=True, capture_bytes=400000,
                    profile=0)
print('ACAL_DONE', app.samples, app.lost, app.fifo_overruns, app.bus_errors)
"""


def test_the_app_on_pico_reads_the_stimulus_and_replays(tmp_path, pico):
    """boards/pico.py and the app, unchanged, on the emulated Pico for 10 emulated seconds at
    100 Hz with the FIFO and 2 % of bus transactions NACKed: every fault is one bus error the app
    survives, every sample the app captured is the stimulus's at its time, and the capture
    replays on the host into the board's very log."""
    from accelcal.bridge import boardlog
    xyz = calibration_dance(tmp_path / "stim.bin", RATE, TRUTH, seed=5, rounds=1, rest_s=9)
    r = pico.run([APP.format(seconds=10)], stimulus=tmp_path / "stim.bin", bus_faults=20,
                 puts={"acal_board.py": (ROOT / "boards" / "pico.py").read_bytes()},
                 gets=["log.bin", "capture.bin"])
    done = r.out.split("ACAL_DONE")[1].split()
    samples, lost, overruns, bus_errors = map(int, done[:4])
    chip = r.report["lis3dh"]
    assert chip["faults"] > 0 and bus_errors == chip["faults"]
    assert overruns == 0 and chip["dropped"] == 0
    assert lost == 0 and 10 * RATE <= samples <= chip["converted"]   # it converts on after the app ends
    for f in ("log.bin", "capture.bin"):
        (tmp_path / f).write_bytes(r.files[f])
    # the samples, in the order the FIFO gave them, are the chip's conversions 1, 2, ... of the
    # last ODR start; conversion n reads the stimulus at that start + n periods
    got = np.concatenate([b[3] for b in boardlog.read_capture(tmp_path).blocks if b[0] == "samples"])
    assert len(got) == samples
    s, us = chip["starts"][-1]
    k = (s * 1_000_000 + us + np.arange(1, samples + 1) * 10_000) * RATE // 1_000_000
    assert np.array_equal(got, fifo_q10(xyz[k]))
    rep = boardlog.replay(tmp_path)
    assert rep["identical"] and rep["samples_replayed"] == samples + lost
    assert rep["rest"]["board"] >= 1, rep      # the replay compared the rest means it logged


LATE = """import time, acal.logger.app, acal_board
app = acal.logger.app.App(acal_board, rate_hz=100, fifo=True, profile=0)
for _ in range(4):
    app.step()
time.sleep_ms(700)   # late: 70 samples come due in a 32-level FIFO (a long flash erase, say)
for _ in range(8):   # the one a conversion overwrites during the late drain shows a drain or more later
    app.step()
print('ACAL_DONE', app.samples, app.lost, app.fifo_overruns)
"""


def test_a_late_app_overruns_the_fifo_and_counts_what_it_lost(tmp_path, pico):
    calibration_dance(tmp_path / "stim.bin", RATE, TRUTH, seed=6, rounds=1)
    r = pico.run([LATE], stimulus=tmp_path / "stim.bin",
                 puts={"acal_board.py": (ROOT / "boards" / "pico.py").read_bytes()})
    samples, lost, overruns = map(int, r.out.split("ACAL_DONE")[1].split()[:3])
    chip = r.report["lis3dh"]
    assert overruns == 1
    assert chip["dropped"] >= 70 - 32
    # The app's time-based count is taken before the FIFO's level: a sample the chip converts
    # during the read (25 samples: 3.4 ms of bus at 400 kHz) waits for the next read, not
    # counted lost (it was, once a run, when the clock was read after the FIFO).
    assert lost == chip["dropped"], (lost, chip)



APP_SPI = APP.replace("fifo=True,", "fifo=True, bus='spi',")


def test_the_app_on_pico_reads_the_stimulus_over_spi(tmp_path, pico):
    """The chip wired to SPI0 (pico.mjs --spi, boards/pico.py's pins): machine.SPI (DMA for the
    FIFO's drains) through lis3dh_spi.SPIRegisters reads every sample the stimulus gave at its time,
    the same samples as I2C reads, nothing lost, and the capture replays into the board's log."""
    from accelcal.bridge import boardlog
    xyz = calibration_dance(tmp_path / "stim.bin", RATE, TRUTH, seed=5, rounds=1, rest_s=9)
    r = pico.run([APP_SPI.format(seconds=5)], stimulus=tmp_path / "stim.bin", spi=pico.SPI_PICO,
                 puts={"acal_board.py": (ROOT / "boards" / "pico.py").read_bytes()},
                 gets=["log.bin", "capture.bin"])
    samples, lost, overruns, bus_errors = map(int, r.out.split("ACAL_DONE")[1].split()[:4])
    chip = r.report["lis3dh"]
    assert chip["spi"] == {"bus": 0, "sck": 18, "mosi": 19, "miso": 16, "cs": 17}
    assert (lost, overruns, bus_errors, chip["dropped"]) == (0, 0, 0, 0)
    assert 5 * RATE <= samples <= chip["converted"] and chip["transactions"] > 0
    for f in ("log.bin", "capture.bin"):
        (tmp_path / f).write_bytes(r.files[f])
    got = np.concatenate([b[3] for b in boardlog.read_capture(tmp_path).blocks if b[0] == "samples"])
    s, us = chip["starts"][-1]
    k = (s * 1_000_000 + us + np.arange(1, samples + 1) * 10_000) * RATE // 1_000_000
    assert len(got) == samples and np.array_equal(got, fifo_q10(xyz[k]))
    rep = boardlog.replay(tmp_path)
    assert rep["identical"] and rep["samples_replayed"] == samples


MODES = """from machine import SPI, Pin
cs = Pin(17, Pin.OUT, value=1)
b, cmd = bytearray(1), bytearray([0x8F])     # WHO_AM_I, read
got = []
for pol, pha in ((0, 0), (0, 1), (1, 0), (1, 1)):
    spi = SPI(0, baudrate=10_000_000, polarity=pol, phase=pha, sck=Pin(18), mosi=Pin(19), miso=Pin(16))
    cs(0); spi.write(cmd); spi.readinto(b); cs(1)
    got.append(b[0])
spi.write(cmd); spi.readinto(b)              # CS high: not selected
got.append(b[0])
print('MODES', *got)
"""


def test_the_emulated_chip_answers_spi_in_mode_0_or_3_with_cs_low(tmp_path, pico):
    """The Node chip's SPI front end on the emulated SPI0: WHO_AM_I answers 0x33 in modes 0 and
    3 (CPOL = CPHA: SDI latched on SPC's rising edge, DocID17530 6.2), nothing in modes 1 and 2,
    nothing with CS high."""
    write_stimulus(tmp_path / "stim.bin", 400, np.zeros((400, 3)), np.full(400, 20.0))
    r = pico.run([MODES], stimulus=tmp_path / "stim.bin", spi=pico.SPI_PICO)
    assert r.out.split("MODES")[1].split() == ["51", "0", "0", "51", "0"]
    assert r.report["lis3dh"]["transactions"] == 4
