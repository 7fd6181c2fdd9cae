"""End to end, as a user does it: the virtual board (real MicroPython unix port on a pty, with
an RP2040-sized heap), the real mpremote: deploy, acquire two simulated hours, pull, decode; the
board's calibrations equal, bit for bit, the host's replay of its capture through the device
modules under CPython; its counters agree with the simulated chip's ground truth.  And the
host side's bad-input paths: one line, exit status 2."""
import json
import os
import pty
import tty

import numpy as np
import pytest

import test_app
from accelcal.board import virtual
from conftest import ROOT, mpremote, run_cli

RATE = 10


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    d = tmp_path_factory.mktemp("vboard")
    test_app.RATE = RATE
    try:  # rest at random orientations, 8 s still / 4 s moving: two hours, calibrations every 15 min
        test_app.stimulus(d / "stim.bin", np.random.default_rng(7), n_rest=600)
    finally:
        test_app.RATE = 25
    with virtual.Running(d / "flash", d / "stim.bin", "--heap", "240k", "--bus-faults", "20") as b:
        b.dir = d
        yield b



def test_deploy_acquire_pull_replay_bit_for_bit(board):
    port = board.port
    r = run_cli("deploy", "--port", port, "--rate", RATE, "--capture-kb", 2048, "--recal-hours",
                0.25, "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    from accelcal.board.deploy import APP_MODULES
    assert info["board"] == "virtual" and info["platform"] == "linux"
    device = {f.relative_to(ROOT / "device" / "acal").as_posix()
              for f in (ROOT / "device" / "acal").rglob("*.py")} - {"logger/lis3dh_cp.py"}
    assert info["modules"] == len(APP_MODULES) and set(APP_MODULES) == device
    assert (board.dir / "flash" / "lib" / "acal" / "paper" / "optimiser.py").exists()
    assert "acal.logger.app.main(rate_hz=10, profile=1, capture_bytes=2097152, recal_seconds=900)" in \
        (board.dir / "flash" / "main.py").read_text()   # profile 1: wear, the default

    # acquire runs with what deploy recorded on the board
    r = run_cli("acquire", "--port", port, "--hours", 2)
    assert r.returncode == 0, r.stderr
    assert "acal: 3600 s" in r.stderr  # hourly progress lines from the board's console

    # Ground truth from the simulated chip, in the same interpreter session (no soft reset).
    truth = mpremote(port, "resume", "exec",
                     "import acal_board\nprint(acal_board.chip.generated, acal_board.bus.faults)").split()
    generated, faults = int(truth[0]), int(truth[1])

    out = board.dir / "pulled"
    r = run_cli("pull", "--port", port, "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    c = s["counters"]
    assert c["samples"] + c["lost"] == generated == 2 * 3600 * RATE
    assert c["bus_errors"] == faults > 0
    ok = [cal for cal in s["calibrations"] if cal["status"] == "ok"]
    assert len(ok) >= 3
    p = np.array([ok[-1][n] for n in ("kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz")])
    assert np.abs(p - test_app.TRUTH).max() < 0.01
    assert s["stored_calibration"]["number"] == ok[-1]["number"]

    r = run_cli("replay", out, "--json")
    assert r.returncode == 0, r.stdout + r.stderr
    rep = json.loads(r.stdout)
    assert rep["identical"] and rep["cal"]["board"] == len(s["calibrations"]) and rep["rest"]["board"] > 100
    assert rep["samples_replayed"] == generated


def test_pull_from_a_board_without_our_logs(tmp_path):
    stim = tmp_path / "stim.bin"
    test_app.stimulus(stim, np.random.default_rng(1), n_rest=2)
    with virtual.Running(tmp_path / "empty", stim) as b:
        r = run_cli("pull", "--port", b.port, "-o", tmp_path / "out")
        r2 = run_cli("acquire", "--port", b.port, "--hours", 1)
    assert r2.returncode == 2 and "accelcal is not deployed there" in r2.stderr
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "no accelcal log.bin on this board" in r.stderr


def test_missing_port_is_one_line_exit_2(tmp_path):
    for cmd in (("deploy", "--port", "/dev/ttyNOPE"), ("pull", "--port", "/dev/ttyNOPE", "-o", tmp_path),
                ("acquire", "--port", "/dev/ttyNOPE", "--hours", 1)):
        r = run_cli(*cmd)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
        assert "/dev/ttyNOPE: no such port" in r.stderr and "Traceback" not in r.stderr


def test_a_port_that_is_not_a_micropython_board(tmp_path, monkeypatch):
    monkeypatch.setenv("ACCELCAL_REPL_TIMEOUT", "4")
    # A pty whose other end answers with something else (a GPS, a modem...): mpremote gives up.
    master, slave = pty.openpty()
    tty.setraw(slave)
    pid = os.fork()
    if pid == 0:  # the "device": answers every write with NMEA-ish noise
        try:
            while True:
                os.read(master, 1024)
                os.write(master, b"$GPGGA,0,0*00\r\n")
        finally:
            os._exit(0)
    try:
        r = run_cli("deploy", "--port", os.ttyname(slave))
    finally:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "no MicroPython REPL answered within 4 s" in r.stderr


def test_replay_of_a_corrupt_log_is_one_line_exit_2(tmp_path):
    (tmp_path / "log.bin").write_bytes(np.random.default_rng(3).bytes(5000))
    (tmp_path / "capture.bin").write_bytes(b"")
    r = run_cli("replay", tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "no valid accelcal log records" in r.stderr
    r = run_cli("replay", tmp_path / "nothing-here")
    assert r.returncode == 2 and "no log.bin" in r.stderr


def test_mip_package_lists_every_device_module_and_installs(tmp_path):
    pkg = json.loads((ROOT / "package.json").read_text())
    listed = sorted(dst for dst, src in pkg["urls"])
    assert listed == sorted(f"acal/{p.relative_to(ROOT / 'device' / 'acal').as_posix()}"
                            for p in (ROOT / "device" / "acal").rglob("*.py"))
    assert all((ROOT / src).exists() for _, src in pkg["urls"])
    stim = tmp_path / "stim.bin"
    test_app.stimulus(stim, np.random.default_rng(1), n_rest=2)
    with virtual.Running(tmp_path / "flash", stim) as b:
        mpremote(b.port, "mip", "install", "--target", "lib", str(ROOT / "package.json"))
        out = mpremote(b.port, "exec", "import acal.logger.app, acal.logger.lis3dh_cp\nprint(acal.logger.app.VERSION)")
    from acal.logger.app import VERSION
    assert out.strip() == str(VERSION) == "4"
    lib = tmp_path / "flash" / "lib" / "acal"
    assert sorted(p.relative_to(lib) for p in lib.rglob("*") if p.is_file()) == \
        sorted(p.relative_to(ROOT / "device" / "acal") for p in (ROOT / "device" / "acal").rglob("*.py"))


def test_a_base_board_gets_core_and_logger_only(tmp_path):
    """Each install unit its own mip package (device/UNIT.json): together they list package.json's
    modules, each once; core's and logger's alone make a board that runs the base logger and has
    no acal/paper nor acal/discover.  `deploy --units run` copies what the settings run."""
    units = {u: json.loads((ROOT / "device" / f"{u}.json").read_text())
             for u in ("core", "logger", "paper", "discover")}
    whole = json.loads((ROOT / "package.json").read_text())
    listed = [dst for u in units.values() for dst, _ in u["urls"]]
    assert sorted(listed) == sorted(dst for dst, _ in whole["urls"])
    assert all(u["version"] == whole["version"] for u in units.values())
    for name, u in units.items():
        assert all(dst == src and (ROOT / "device" / src).exists() for dst, src in u["urls"])
        assert all(dst.startswith(f"acal/{name}/") or dst == "acal/__init__.py" for dst, _ in u["urls"])
    stim = tmp_path / "stim.bin"
    test_app.stimulus(stim, np.random.default_rng(1), n_rest=2)
    flash = tmp_path / "flash"
    with virtual.Running(flash, stim) as b:
        for u in ("core", "logger"):
            mpremote(b.port, "mip", "install", "--target", "lib", str(ROOT / "device" / f"{u}.json"))
        out = mpremote(b.port, "exec", "import sys\nfrom acal.logger.processor import Processor\n"
                       "p = Processor(None, 10)\n"
                       "print(' '.join(sorted(m for m in sys.modules if m.startswith('acal'))))")
        assert sorted(p.name for p in (flash / "lib" / "acal").iterdir()) == ["__init__.py", "core", "logger"]
        mods = out.split()
        assert "acal.core.pipeline" in mods and not [m for m in mods if m.startswith(("acal.discover", "acal.paper"))]
        r = run_cli("deploy", "--port", b.port, "--units", "run", "--profile", "paper", "--json")
        assert r.returncode == 0, r.stderr
        assert json.loads(r.stdout)["units"] == ["core", "logger", "paper"]
        assert sorted(p.name for p in (flash / "lib" / "acal").iterdir()) == \
            ["__init__.py", "core", "logger", "paper"]   # the earlier install removed whole
