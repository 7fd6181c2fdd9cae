"""An effect that follows a column of the recording (issue 17): the wearable's battery voltage,
written after temp (CSV t,x,y,z,temp,battery_v), and a user's effects file that declares an
offset following it (regressor "column:battery_v").  Simulated wear hides it; once declared,
diagnose names it and the loop ends within 1.5x of the true model's held-out error; undeclared,
what remains is said to follow that column; calibrate (lsq on every rest point), save and apply
remove it, the applied file keeping the column; points files carry the column too; what cannot
be done (no such column, the device's fit, the device engine) is one line and exit 2."""
import json

import numpy as np
import pytest

from accelcal.files.recordings import recording_columns
from conftest import run_cli, run_main, true_heldout_error

DAYS, RATE, SEED = 3, 10, 31
SUPPLY = '''
EFFECTS = [
    dict(name="supply", regressor="column:battery_v", unit="g/V", bound=0.05,
         explanation="The zero-g level follows the supply: the readout's reference is not "
                     "fully ratiometric, so rest readings shift as the battery runs down."),
]
'''


@pytest.fixture(scope="module")
def battery(tmp_path_factory):
    d = tmp_path_factory.mktemp("battery")
    eff = d / "supply.py"
    eff.write_text(SUPPLY)
    rec = d / "bat.csv"
    r = run_cli("simulate", "wrist", "--days", DAYS, "--rate", RATE, "--seed", SEED,
                "--effects", eff, "--effect", "supply", "-o", rec)
    assert r.returncode == 0, r.stderr
    return eff, rec


def diagnose(rec, eff, model="base"):
    args = ["diagnose", rec, "--model", model, "--json"] + (["--effects", eff] if eff else [])
    r = run_cli(*args)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def test_the_simulator_writes_the_column_and_says_what_it_is(battery):
    _, rec = battery
    head = rec.read_text()[:200].splitlines()
    assert head[0] == "t,x,y,z,temp,battery_v"
    v = np.loadtxt(rec, delimiter=",", skiprows=1, usecols=5, max_rows=864000)   # the first day
    assert 3.7 < v.min() < 3.85 and 4.1 < v.max() < 4.25       # a LiPo's day, discharged
    truth = json.loads(rec.with_suffix(".truth.json").read_text())
    assert "battery" in truth["columns"]["battery_v"]
    assert truth["effects"][0]["reference"]["battery_v0"] == pytest.approx(3.9)


def test_a_declared_column_effect_is_found_and_the_loop_ends_near_the_truth(battery):
    eff, rec = battery
    first = diagnose(rec, eff)
    assert first["missing_effect"] == "supply", first["explanation"]
    assert "column:battery_v" in first["where_it_fails"]
    second = diagnose(rec, eff, "base+supply")
    assert second["missing_effect"] is None, second["explanation"]
    assert second["reference"]["battery_v0"] == pytest.approx(3.95, abs=0.1)
    assert second["heldout_error_mg"] <= 1.5 * true_heldout_error(rec, eff)
    assert second["heldout_error_mg"] < 0.6 * first["heldout_error_mg"]


def test_undeclared_what_remains_follows_the_column(battery):
    """Without the declaration the catalogue cannot explain it; diagnose says that the residual
    follows the recording's column and how to declare an effect on it."""
    _, rec = battery
    model = "base"
    for _ in range(4):
        out = diagnose(rec, None, model)
        if out["missing_effect"] is None:
            break
        model += "+" + out["missing_effect"]
    assert out["missing_effect"] is None
    wr = out["what_remains"]
    assert wr["regressor"] == "column:battery_v", out["explanation"]
    assert "regressor='column:battery_v'" in wr["suggests"] and wr["text"] in out["explanation"]


def test_calibrate_save_and_apply_keep_the_column(battery, tmp_path):
    eff, rec = battery
    params, out = tmp_path / "p.json", tmp_path / "applied.csv"
    r = run_cli("calibrate", rec, "--effects", eff, "--model", "base+supply", "--method", "lsq",
                "--points", "all", "--save", params, "--json")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    truth = json.loads(rec.with_suffix(".truth.json").read_text())
    true_p = np.array(list(truth["effects"][0]["params"].values()))
    got = np.array([res["params"][f"supply_{a}"] for a in "xyz"])
    assert np.abs(got - true_p).max() < 0.2 * np.abs(true_p).max(), (got, true_p)
    assert "battery_v0" in json.loads(params.read_text())["reference"]
    r = run_cli("apply", "--effects", eff, params, rec, "-o", out)
    assert r.returncode == 0, r.stderr
    assert out.read_text()[:40].splitlines()[0] == "t,x,y,z,temp,battery_v"
    a = np.loadtxt(out, delimiter=",", skiprows=1, max_rows=50000)
    b = np.loadtxt(rec, delimiter=",", skiprows=1, max_rows=50000)
    assert np.array_equal(a[:, 5], b[:, 5]) and np.array_equal(a[:, 0], b[:, 0])
    after = diagnose(out, None)
    assert after["heldout_error_mg"] < 0.6 * diagnose(rec, None)["heldout_error_mg"]
    # the same parameters on a recording without the column: one line
    bare = tmp_path / "bare.csv"
    bare.write_text("t,x,y,z,temp\n" + "".join(f"{i / 10:.1f},0,0,1,30\n" for i in range(50)))
    r = run_cli("apply", "--effects", eff, params, bare, "-o", tmp_path / "o.csv")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "battery_v" in r.stderr, r.stderr
    assert not (tmp_path / "o.csv").exists()


