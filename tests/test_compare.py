"""`accelcal compare`: one row per method, all scored on the same held-out rest points; a
method that cannot fit is a failed row while the others complete; `paper gietzelt` runs."""
import json

import numpy as np
import pytest

from accelcal.pipeline import compare
from accelcal import methods
from accelcal.bridge import runtime
from conftest import run_cli


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("compare") / "wrist.csv"
    r = run_cli("simulate", "wrist", "--days", 3, "--rate", 10, "--seed", 5, "-o", path)
    assert r.returncode == 0, r.stderr
    return path


def test_compare_gives_one_row_per_method_on_the_same_heldout_points(recording, tmp_path):
    r = run_cli("compare", recording, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    rows = {x["method"]: x for x in out["rows"]}
    assert list(rows) == ["device", *methods.ORDER]
    assert all(x["status"] == "calibrated" for x in rows.values()), rows
    assert len({x["error_before_mg"] for x in rows.values()}) == 1
    assert len({x["points"] for x in rows.values()}) == 1   # all fitted on the bins' selection
    # Re-score every row's parameters on the held-out part, independently of compare's table.
    sp = compare.split_points(str(recording), runtime.Config.for_profile("wear"))
    assert (len(sp.train), len(sp.test)) == (out["rest_points"]["train"], out["rest_points"]["heldout"])
    for x in rows.values():
        p = np.array(list(x["params"].values()))
        assert abs(methods.calibration_error_mg(p, sp.test.v) - x["error_after_mg"]) < 1e-3
        assert x["error_after_mg"] < x["error_before_mg"] / 3
        assert x["fit_ms"] > 0
    # the training curve (--plots): every method but differential evolution, whose ~30 fits at
    # growing sizes take over a minute (it is in the table above)
    quick = ["device"] + [m for m in methods.ORDER if m != "de"]
    r = run_cli("compare", recording, "--json", "--plots", tmp_path, "--methods", ",".join(quick))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "training_curve.png").stat().st_size > 10_000
    curve = json.loads(r.stdout)["training_curve"]
    assert set(curve["error_mg"]) == set(quick) and len(curve["sizes"]) >= 5


def test_compare_table_and_method_choice(recording):
    r = run_cli("compare", recording, "--methods", "lsq,linauto", "--train", "thinned")
    assert r.returncode == 0, r.stderr
    assert "at most 10 per direction" in r.stdout
    lines = [ln.split()[0] for ln in r.stdout.splitlines() if ln.split() and ln.split()[0] in
             ("device", *methods.ORDER)]
    assert lines == ["lsq", "linauto"]
    r = run_cli("compare", recording, "--methods", "lsq,fminunc")
    assert r.returncode == 2 and "unknown method fminunc" in r.stderr and r.stderr.count("\n") == 1


def _points_file(path, v, with_device=False):
    with open(path, "w") as fh:
        fh.write("x,y,z\n")
        for x, y, z in v:
            fh.write(f"{x:.6f},{y:.6f},{z:.6f}\n")
    return path


def test_too_few_points_fail_some_rows_while_the_others_complete(tmp_path, rng):
    a = np.r_[np.eye(3), -np.eye(3), [[0.6, 0, 0.8]]]       # 7 directions, both sides of each axis
    a = np.repeat(a, 2, axis=0) * (1 + rng.uniform(-0.002, 0.002, (14, 1)))
    path = _points_file(tmp_path / "few.csv", a * 1.02 + 0.01)   # alternate split: 7 train, 7 test
    r = run_cli("compare", path, "--json")
    assert r.returncode == 0, r.stderr
    rows = {x["method"]: x for x in json.loads(r.stdout)["rows"]}
    assert rows["device"]["status"] == "failed" and "bins did not fill" in rows["device"]["reason"]
    for n in ("lsq", "de", "merayo", "minvol"):
        assert rows[n]["status"] == "failed" and "needs at least 9 points, got 7" in rows[n]["reason"]
    for n in ("linauto", "linminvar", "campolo"):
        assert rows[n]["status"] == "calibrated" and rows[n]["error_after_mg"] < 5


def test_one_hemisphere_is_refused_before_any_method(tmp_path, rng):
    # as calibrate and diagnose refuse it (tests/test_degenerate.py): one line, exit 2
    a = rng.normal(size=(60, 3))
    a[:, 2] = np.abs(a[:, 2]) + 0.3
    path = _points_file(tmp_path / "hemi.csv", a / np.linalg.norm(a, axis=1, keepdims=True))
    r = run_cli("compare", path)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "one hemisphere" in r.stderr


@pytest.mark.parametrize("method", methods.ORDER)
def test_every_method_through_calibrate(tmp_path, method):
    pts = tmp_path / "pts.csv"
    r = run_cli("simulate", "paper", "--scenarios", 2, "--points", 200, "--seed", 3, "-o", pts)
    assert r.returncode == 0
    r = run_cli("calibrate", pts, "--by", "device", "--method", method, "--json")
    assert r.returncode == 0, r.stderr
    truth = json.loads(pts.with_suffix(".truth.json").read_text())["params"]
    for rec in map(json.loads, r.stdout.splitlines()):
        assert rec["method"] == method
        est, true = np.array(list(rec["params"].values())), np.array(list(truth[rec["device"]].values()))
        bound = 0.01 if methods.METHODS[method].n_params == 9 else 0.1   # eq. 1: no misalignment
        assert np.abs(est - true).max() < bound


def test_paper_gietzelt_command(tmp_path):
    r = run_cli("paper", "gietzelt", "--passes", 3, "--json", "--plots", tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out["table4"]) == {*methods.ORDER, "minvol*"}
    assert out["table4"]["linauto"]["paper_mean"][0] == 499.83
    assert set(out["unequal_axes"]) >= {"1:2:3"} and (tmp_path / "gietzelt_fig3.png").exists()


def test_paper_farago_table3_command(tmp_path):
    """One short recording (the ten-recording target is tests/test_slow_table3.py)."""
    r = run_cli("paper", "farago-table3", "--devices", 1, "--days", 1.5, "--seed", 301,
                "--keep", tmp_path)
    assert r.returncode == 0, r.stderr
    for label in ("Our method (device)", "Non-iterative (linauto)", "MATLAB fminunc (lsq)",
                  "LabVIEW global (de)"):
        assert label in r.stdout
    assert "3.06" in r.stdout and (tmp_path / "wrist00.csv").exists()
