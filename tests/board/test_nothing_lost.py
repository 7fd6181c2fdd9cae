"""Nothing lost by default: the app as `deploy` starts it (acal.logger.app.main with no reader named:
the FIFO, drained past its watermark) on the emulated Pico (MicroPython, boards/pico.py) and the
emulated Feather RP2040 (CircuitPython, boards/feather_rp2040.py, busio.I2C at 400 kHz) loses no
sample at any rate the CLI offers: the app counts none lost, the chip model overwrote none, and
the FIFO never filled.  One short run per board here; an emulated hour at each rate is slow."""
import numpy as np
import pytest

from accelcal.simulate.stimulus import calibration_dance
from conftest import ROOT, emulated_chip

TRUTH = np.array([1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04])
APP = """import acal.logger.app
app = acal.logger.app.main(seconds={seconds}, verbose=False, rate_hz={rate}, profile=1)
print('ACAL_DONE', app.samples, app.lost, app.fifo_overruns, app.bus_errors,
      int(app.sensor.fifo_tables is not None))
"""
BOARDS = {"pico": ("pico.py", "MICROPYTHON", "0,4,5"),
          "feather": ("feather_rp2040.py", "CIRCUITPYTHON", "1,2,3")}


def cli_rates():
    """The rates `deploy`/`acquire` offer (--rate's choices)."""
    import argparse
    from accelcal.cli import board
    top = argparse.ArgumentParser()
    board.add_parsers(top.add_subparsers())
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    return next(a.choices for a in sub.choices["deploy"]._actions if a.dest == "rate")


RATES = [10, 25, 50, 100, 200, 400]


def test_the_rates_are_the_clis():
    assert cli_rates() == RATES


def run_default_app(tmp_path, which, rate, seconds):
    from accelcal.board import emulated
    from accelcal.bridge import rp2040
    board_file, fw_name, i2c = BOARDS[which]
    fw = getattr(rp2040, fw_name)
    emulated_chip(fw)
    stim = tmp_path / "stim.bin"
    calibration_dance(stim, 400, TRUTH, seed=5, rounds=1, rest_s=9)  # then the last pose, held
    r = emulated.run([APP.format(seconds=seconds, rate=rate)], stimulus=stim, fw=fw, i2c=i2c,
                     puts={"acal_board.py": (ROOT / "boards" / board_file).read_bytes()},
                     timeout=max(1800, 6 * seconds))
    samples, lost, overruns, bus_errors, tables = map(int, r.out.split("ACAL_DONE")[1].split()[:5])
    assert tables == (which == "feather")   # the FIFO tables where the board file asks (FIFO_TABLES)
    chip = r.report["lis3dh"]
    print(f"\n{which} {rate} Hz, {seconds} emulated s: {samples} samples, {lost} lost, "
          f"{overruns} overruns; the chip converted {chip['converted']}, dropped {chip['dropped']}")
    assert (lost, overruns, chip["dropped"], bus_errors) == (0, 0, 0, 0)
    assert seconds * rate <= samples <= chip["converted"] <= samples + 32


@pytest.mark.parametrize("which", ["pico", "feather"])
def test_the_default_app_loses_nothing_at_400_hz(tmp_path, which):
    run_default_app(tmp_path, which, 400, 5 if which == "pico" else 2)


@pytest.mark.slow
@pytest.mark.parametrize("rate", RATES)
@pytest.mark.parametrize("which", ["pico", "feather"])
def test_an_emulated_hour_loses_nothing(tmp_path, which, rate):
    run_default_app(tmp_path, which, rate, 3600)
