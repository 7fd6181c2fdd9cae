"""The device app itself (CPython, the simulated LIS3DH behind the fake I2C bus) wearing a wrist
with a shock for two days, with base+step: its calibrations find the step's time and size, log
them (the step's EFFECT record holds ts), and the host's replay of the raw capture reproduces
every record.  The same on the virtual board over mpremote is slow (`make bench`)."""
import json
import os
import sys

import numpy as np
import pytest

from accelcal.bridge import boardlog
from accelcal.locations import CHIP_DIR
from conftest import run_cli, wear_on_virtual_board

RATE = 10


@pytest.mark.slow   # CI's time limit (stop 37)
def test_the_app_finds_and_removes_a_shock(tmp_path):
    """In the default run (about 30 s): the board's own code path, app to log to replay."""
    sys.path.insert(0, str(CHIP_DIR))
    from simboard import SimBoard
    from acal.core import effects as deff
    from acal.logger import log
    from acal.logger.app import App
    from acal.core.profile import WEAR
    rec, stim = tmp_path / "rec.csv", tmp_path / "stim.bin"
    r = run_cli("simulate", "wrist", "--days", 2, "--rate", RATE, "--seed", 31, "--effect", "step",
                "-o", rec, "--stimulus", stim)
    assert r.returncode == 0, r.stderr
    truth = json.loads(rec.with_suffix(".truth.json").read_text())["effects"][0]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        app = App(SimBoard(str(stim)), rate_hz=RATE, capture_bytes=1 << 25, recal_seconds=6 * 3600,
                  model="base+step", profile=WEAR)
        app.run(10 ** 9)
    finally:
        os.chdir(cwd)
    lg = boardlog.decode(tmp_path / "log.bin")
    cals, effs = lg.dicts(log.CAL), lg.dicts(log.EFFECT)
    ok = [(c, e) for c, e in zip(cals, effs) if c["status"] == 0 and e["effect"] == deff.STEP]
    assert ok, [c["status"] for c in cals]
    c, e = ok[-1]
    ts = e["ref_time"] * deff.DT_UNIT_S        # running time from the stimulus's start, s
    j = np.array([e["p0"], e["p1"], e["p2"]]) / float(1 << 24)
    print("calibrations", len(cals), "ok", len(ok), "ts", ts, "true", truth["reference"]["ts"],
          "j mg", np.round(j * 1e3, 2), "true", np.round(list(truth["params"].values()), 5))
    assert 0 <= ts - truth["reference"]["ts"] < 6 * 3600
    assert np.abs(j - np.array(list(truth["params"].values()))).max() < 0.001
    replay = boardlog.replay(tmp_path)
    assert replay["identical"], replay


@pytest.mark.slow
def test_the_virtual_board_finds_the_shock_over_mpremote(tmp_path):
    """The same wrist on the virtual board (the MicroPython unix port on a pty, an RP2040-sized
    heap) with the real mpremote: deploy base+step, acquire two simulated days, pull: the pulled
    summary shows the step's time and size, and the host's replay of the capture is identical."""
    rec, stim = tmp_path / "rec.csv", tmp_path / "stim.bin"
    r = run_cli("simulate", "wrist", "--days", 2, "--rate", RATE, "--seed", 31, "--effect", "step",
                "-o", rec, "--stimulus", stim)
    assert r.returncode == 0, r.stderr
    truth = json.loads(rec.with_suffix(".truth.json").read_text())["effects"][0]
    s, out = wear_on_virtual_board(tmp_path, stim, "base+step", RATE)
    ok = [c for c in s["calibrations"] if c["status"] == "ok" and "step" in c.get("effects", {})]
    assert ok, [c["status"] for c in s["calibrations"]]
    step = ok[-1]["effects"]["step"]
    j = np.array(list(step["params"].values())) / 1e3          # mg -> g
    print("ts", step["step_time_s"], "true", truth["reference"]["ts"], "j", j)
    assert 0 <= step["step_time_s"] - truth["reference"]["ts"] < 6 * 3600
    assert np.abs(j - np.array(list(truth["params"].values()))).max() < 0.001
    r = run_cli("replay", out, "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["identical"], r.stdout + r.stderr
