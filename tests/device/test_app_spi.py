"""The app with the LIS3DH on SPI (lis3dh_spi.SPIRegisters over the virtual board's fake machine.SPI
and chip-select Pin, the simulated chip's SPI front end): the same samples, log and capture as
over I2C, and nothing allocated per sample under MicroPython (64-bit unix and the 32-bit port)."""
import os
import sys

import pytest

from accelcal.locations import CHIP_DIR
from accelcal.bridge import runtime
from test_app import HEAP_SCRIPT, board, stimulus  # noqa: F401

sys.path.insert(0, str(CHIP_DIR))
from acal.logger.app import App  # noqa: E402
from acal.logger.lis3dh import open_bus  # noqa: E402
from acal.logger.lis3dh_spi import SPIRegisters  # noqa: E402


class Wired:
    """A board file for the virtual board's hardware (simboard.SimBoard) with the chip's bus
    chosen: what boards/virtual.py's sensor_bus gives."""

    def __init__(self, hw, bus):
        self.hw, self.bus = hw, bus
        self.clock, self.I2C_ADDRESS = hw.clock, hw.I2C_ADDRESS

    def i2c(self):
        return self.hw.i2c()

    def spi(self):
        return SPIRegisters(self.hw.spi_bus, self.hw.cs)

    def sensor_bus(self, bus=None):
        return open_bus(bus or self.bus, self.spi, self.i2c)


@pytest.fixture
def stim_path(tmp_path, rng):
    path = tmp_path / "stim.bin"
    stimulus(path, rng, n_rest=40)
    return path


@pytest.mark.parametrize("fifo", [True, False])
def test_the_app_on_spi_logs_what_it_logs_on_i2c(tmp_path, stim_path, fifo):
    out = {}
    for bus in ("i2c", "spi", "auto"):
        d = tmp_path / bus
        d.mkdir()
        os.chdir(d)
        hw = board(stim_path)
        app = App(Wired(hw, bus), rate_hz=25, capture_bytes=1 << 22, recal_seconds=600, fifo=fifo)
        app.run(400)
        assert (hw.spi_bus.transfers > 0) == (bus != "i2c")
        assert (hw.bus.transactions > 0) == (bus == "i2c")
        out[bus] = (app.samples, app.lost, (d / "log.bin").read_bytes(), (d / "capture.bin").read_bytes())
    assert out["i2c"][0] >= 400 * 25 and out["i2c"][1] == 0
    assert out["spi"] == out["i2c"] == out["auto"]


def test_auto_falls_back_to_i2c_when_spi_has_no_chip(tmp_path, stim_path):
    """Nothing on SPI (MISO reads 0, as a Pico's pulled-down pad): WHO_AM_I fails there and the
    app reads the chip over I2C."""
    from vbus import SPI, Pin

    class Nothing:
        def spi_select(self, low):
            pass

        def spi_byte(self, v):
            return 0

    hw = board(stim_path)
    hw.spi_bus, hw.cs = SPI(Nothing()), Pin(Nothing())
    os.chdir(tmp_path)
    app = App(Wired(hw, "auto"), rate_hz=25, capture_bytes=0)
    assert type(app.sensor.i2c).__name__ == "I2C" and hw.spi_bus.transfers == 2
    with pytest.raises(ValueError, match="bus must be"):
        App(Wired(hw, "usb"), rate_hz=25)


SPI_BOARD = """from acal.logger.lis3dh_spi import SPIRegisters


class SpiBoard(SimBoard):
    def sensor_bus(self, bus=None):
        return SPIRegisters(self.spi_bus, self.cs)


"""


SPI_LOADED = '\nprint("SPI_LOADED", "acal.logger.lis3dh_spi" in sys.modules)\n'


def test_acquisition_on_spi_allocates_nothing_per_sample_under_micropython(tmp_path, stim_path):
    script = tmp_path / "heap_spi.py"
    script.write_text(HEAP_SCRIPT.replace("app = App(SimBoard(sys.argv[1]),",
                                          SPI_BOARD + "app = App(SpiBoard(sys.argv[1]),")
                      + SPI_LOADED)
    for reader in ("fifo", "registers"):
        out = runtime.run_micropython_script(str(script), str(stim_path), str(tmp_path), reader,
                                             extra_path=[str(CHIP_DIR)]).split()
        assert out[0] == "OK", out
        assert 5000 <= int(out[1]) < 5032 and int(out[3]) == 0
        assert out[-2:] == ["SPI_LOADED", "True"]


def test_a_board_on_i2c_loads_no_spi_code_under_micropython(tmp_path, stim_path):
    """The SPI register class is its own module (lis3dh_spi), which only a board's spi() imports:
    the app on an I2C board runs without it ever loaded."""
    script = tmp_path / "heap_i2c.py"
    script.write_text(HEAP_SCRIPT + SPI_LOADED)
    out = runtime.run_micropython_script(str(script), str(stim_path), str(tmp_path), "fifo",
                                         extra_path=[str(CHIP_DIR)]).split()
    assert out[0] == "OK", out
    assert out[-2:] == ["SPI_LOADED", "False"]


def test_acquisition_on_spi_allocates_nothing_on_the_32_bit_port(tmp_path, stim_path, mp32):
    script = tmp_path / "heap_spi32.py"
    script.write_text(HEAP_SCRIPT.replace("app = App(SimBoard(sys.argv[1]),",
                                          SPI_BOARD + "app = App(SpiBoard(sys.argv[1]),"))
    out = mp32(str(script), str(stim_path), str(tmp_path), "fifo", extra_path=[str(CHIP_DIR)]).split()
    assert out[0] == "OK", out
    assert 5000 <= int(out[1]) < 5032 and int(out[3]) == 0


def test_a_board_file_without_spi_refuses_the_spi_bus(tmp_path, stim_path):
    """A board file with no sensor_bus (boards/esp32.py) has the chip on I2C: bus="spi" is
    refused at once, not run over I2C unsaid."""
    os.chdir(tmp_path)
    with pytest.raises(ValueError, match="I2C only"):
        App(board(stim_path), rate_hz=25, bus="spi")
    assert App(board(stim_path), rate_hz=25, bus="i2c").sensor is not None
