"""An integer the board supplies (its supply in mV, read by the board file's supply_mv()) as a
regressor on the board (issue 17): the device app itself (CPython, the simulated LIS3DH behind
the fake I2C bus, the simulated battery in its stimulus) wears a wrist whose zero-g level follows the battery for two days with
base+supply_offset; its calibrations find the effect near its true size, log the reference
supply in the EFFECT record, capture the supply beside the samples, and the host's replay of
the capture reproduces every record.  calibrate's device method on the recording's supply_mv
column gives the same kind of fit; a board file without supply_mv() is refused."""
import json
import os
import sys

import numpy as np
import pytest

from accelcal.bridge import boardlog
from accelcal.locations import CHIP_DIR
from conftest import run_cli, run_main, true_heldout_error, wear_on_virtual_board

RATE = 10


@pytest.fixture(scope="module")
def wrist(tmp_path_factory):
    d = tmp_path_factory.mktemp("supply")
    rec, stim = d / "rec.csv", d / "stim.bin"
    r = run_cli("simulate", "wrist", "--days", 2, "--rate", RATE, "--seed", 31, "--effect",
                "supply_offset", "-o", rec, "--stimulus", stim)
    assert r.returncode == 0, r.stderr
    return rec, stim


def diagnose(capsys, rec, model="base"):
    code, text, err = run_main(capsys, ["diagnose", str(rec), "--model", model, "--json"])
    assert code == 0, err
    return json.loads(text)


def test_diagnose_names_the_supply_where_the_recording_has_it(wrist, capsys):
    """supply_offset is a candidate wherever a recording has the supply_mv column: named, and
    the loop ends within 1.5x of the true model's held-out error."""
    rec, _ = wrist
    first = diagnose(capsys, rec)
    assert first["missing_effect"] == "supply_offset", first["explanation"]
    second = diagnose(capsys, rec, "base+supply_offset")
    assert second["missing_effect"] is None, second["explanation"]
    assert second["heldout_error_mg"] <= 1.5 * true_heldout_error(rec)


def test_a_battery_that_moves_nothing_names_nothing(tmp_path, capsys):
    """Clean wear with a supply_mv column (a declared effect of that column, 1e-9 g/mV at most:
    nothing) - supply_offset is tried and not named, nor anything else."""
    eff = tmp_path / "none.py"
    eff.write_text("EFFECTS = [dict(name='flat', regressor='column:supply_mv', unit='g/mV', "
                   "bound=1e-9, explanation='A battery that moves nothing.')]")
    rec = tmp_path / "clean.csv"
    r = run_cli("simulate", "wrist", "--days", 2, "--rate", RATE, "--seed", 32, "--effects", eff,
                "--effect", "flat", "-o", rec)
    assert r.returncode == 0, r.stderr
    out = diagnose(capsys, rec)
    tried = {c["effect"]: c for c in out["candidates"]}
    assert tried["supply_offset"]["heldout_error_mg"] is not None
    assert out["missing_effect"] is None, out["explanation"]


def true_params(rec):
    truth = json.loads(rec.with_suffix(".truth.json").read_text())["effects"][0]
    assert truth["effect"] == "supply_offset"
    return np.array(list(truth["params"].values()))      # g/mV


class NoSupply:
    """The simulated board seen through a board file without supply_mv()."""

    def __init__(self, sim):
        self.sim, self.clock, self.I2C_ADDRESS = sim, sim.clock, sim.I2C_ADDRESS

    def i2c(self):
        return self.sim.i2c()


@pytest.mark.slow   # CI's time limit (stop 37)
def test_the_app_follows_the_board_supply(wrist, tmp_path):
    sys.path.insert(0, str(CHIP_DIR))
    from simboard import SimBoard
    from acal.core import effects as deff
    from acal.logger import log
    from acal.logger.app import App
    from acal.core.profile import WEAR
    rec, stim = wrist
    mv = np.loadtxt(rec, delimiter=",", skiprows=1, usecols=5)
    sim = SimBoard(str(stim))     # its stimulus carries the battery: the board reads it
    assert sim.has_supply() and sim.supply_mv() == 0
    sim.chip.stim.load(1234)
    assert sim.supply_mv() == mv[1234]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        with pytest.raises(ValueError, match="supply_mv"):
            App(NoSupply(SimBoard(str(stim))), rate_hz=RATE, model="base+supply_offset",
                profile=WEAR)
        app = App(SimBoard(str(stim)), rate_hz=RATE, capture_bytes=1 << 25,
                  recal_seconds=6 * 3600, model="base+supply_offset", profile=WEAR)
        app.run(10 ** 9)
    finally:
        os.chdir(cwd)
    lg = boardlog.decode(tmp_path / "log.bin")
    cals, effs = lg.dicts(log.CAL), lg.dicts(log.EFFECT)
    ok = [(c, e) for c, e in zip(cals, effs)
          if c["status"] == 0 and e["effect"] == deff.SUPPLY_OFFSET]
    assert ok, [c["status"] for c in cals]
    c, e = ok[-1]
    from accelcal.model.effects import CATALOGUE
    got = CATALOGUE["supply_offset"].from_int([e["p0"], e["p1"], e["p2"]])
    want = true_params(rec)
    print("calibrations", len(cals), "ok", len(ok), "ref mV", e["ref_time"],
          "mg/V", np.round(got * 1e6, 2), "true", np.round(want * 1e6, 2))
    assert 3700 <= e["ref_time"] <= 4200                   # the reference supply, mV
    assert np.abs(got - want).max() < 0.2 * np.abs(want).max(), (got, want)
    assert lg.of(log.SUPPLY) == [] and boardlog.decode(tmp_path / "capture.bin").of(log.SUPPLY)
    s = boardlog.summary(tmp_path)
    assert s["calibrations"][-1]["effects"]["supply_offset"]["ref_supply_mv"] == e["ref_time"]
    replay = boardlog.replay(tmp_path)
    assert replay["identical"], replay


