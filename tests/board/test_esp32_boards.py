"""boards/esp32.py on each chip of the family, its pins checked against MicroPython's esp32 port
(v1.28.0: ports/esp32/machine_i2c.h's I2C0 defaults, SDA 8 / SCL 9 on the S3 and C3) and the
chips' datasheets (pins that exist, are outputs, and are not the flash's, the USB's or the REPL
UART's); the supply read only where a pin is wired, in mV from the port's ADC.read_uv()."""
import importlib.util
import sys
import types

import pytest

from accelcal.locations import BOARDS_DIR, CHIP_DIR

sys.path.insert(0, str(CHIP_DIR))
from vbus import Pin as VPin, SPI as VSPI  # noqa: E402

# GPIOs an I2C bus may use on each chip: those it has, less flash (ESP32 6-11, C3 12-17),
# inputs only (ESP32 34-39), flash and PSRAM (S3 26-37), USB (S3 19-20, C3 18-19) and UART0, the REPL (ESP32 1/3, S3 43/44,
# C3 20/21)
USABLE = {"ESP32": set(range(0, 34)) - set(range(6, 12)) - {1, 3},
          "ESP32S3": set(range(0, 22)) - {19, 20} | set(range(38, 49)) - {43, 44},
          "ESP32C3": set(range(0, 22)) - set(range(12, 18)) - {18, 19, 20, 21}}


def load(monkeypatch, machine_name, supply_pin=None, uv=0, chip=None):
    """The board file as the board imports it: sys.implementation._machine as the port says
    it, machine's I2C, ADC and SPI recording what they are asked; with chip (a simulated
    LIS3DH), SPI and an output Pin are the virtual board's fakes in front of it."""
    calls = []
    fake = types.ModuleType("machine")

    def pin(n, mode=None, value=None):
        if mode is None:
            return ("pin", n)
        calls.append(("Pin", n, mode, value))
        return VPin(chip, value)
    pin.OUT = 1
    fake.Pin = pin

    def spi(i, **kw):
        calls.append(("SPI", i, kw))
        return VSPI(chip)
    fake.SPI = spi

    class ADC:
        ATTN_11DB = 3

        def __init__(self, pin, atten=None):
            calls.append(("ADC", pin, atten))

        def read_uv(self):
            return uv
    fake.ADC = ADC
    fake.I2C = lambda i, **kw: calls.append(("I2C", i, kw)) or "bus"
    monkeypatch.setitem(sys.modules, "machine", fake)
    monkeypatch.setattr(sys, "implementation", types.SimpleNamespace(
        name="micropython", _machine=machine_name))
    src = (BOARDS_DIR / "esp32.py").read_text()
    if supply_pin is not None:
        src = src.replace("SUPPLY_PIN = None", f"SUPPLY_PIN = {supply_pin}")
    mod = types.ModuleType("acal_board")
    exec(compile(src, "esp32.py", "exec"), mod.__dict__)
    return mod, calls


@pytest.mark.parametrize("machine_name,chip,pins", [
    ("Generic ESP32 module with ESP32", "ESP32", (21, 22)),
    ("Generic ESP32S3 module with ESP32S3", "ESP32S3", (8, 9)),
    ("ESP32C3 module with ESP32C3", "ESP32C3", (8, 9))])
def test_each_chip_gets_i2c0_on_usable_pins(monkeypatch, machine_name, chip, pins):
    board, calls = load(monkeypatch, machine_name)
    assert board.CHIP == chip and board.i2c() == "bus"
    assert calls == [("I2C", 0, {"sda": ("pin", pins[0]), "scl": ("pin", pins[1]),
                                 "freq": 400000})]
    assert set(pins) <= USABLE[chip]
    assert not hasattr(board, "supply_mv")       # no supply wired: a supply model is refused


def test_another_chip_takes_the_ports_own_default_pins(monkeypatch):
    board, calls = load(monkeypatch, "ESP32C6 module with ESP32C6")
    board.i2c()
    assert calls == [("I2C", 0, {"freq": 400000})]


def test_supply_in_mv_from_the_calibrated_adc(monkeypatch):
    board, calls = load(monkeypatch, "ESP32C3 module with ESP32C3", supply_pin=2, uv=1_652_000)
    assert board.supply_mv() == 3304 and board.supply_mv() == 3304   # divide by 2, in mV
    assert calls == [("ADC", ("pin", 2), 3)]                           # made once, at 11 dB


def test_deploy_reads_its_runtime_and_arch():
    from accelcal.board import deploy
    info = deploy.board_info("esp32")
    assert info["RUNTIME"] == "micropython" and info["ARCH"] == "xtensawin"


def test_the_esp32_offers_spi_on_vspis_io_mux_pins(monkeypatch, tmp_path, rng):
    """On an ESP32 the board file offers the LIS3DH on SPI too: VSPI (machine.SPI(2)) at 10 MHz,
    mode 3, on the IO_MUX pins the ESP32 datasheet gives VSPI (CLK 18, D 23, Q 19, CS0 5), all
    usable and apart from the I2C pins; through them the driver finds the simulated chip
    (WHO_AM_I over the virtual board's fake SPI) and reads its FIFO.  BUS stays I2C; the S3 and
    the C3 offer no SPI (no sensor_bus: the app takes their LIS3DH on I2C only)."""
    import numpy as np
    # lis3dh_spi (which the board file's spi() imports) first: load() swaps sys.implementation
    # for one without the cache_tag CPython's importer reads
    from acal.logger import lis3dh, lis3dh_spi  # noqa: F401
    from accelcal.simulate.stimulus import write_stimulus
    from vclock import Clock
    from vlis3dh import SimLIS3DH, Stimulus
    n = 800
    write_stimulus(tmp_path / "stim.bin", 400, np.tile([0.0, 0.0, 1.0], (n, 1))
                   + rng.normal(scale=0.002, size=(n, 3)), np.full(n, 25.0))
    clock = Clock()
    sim = SimLIS3DH(Stimulus(str(tmp_path / "stim.bin")), clock)
    board, calls = load(monkeypatch, "Generic ESP32 module with ESP32", chip=sim)
    assert board.BUS == "i2c"
    regs = board.sensor_bus("spi")
    assert calls == [("SPI", 2, {"baudrate": 10_000_000, "polarity": 1, "phase": 1,
                                 "sck": ("pin", 18), "mosi": ("pin", 23), "miso": ("pin", 19)}),
                     ("Pin", 5, 1, 1)]
    spi_pins = {18, 23, 19, 5}
    assert spi_pins <= USABLE["ESP32"] and not spi_pins & {board.SDA_PIN, board.SCL_PIN}
    d = lis3dh.LIS3DH(regs, rate_hz=400, fifo=True)          # WHO_AM_I 0x33 over SPI
    clock.sleep_us(50_000)
    k = d.fifo_level()
    out = [0] * 96
    d.read_fifo(out, 0, k)
    assert k >= 15 and all(abs(v - 1024) < 40 for v in out[2:3 * k:3])   # z: 1 g in Q10
    assert lis3dh.answers(board.spi())
    for name in ("Generic ESP32S3 module with ESP32S3", "ESP32C3 module with ESP32C3"):
        other, _ = load(monkeypatch, name)
        assert other.SPI_ID is None and not hasattr(other, "sensor_bus")