def test_compare_scores_the_declared_column_model(battery, capsys):
    eff, rec = battery
    code, text, err = run_main(capsys, ["compare", str(rec), "--methods", "lsq", "--model",
                                        "base+supply", "--effects", str(eff), "--json"])
    assert code == 0, err
    rows = {(r["method"], r.get("model", "base")): r for r in json.loads(text)["rows"]}
    lsq, base = rows[("lsq", "base+supply")], rows[("lsq", "base")]
    assert lsq["status"] == "calibrated" and lsq["error_after_mg"] < 0.6 * base["error_after_mg"]
    dev = rows[("device", "base+supply")]
    assert dev["status"] == "failed" and "no device form" in dev["reason"]


def test_what_the_board_cannot_do_is_one_line(battery, capsys):
    eff, rec = battery
    for extra, says in ((["--model", "base+supply"], "no device form"),
                        (["--model", "base+supply", "--method", "lsq", "--points", "all",
                          "--engine", "device"], "--engine vector")):
        code, _, err = run_main(capsys, ["calibrate", str(rec), "--effects", str(eff), *extra])
        assert code == 2 and err.count("\n") == 1 and says in err, err


def test_a_points_file_carries_the_column(battery, tmp_path, capsys):
    """Rest points with a battery_v column (what a user's own pipeline might export): lsq fits
    the declared effect on them; without the column, one line."""
    eff, rec = battery
    from accelcal.pipeline.restpoints import rest_points, usable
    p = usable(rest_points(str(rec)))
    pts = tmp_path / "pts.csv"
    np.savetxt(pts, np.column_stack([p.v, p.temp, p.t, p.cols["battery_v"]]), delimiter=",",
               header="x,y,z,temp,t,battery_v", comments="", fmt="%.7f")
    code, text, err = run_main(capsys, ["calibrate", str(pts), "--effects", str(eff), "--model",
                                        "base+supply", "--method", "lsq", "--points", "all",
                                        "--json"])
    assert code == 0, err
    res = json.loads(text)
    truth = json.loads(rec.with_suffix(".truth.json").read_text())
    true_p = np.array(list(truth["effects"][0]["params"].values()))
    got = np.array([res["params"][f"supply_{a}"] for a in "xyz"])
    assert np.abs(got - true_p).max() < 0.2 * np.abs(true_p).max(), (got, true_p)
    assert res["error_after_mg"] < 0.3 * res["error_before_mg"]
    np.savetxt(pts, np.column_stack([p.v, p.temp, p.t]), delimiter=",",
               header="x,y,z,temp,t", comments="", fmt="%.7f")
    code, _, err = run_main(capsys, ["calibrate", str(pts), "--effects", str(eff), "--model",
                                     "base+supply", "--method", "lsq", "--points", "all"])
    assert code == 2 and err.count("\n") == 1 and "battery_v" in err, err


def test_recording_headers():
    assert recording_columns(["t", "x", "y", "z"]) == []
    assert recording_columns(["t", "x", "y", "z", "temp", "battery_v", "rssi"]) == ["battery_v", "rssi"]
    assert recording_columns(["t", "x", "y", "z", "battery_v"]) == ["battery_v"]
    for bad in (["x", "y", "z", "t"], ["t", "x", "y", "z", "device"], ["t", "x", "y", "z", "Bat"],
                ["t", "x", "y", "z", "v", "v"], ["t", "x", "y", "z", "battery_v", "temp"]):
        assert recording_columns(bad) is None, bad


@pytest.mark.parametrize("reg, says", [("column:temp", "column:NAME"), ("column:", "column:NAME"),
                                       ("column:Battery", "column:NAME"), ("battery", "column:NAME")])
def test_a_bad_column_regressor_is_one_line(battery, tmp_path, capsys, reg, says):
    _, rec = battery
    f = tmp_path / "bad.py"
    f.write_text(f"EFFECTS = [dict(name='b', regressor={reg!r}, unit='g', bound=0.1, "
                 "explanation='x')]")
    code, _, err = run_main(capsys, ["diagnose", str(rec), "--effects", str(f)])
    assert code == 2 and err.count("\n") == 1 and says in err, err
