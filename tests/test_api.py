"""The public API (accelcal.__all__) as a notebook user calls it: a simulated recording
calibrated, saved, applied, diagnosed and compared from the public names only, against the
simulator's truth and against what the commands print for the same file."""
import json

import numpy as np
import pytest

from conftest import run_cli


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    import accelcal
    d = tmp_path_factory.mktemp("api")
    truth = accelcal.simulate_wrist(d / "wrist.csv", 1, 10, seed=3)
    return d, d / "wrist.csv", truth


def test_calibrate_gives_the_truth_and_the_command_s_record(day):
    import accelcal
    d, rec_path, truth = day
    rec = accelcal.calibrate(str(rec_path))
    assert isinstance(rec, accelcal.CalibrationResult) and rec.ok
    got = np.array([rec["params"][k] for k in truth["params"]])
    assert np.abs(got - np.array(list(truth["params"].values()))).max() < 0.01
    assert rec["error_after_mg"] < rec["error_before_mg"] / 5
    cli = run_cli("calibrate", rec_path, "--json")
    assert cli.returncode == 0, cli.stderr
    assert json.loads(rec.to_json()) == json.loads(cli.stdout)
    # options as keywords: the paper profile, the CLI's --profile paper
    paper = accelcal.calibrate(str(rec_path), profile="paper", max_count=4)
    cli = run_cli("calibrate", rec_path, "--json", "--profile", "paper", "--max-count", 4)
    assert json.loads(paper.to_json()) == json.loads(cli.stdout)


def test_apply_writes_what_the_command_writes(day):
    import accelcal
    d, rec_path, _ = day
    rec = accelcal.calibrate(str(rec_path))
    rec.save(d / "params.json")
    with pytest.raises(accelcal.InputError):
        rec.save(d / "params.json")     # exists: replaced only with force
    out = accelcal.apply(d / "params.json", rec_path, d / "api.csv")
    assert isinstance(out, accelcal.ApplyResult)
    assert out["samples"] == 86400 * 10 and out["range_g"] == 2
    cli = run_cli("apply", d / "params.json", rec_path, "-o", d / "cli.csv")
    assert cli.returncode == 0 and cli.stderr.strip() == out.report().replace("api.csv", "cli.csv")
    assert (d / "api.csv").read_bytes() == (d / "cli.csv").read_bytes()


def test_diagnose_and_compare_give_the_command_s_findings(day):
    import accelcal
    d, rec_path, _ = day
    found = accelcal.diagnose(str(rec_path), "base")
    assert isinstance(found, accelcal.DiagnoseResult)
    cli = run_cli("diagnose", rec_path, "--json")
    assert json.loads(found.to_json()) == json.loads(cli.stdout)
    table = accelcal.compare(str(rec_path), methods=["device", "lsq"])
    assert isinstance(table, accelcal.CompareResult)
    cli = json.loads(run_cli("compare", rec_path, "--methods", "device,lsq", "--json").stdout)
    timeless = lambda rows: [{k: v for k, v in r.items() if k != "fit_ms"} for r in rows]  # noqa: E731
    assert timeless(table["rows"]) == timeless(cli["rows"])
    assert [r["status"] for r in table["rows"]] == ["calibrated", "calibrated"]


def test_a_model_spec_and_its_settings_from_the_public_names():
    import accelcal
    spec = accelcal.ModelSpec.parse("base+temp_offset")
    assert "temp_offset" in accelcal.CATALOGUE and spec.effects == ("temp_offset",)
    cfg = accelcal.Config.for_profile("paper")
    job = accelcal.Job.of(profile="paper")
    assert job.cfg == cfg and job.engine == "vector"


def test_a_result_reads_as_lmfit_s_model_result(day):
    import accelcal
    from importlib import metadata
    d, rec_path, truth = day
    rec = accelcal.calibrate(str(rec_path))
    assert rec.status == rec["status"] == "calibrated" and rec.error_after_mg == rec["error_after_mg"]
    p = rec.params          # names, units, the device's Q24 integers beside the values
    # the default (auto) on a wrist with temperature: the paper's nine and a temperature offset
    assert rec.model == "base+temp_offset" and "temperature" in rec.auto
    assert list(p) == [*truth["params"], "cx", "cy", "cz"] == list(rec["params"])
    assert [p[k].unit for k in ("kxx", "kxy", "ox", "cx")] == ["1", "1", "g", "g/degC"]
    for k, par in p.items():
        assert par.value == rec["params"][k] and par.int == rec["params_int"][k]
        per = 16 if k.startswith("c") else 1   # temp_offset: Q24 per 16 degC (effects.py)
        assert abs(par.int / 2 ** 24 / per - par.value) <= 2 ** -24
    assert p.valuesdict() == rec["params"]
    assert rec.to_dict() == json.loads(rec.to_json()) and type(rec.to_dict()) is dict
    assert repr(rec).startswith(f"<CalibrationResult {rec_path} calibrated") and len(repr(rec)) < 200
    text = rec.summary()
    assert text.startswith(rec.report()) and f"{p['ox'].int:>12}" in text and "Q24 int" in text
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        rec.nope
    assert accelcal.__version__ == metadata.version("accelcal")
    units = accelcal.Params.of({"cx": 1e-4}, {"cx": 5}, "base+temp_offset")["cx"]
    assert units.unit == accelcal.CATALOGUE["temp_offset"].unit
