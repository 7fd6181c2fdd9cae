"""The LIS3DH wired to SPI on both emulated boards (pico.mjs --spi: the Pico's SPI0 GP16-19,
the Feather RP2040's board.SPI() with CS on D5), the board files and the app as `deploy` starts
them, unchanged: their BUS "auto" finds the chip on SPI, and nothing is lost at any rate the CLI
offers (the app counts none lost, the chip model overwrote none, the FIFO never filled, every
transaction went over SPI).  One short run per board here; 20 emulated s at each rate is slow."""
import shutil

import numpy as np
import pytest

from accelcal.simulate.stimulus import calibration_dance
from conftest import ROOT, emulated_chip

TRUTH = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
RATES = [10, 25, 50, 100, 200, 400]     # the CLI's (test_nothing_lost.test_the_rates_are_the_clis)
APP = """import acal.logger.app
app = acal.logger.app.main(seconds={seconds}, verbose=False, rate_hz={rate}, profile=1)
print('ACAL_DONE', app.samples, app.lost, app.fifo_overruns, app.bus_errors, type(app.sensor.i2c).__name__)
"""
BOARDS = {"pico": ("pico.py", "MICROPYTHON", "SPI_PICO", "SPIRegisters"),
          "feather": ("feather_rp2040.py", "CIRCUITPYTHON", "SPI_FEATHER", "BusioSPIRegisters")}


def run_on_spi(tmp_path, which, rate, seconds):
    from accelcal.board import emulated
    from accelcal.bridge import rp2040
    board_file, fw_name, spi, regs = BOARDS[which]
    fw = getattr(rp2040, fw_name)
    emulated_chip(fw)
    stim = tmp_path / "stim.bin"
    calibration_dance(stim, 400, TRUTH, seed=5, rounds=1, rest_s=9)
    r = emulated.run([APP.format(seconds=seconds, rate=rate)], stimulus=stim, fw=fw,
                     spi=getattr(emulated, spi),
                     puts={"acal_board.py": (ROOT / "boards" / board_file).read_bytes()},
                     timeout=max(1800, 6 * seconds))
    done = r.out.split("ACAL_DONE")[1].split()
    samples, lost, overruns, bus_errors = map(int, done[:4])
    chip = r.report["lis3dh"]
    print(f"\n{which} on SPI, {rate} Hz, {seconds} emulated s: {samples} samples, {lost} lost, "
          f"{overruns} overruns; the chip converted {chip['converted']}, dropped {chip['dropped']}; "
          f"{chip['transactions']} SPI transactions, {chip['bytes']} bytes")
    assert done[4] == regs and chip["spi"] is not None
    assert (lost, overruns, chip["dropped"], bus_errors) == (0, 0, 0, 0)
    assert seconds * rate <= samples <= chip["converted"] <= samples + 32


@pytest.mark.parametrize("which", ["pico", "feather"])
def test_the_default_app_on_spi_loses_nothing_at_400_hz(tmp_path, which):
    run_on_spi(tmp_path, which, 400, 2)


@pytest.mark.slow
@pytest.mark.parametrize("rate", RATES)
@pytest.mark.parametrize("which", ["pico", "feather"])
def test_the_default_app_on_spi_loses_nothing_at_every_rate(tmp_path, which, rate):
    run_on_spi(tmp_path, which, rate, 20)


def test_deploy_bus_goes_to_the_app_and_boards_name_theirs(tmp_path):
    """`deploy --bus spi` puts bus='spi' in main.py's app settings (left out, the board file's
    BUS rules); the two RP2040 board files default to auto, the virtual board to I2C, and a
    bus the app does not know is refused before anything is read."""
    import argparse
    from accelcal.board.deploy import main_py
    from accelcal.cli import board as cli_board
    top = argparse.ArgumentParser()
    cli_board.add_parsers(top.add_subparsers())
    for given, want in ((["--bus", "spi"], "spi"), ([], None)):
        args = top.parse_args(["deploy", "--port", "X", *given])
        s = cli_board._app_settings(args)
        assert s.get("bus") == want
        assert ("bus='spi'" in main_py(s)) == (want == "spi")
    with pytest.raises(SystemExit):
        top.parse_args(["deploy", "--port", "X", "--bus", "usb"])
    for f, bus in (("pico.py", '"auto"'), ("feather_rp2040.py", '"auto"'),
                   ("virtual.py", 'os.getenv("ACCELCAL_BUS") or "i2c"')):
        assert f"\nBUS = {bus}\n" in (ROOT / "boards" / f).read_text()


def test_board_virtual_bus_is_the_unix_boards_bus(tmp_path):
    """`board virtual --bus spi` on the unix port: boards/virtual.py (as deploy installs it)
    takes BUS from it, and sensor_bus() then reads WHO_AM_I over the fake machine.SPI; the
    default is I2C."""
    from accelcal.board import virtual
    from conftest import mpremote
    calibration_dance(tmp_path / "stim.bin", 100, TRUTH, seed=3, rounds=1, rest_s=1)
    code = ("import acal_board\nfrom acal.logger.lis3dh import answers\n"
            "r = acal_board.sensor_bus()\nprint('BUS', acal_board.BUS, type(r).__name__, answers(r))")
    for given, want in ((["--bus", "spi"], "BUS spi SPIRegisters True"),
                        ([], "BUS i2c I2C True")):
        flash = tmp_path / f"flash{len(given)}"
        (flash / "lib" / "acal").mkdir(parents=True)
        (flash / "acal_board.py").write_bytes((ROOT / "boards" / "virtual.py").read_bytes())
        for sub in ("acal/__init__.py", "acal/core", "acal/logger"):
            src = ROOT / "device" / sub
            if src.is_dir():
                shutil.copytree(src, flash / "lib" / sub)
            else:
                (flash / "lib" / sub).write_bytes(src.read_bytes())
        with virtual.Running(flash, tmp_path / "stim.bin", *given) as b:
            out = mpremote(b.port, "exec", code)
        assert out.strip().splitlines()[-1] == want, out
