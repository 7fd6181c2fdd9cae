"""The real mpremote to the emulated Pico: `accelcal board virtual --chip rp2040` serves the
emulated chip's USB CDC on a pseudo-terminal, and `deploy`, `acquire` and `pull` use that port as
a Pico's, unchanged.  What the board logged replays on the host bit for bit."""
import json

import numpy as np
import pytest

from accelcal.board import virtual
from accelcal.simulate.stimulus import calibration_dance
from conftest import mpremote, run_cli, run_main

TRUTH = [1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04]


@pytest.fixture(scope="module")
def emulator():
    from accelcal.bridge import rp2040
    from accelcal.errors import InputError
    try:
        rp2040.emulator_index()
    except InputError as e:
        pytest.skip(f"emulated RP2040 not available: {e}")



def session(tmp_path, app_args, seconds):
    """deploy, acquire `seconds` of board time, pull: (deploy's JSON, pull's JSON, the pulled
    folder)."""
    with virtual.Running(tmp_path / "pico.bin", tmp_path / "stim.bin", "--chip", "rp2040") as b:
        # an older install's sources (MicroPython imports a .py before the .mpy beside it) and a
        # module the package no longer has: deploy removes both
        mpremote(b.port, "exec", "import os\nfor d in ('lib', 'lib/acal', 'lib/acal/core'):\n"
                 "    os.mkdir(d)\nfor f in ('core/fixed.py', 'orphan.py'):\n"
                 "    open('lib/acal/' + f, 'w').write('X = 1')")
        r = run_cli("deploy", "--port", b.port, *app_args, "--json")
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        assert sorted(info["stale_removed"]) == ["lib/acal/core/fixed.py", "lib/acal/orphan.py"]
        out = mpremote(b.port, "exec", "import acal.core.fixed\nprint(acal.core.fixed.__file__)")
        assert out.strip() == "/lib/acal/core/fixed.mpy"
        r = run_cli("acquire", "--port", b.port, "--hours", seconds / 3600, *app_args)
        assert r.returncode == 0, r.stderr
        out = tmp_path / "pulled"
        r = run_cli("pull", "--port", b.port, "-o", out, "--json")
        assert r.returncode == 0, r.stderr
        pulled = json.loads(r.stdout)
    return info, pulled, out


def test_mpremote_deploys_acquires_and_pulls_on_the_emulated_pico(tmp_path, emulator):
    # The stimulus runs on the emulated clock from power-up, and deploy takes a few seconds of it
    # (measured 5.0 s on 26 November, less before): with 10 s poses the move could cut the first
    # 5 s segment by two samples.  30 s poses hold a whole still segment wherever the app starts.
    calibration_dance(tmp_path / "stim.bin", 100, TRUTH, seed=3, rounds=1, rest_s=30.0)
    info, pulled, out = session(tmp_path, ["--fifo", "--capture-kb", 200, "--profile", "paper"], 12)
    assert info["board"] == "pico" and info["platform"] == "rp2" and info["format"] == "mpy"
    c = pulled["counters"]
    assert c["samples"] + c["lost"] >= 12 * 100 and c["fifo_overruns"] == 0
    assert len(pulled["rest_points"]) >= 1
    assert not pulled["dropped"]
    r = run_cli("replay", out, "--json")
    assert r.returncode == 0, r.stdout + r.stderr
    assert json.loads(r.stdout)["identical"]
    # the flash image the board saved when it stopped holds what it ran: littlefs, as written
    img = (tmp_path / "pico.bin").read_bytes()
    assert len(img) == 2 * 1024 * 1024 and b"littlefs" in img


@pytest.mark.slow
def test_a_calibration_dance_on_the_emulated_pico(tmp_path, emulator):
    """Seven emulated minutes of a calibration dance at 100 Hz (the board on each face and six
    edges, three rounds; the paper's profile, which needs two points in each of its nine
    subsets): the board calibrates, the host's replay of its capture gives the same rest points
    and the same calibration, integer for integer."""
    calibration_dance(tmp_path / "stim.bin", 100, TRUTH, seed=4, rounds=3, tilt_deg=20)
    info, pulled, out = session(tmp_path, ["--fifo", "--capture-kb", 1500, "--profile", "paper"],
                                420)
    assert pulled["calibrations"] and pulled["calibrations"][0]["status"] == "ok"
    r = run_cli("replay", out, "--json")
    rep = json.loads(r.stdout)
    assert r.returncode == 0 and rep["identical"] and rep["cal"]["board"] >= 1, rep
    got = np.array([pulled["calibrations"][-1][n] for n in
                    ("kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz")])
    print(f"\nemulated Pico, calibration dance: {rep['samples_replayed']} samples, "
          f"{rep['rest']['board']} rest records, {rep['cal']['board']} calibration(s); "
          f"largest parameter error {np.max(np.abs(got - TRUTH)):.4f}")
    assert np.max(np.abs(got - TRUTH)) < 0.02


def test_bad_emulated_board_options_end_in_one_line(tmp_path, capsys):
    """No file is taken for a flash image unless it is one; the unix port's options refused."""
    stim = tmp_path / "stim.bin"
    calibration_dance(stim, 100, TRUTH, seed=3, rounds=1, rest_s=1)
    other = tmp_path / "notes.txt"
    other.write_text("mine")
    cases = [["--flash", other], ["--flash", stim], ["--heap", "100k"], ["--speed", "2"]]
    for extra in cases:
        code, out, err = run_main(capsys, ["board", "virtual", "--chip", "rp2040", "--stimulus",
                                           stim, *extra])
        assert code == 2 and len(err.strip().splitlines()) == 1 and not out, (extra, err)
    assert other.read_text() == "mine" and stim.stat().st_size > 1000


WIRING = """from machine import I2C, SPI, Pin
i2c = I2C(0, sda=Pin(4), scl=Pin(5), freq=400000)
spi = SPI(0, baudrate=10000000, polarity=1, phase=1, sck=Pin(18), mosi=Pin(19), miso=Pin(16))
cs = Pin(17, Pin.OUT, value=1)
cs(0)
spi.write(bytes([0x8f]))   # read WHO_AM_I (0Fh), DocID17530 6.2
who = spi.read(1)[0]
cs(1)
try:
    on_i2c = i2c.readfrom_mem(0x18, 0x0f, 1)[0]
except OSError:
    on_i2c = -1   # no acknowledge at 0x18
print('WIRED', on_i2c, who)
"""


def test_board_virtual_bus_spi_wires_the_lis3dh_to_spi0(tmp_path, emulator):
    """`board virtual --chip rp2040 --bus spi`: the LIS3DH answers on SPI0 with boards/pico.py's
    pins (WHO_AM_I 0x33, DocID17530) and nothing acknowledges 0x18 on I2C0; the default wires it
    on I2C0 (WHO_AM_I read there) and SPI reads nothing (MISO's pull-down)."""
    calibration_dance(tmp_path / "stim.bin", 100, TRUTH, seed=3, rounds=1, rest_s=1)
    for bus, want in (("spi", "WIRED -1 51"), ("i2c", "WIRED 51 0")):
        with virtual.Running(tmp_path / f"{bus}.bin", tmp_path / "stim.bin", "--chip", "rp2040",
                             "--bus", bus) as b:
            out = mpremote(b.port, "exec", WIRING)
        assert out.strip().splitlines()[-1] == want, (bus, out)