def test_calibrate_fits_the_supply_on_the_device(wrist, capsys, tmp_path):
    """The recording's supply_mv column is the device's third condition: the integer fit (wear
    profile) finds the effect; saved and applied (the twin, bit-exact with the board's apply)
    it comes out of the data; a recording without the column is one line."""
    rec, _ = wrist
    params, out = tmp_path / "p.json", tmp_path / "applied.csv"
    code, text, err = run_main(capsys, ["calibrate", str(rec), "--model", "base+supply_offset",
                                        "--save", str(params), "--json"])
    assert code == 0, err
    res = json.loads(text)
    assert res["method"] == "device" and res["status"] == "calibrated" and "note" not in res
    got = np.array([res["params"][f"v{a}"] for a in "xyz"])
    want = true_params(rec)
    assert np.abs(got - want).max() < 0.2 * np.abs(want).max(), (got, want)
    assert 3700 <= res["reference"]["supply_mv0"] <= 4200
    assert res["error_after_mg"] < 0.02 * res["error_before_mg"]
    code, _, err = run_main(capsys, ["apply", str(params), str(rec), "-o", str(out)])
    assert code == 0, err
    a = np.loadtxt(out, delimiter=",", skiprows=1, max_rows=200000)
    still = np.abs(np.linalg.norm(a[:, 1:4], axis=1) - 1) < 0.02
    assert np.abs(np.linalg.norm(a[still, 1:4], axis=1) - 1).mean() < 0.004
    bare = tmp_path / "bare.csv"
    bare.write_text("t,x,y,z,temp\n" + "".join(f"{i / 10:.1f},0,0,1,30\n" for i in range(50)))
    code, _, err = run_main(capsys, ["apply", str(params), str(bare), "-o", str(tmp_path / "o.csv")])
    assert code == 2 and err.count("\n") == 1 and "supply_mv" in err, err
    code, _, err = run_main(capsys, ["calibrate", str(bare), "--model", "base+supply_offset"])
    assert code == 2 and err.count("\n") == 1 and "supply_mv" in err, err


def test_compare_scores_the_device_supply_fit(wrist, capsys):
    rec, _ = wrist
    code, text, err = run_main(capsys, ["compare", str(rec), "--methods", "lsq", "--model",
                                        "base+supply_offset", "--json"])
    assert code == 0, err
    rows = {(r["method"], r.get("model", "base")): r for r in json.loads(text)["rows"]}
    base = rows[("lsq", "base")]["error_after_mg"]
    for m in ("device", "lsq"):
        r = rows[(m, "base+supply_offset")]
        assert r["status"] == "calibrated" and r["error_after_mg"] < 0.6 * base, (r, base)


@pytest.mark.slow
def test_the_virtual_board_follows_its_supply_over_mpremote(wrist, tmp_path):
    """The same wrist on the virtual board (the MicroPython unix port on a pty, an RP2040-sized
    heap; its board file reads the stimulus's battery) with the real mpremote: deploy
    base+supply_offset, acquire two simulated days, pull: the pulled summary shows the effect
    and its reference supply, and the host's replay of the capture is identical."""
    rec, stim = wrist
    s, out = wear_on_virtual_board(tmp_path, stim, "base+supply_offset", RATE)
    ok = [c for c in s["calibrations"]
          if c["status"] == "ok" and "supply_offset" in c.get("effects", {})]
    assert ok, [c["status"] for c in s["calibrations"]]
    e = ok[-1]["effects"]["supply_offset"]
    got = np.array(list(e["params"].values())) / 1e6          # mg/V -> g/mV
    want = true_params(rec)
    print("ref mV", e["ref_supply_mv"], "mg/V", np.round(got * 1e6, 2), "true",
          np.round(want * 1e6, 2))
    assert 3700 <= e["ref_supply_mv"] <= 4200
    assert np.abs(got - want).max() < 0.2 * np.abs(want).max(), (got, want)
    replay = boardlog.replay(out)
    assert replay["identical"], replay


def test_a_declared_offset_on_the_supply_column_runs_on_the_device(wrist, tmp_path, capsys):
    """A user's effect declared on column:supply_mv (power 1, an offset) is the device's
    supply_offset: the board is given that name, and the integer fit finds it."""
    from accelcal.model.declared import register
    from accelcal.model.effects import ModelSpec
    rec, _ = wrist
    eff = tmp_path / "vsys.py"
    eff.write_text("EFFECTS = [dict(name='vsys', regressor='column:supply_mv', unit='g/mV', "
                   "bound=4e-5, explanation='The offset follows VSYS.')]")
    code, text, err = run_main(capsys, ["calibrate", str(rec), "--effects", str(eff), "--model",
                                        "base+vsys", "--json"])
    assert code == 0, err
    res = json.loads(text)
    assert res["method"] == "device" and res["status"] == "calibrated"
    got = np.array([res["params"][f"vsys_{a}"] for a in "xyz"])
    want = true_params(rec)
    assert np.abs(got - want).max() < 0.2 * np.abs(want).max(), (got, want)
    register(str(eff))
    assert ModelSpec.parse("base+drift+vsys").device_model == "base+drift+supply_offset"
    assert ModelSpec.parse("base+vsys").host_only == ()
