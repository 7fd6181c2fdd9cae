"""Held out on a real wrist recording (issue 30): the rest points of 21 hours of a GENEActiv
wrist watch (sleeppy's demo.bin, tests/data/real/sleeppy/), split by time, in halves and in
compare's 2-hour blocks.  Both halves cover the sphere; the device's fit reaches the optimum of
its own points (float lsq on the same points); and the issue's criterion, the default
calibration's held-out error at or below float lsq on every training rest point, is checked on
each split: met by the default (auto, issue 50: base+temp_offset on this day) on all three; the
paper's model by the device met it only trained on the second half (above by 0.013 and 0.14 mg
on the other two); and against scikit-digital-health and actipy, fitted on the raw file's
training samples by `python -m accelcal.studies.peers_real` (make bench; tests/data/real/peers.json)
and scored here on the same held-out points, the default at or below both on every split."""
import numpy as np
import pytest

from accelcal import methods
from accelcal.bridge import runtime
from accelcal.methods import coverage_reason
from accelcal.pipeline import compare
from accelcal.pipeline.restpoints import rest_points, split, usable
from conftest import ROOT

POINTS = ROOT / "tests" / "data" / "real" / "sleeppy" / "demo_restpoints.csv"
CFG = runtime.Config.for_profile("wear", False)


@pytest.fixture(scope="module")
def points():
    return usable(rest_points(str(POINTS)))


RULES = {"blocks": "blocks", "first": "first-half", "second": "second-half"}


def halves(p, which):
    """(training, held out) by compare's split (restpoints.split): the rest points cut at the
    middle of their time span, or the 2-hour blocks."""
    train, test, _ = split(p, RULES[which])
    return train, test


@pytest.fixture(scope="module")
def fits(points):
    """Per split: held-out error (mg) of the device's fit, of lsq on the device's points and of
    lsq on every training rest point."""
    out = {}
    for which in ("blocks", "first", "second"):
        train, test = halves(points, which)
        device, selected, why = compare.device_fit(train.v, CFG)
        assert why is None, why
        out[which] = {name: methods.calibration_error_mg(params, test.v) for name, params in (
            ("device", device), ("lsq_selected", methods.METHODS["lsq"](np.asarray(selected))),
            ("lsq_all", methods.METHODS["lsq"](train.v)))}
        out[which]["before"] = methods.calibration_error_mg(None, test.v)
    return out


def test_a_day_of_wrist_wear_long_enough_that_both_time_halves_cover(points):
    assert (points.t.max() - points.t.min()) / 3600 > 20
    for which in ("first", "second"):
        train, test = halves(points, which)
        assert len(train) and len(test)
        assert train.t.max() < test.t.min() or test.t.max() < train.t.min()   # by time
        early, late = (train, test) if which == "first" else (test, train)
        mid = points.t.min() + (points.t.max() - points.t.min()) / 2
        assert early.t.max() < mid <= late.t.min() and len(early) + len(late) == len(points)
        assert coverage_reason(train.v, 9, "train") is None
        assert coverage_reason(test.v, 9, "held out") is None
    assert split(points).how == "2-hour blocks: even train, odd held out"   # the standing split


@pytest.mark.parametrize("which", ["blocks", "first", "second"])
def test_the_device_fit_reaches_the_optimum_of_its_points_on_real_wear(fits, which):
    f = fits[which]
    assert f["device"] < f["before"] * 0.7
    assert abs(f["device"] - f["lsq_selected"]) <= 0.01 * f["lsq_selected"]


@pytest.fixture(scope="module")
def default_fits(points, tmp_path_factory):
    """Per split: the default calibration (accelcal.calibrate with no model: auto, issue 50) of
    the training rest points written as a points file, its model, and its held-out error (mg)
    scored with the model's own correction on the held-out points."""
    import accelcal
    from accelcal.model.effects import ModelSpec
    out = {}
    for which in ("blocks", "first", "second"):
        train, test = halves(points, which)
        path = tmp_path_factory.mktemp("halves") / f"{which}.csv"
        np.savetxt(path, np.column_stack([train.v, train.temp, train.t]), delimiter=",",
                   header="x,y,z,temp,t", comments="", fmt="%.9g")
        rec = accelcal.calibrate(str(path))
        assert rec.ok, rec
        spec = ModelSpec.parse(rec["model"])
        a = spec.correct(np.array(list(rec["params"].values())), test.v, test.temp, test.t,
                         rec["reference"], test.cols)
        out[which] = (rec["model"], float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)) * 1e3))
    return out


@pytest.mark.parametrize("which", ["blocks", "first", "second"])
def test_the_default_calibration_held_out_at_or_below_lsq_on_every_training_point(
        fits, default_fits, which):
    """Issue 50's test: the default (auto: base+temp_offset on this day, 24.9-33.8 degC) at or
    below float 9-parameter least squares on every training rest point, on every split, where
    the paper's model by the device was above it on two (measured 26 Nov 2026: blocks 2.62
    against 2.49 mg, first half 4.434 against 4.421)."""
    model, err = default_fits[which]
    assert model == "base+temp_offset"
    assert err <= fits[which]["lsq_all"], (err, fits[which])
    assert err < fits[which]["device"], (err, fits[which])   # and below the paper's model


# The peers on this day, measured here: scikit-digital-health and actipy (.venv-bench, which CI's
# venv does not have) fitted on each split's training samples of the raw demo.bin by
# `python -m accelcal.studies.peers_real` (make bench), their maps recorded in peers.json with
# their versions.  Scored here on the same held-out rest points as the default.
PEERS = ROOT / "tests" / "data" / "real" / "peers.json"
DEMO_SHA256 = "2cd13acb192b246a09844a764bad2441e6814411f242e684d8904a208a76d48f"


def peers_of(name):
    import json
    data = json.loads(PEERS.read_text())
    return data, next(f for f in data["files"] if f["file"] == name)


def peer_error_mg(fit, p):
    """A peer's map (per axis c0 + c1 v + c2 T + c3 v T, read back from its calibrated samples)
    on rest points p: mean | |a| - 1 g | in mg."""
    c = np.asarray(fit["map"])
    v, T = p.v, p.temp[:, None]
    a = c[:, 0] + c[:, 1] * v + c[:, 2] * T + c[:, 3] * v * T
    return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)) * 1e3)


def test_the_peers_were_fitted_on_the_raw_file_of_these_points_split_as_here(points):
    """peers.json holds the raw demo.bin's peers (its sha256 as the README gives it), with the
    peers' versions, and each split cut the rest points as restpoints.split cuts the shipped
    ones (the same counts of training and held-out points); the read-back maps reproduce the
    peers' calibrated samples (residual under 1e-9 g), so the map is the peer's own."""
    data, demo = peers_of("demo.bin")
    assert demo["sha256"] == DEMO_SHA256
    assert set(data["versions"]) >= {"scikit-digital-health", "actipy"}
    assert demo["splits"].keys() == set(RULES.values())
    for which, rule in RULES.items():
        s = demo["splits"][rule]
        train, test = halves(points, which)
        assert (s["points"], s["train_points"], s["held_out_points"]) == (
            len(points), len(train), len(test))
        for tool in ("skdh", "skdh_lifted", "actipy"):
            assert s[tool]["fitted"] == ("map" in s[tool])
            assert not s[tool]["fitted"] or s[tool]["map_residual_g"] < 1e-9


def test_the_peers_data_is_for_the_real_files_in_the_suite():
    """Every file of peers.json but demo.bin is a file in tests/data/real/ with the same sha256
    (so the data goes stale loudly when a file changes), and a peer that declined a file has its
    reason and no map: no figure."""
    import hashlib
    data, _ = peers_of("demo.bin")
    shipped = {f.name: f for f in (ROOT / "tests" / "data" / "real").rglob("*") if f.is_file()}
    for rec in data["files"]:
        if rec["file"] != "demo.bin":
            assert hashlib.sha256(shipped[rec["file"]].read_bytes()).hexdigest() == rec["sha256"]
        for s in [*rec["splits"].values(), rec["whole_file"]]:
            for tool in ("skdh", "skdh_lifted", "actipy"):
                if tool in s:
                    assert s[tool]["fitted"] or (s[tool]["reason"] and "map" not in s[tool])


@pytest.mark.parametrize("which", ["blocks", "first", "second"])
def test_the_default_held_out_at_or_below_both_peers(fits, default_fits, points, which):
    """Issue 50's test on the real files in the suite: the default's held-out error at or below
    scikit-digital-health's and actipy's, each fitted on the same training part of the raw file
    and scored on the same held-out points.  Measured 28 Nov 2026 (skdh 0.17.18, actipy 3.8.3):
    skdh declines every split with its defaults (under its 12-hour floor: 10.4-10.9 h; no
    figure); with that floor lifted it scores 2.29, 4.44 and 5.76 mg (blocks, first, second)
    against the default's 2.12, 2.78 and 2.78; actipy finds its error under its 10 mg tolerance
    and leaves the samples as they are (4.79, 7.43, 4.72 mg: the uncalibrated figures)."""
    _, demo = peers_of("demo.bin")
    s = demo["splits"][RULES[which]]
    test = halves(points, which)[1]
    default = default_fits[which][1]
    assert not s["skdh"]["fitted"] and "Less than 12 hours" in s["skdh"]["reason"]
    scored = {tool: peer_error_mg(s[tool], test) for tool in ("skdh_lifted", "actipy")}
    assert "left as they are" in s["actipy"]["left_as_is"]
    assert scored["actipy"] == pytest.approx(fits[which]["before"], rel=1e-6)   # identity
    assert default <= min(scored.values()), (default, scored)
    assert default <= fits[which]["lsq_all"]


@pytest.mark.parametrize("which", ["first", "second"])
def test_compare_split_by_time_halves_gives_these_figures(fits, capsys, which):
    """`accelcal compare --split first-half|second-half --json` (main(argv)) on the points file:
    the same held-out errors as computed here, and the split said in its record."""
    import json
    from conftest import run_main
    got = {}
    for train in ("all", "selected"):
        code, out, err = run_main(capsys, ["compare", POINTS, "--split", RULES[which], "--methods",
                                           "device,lsq", "--train", train, "--json"])
        assert code == 0, err
        rec = json.loads(out)
        assert f"the {which} half trains" in rec["split"], rec["split"]
        rows = {r["method"]: r["error_after_mg"] for r in rec["rows"]}
        got["device"], got[f"lsq_{train}"] = rows["device"], rows["lsq"]
        got["before"] = rec["rows"][0]["error_before_mg"]
    assert got == pytest.approx(fits[which], rel=1e-9)


def test_diagnose_on_the_real_day_says_what_its_points_cannot_tell():
    """diagnose on the real day's rest points: no noise floor claimed (a points file has no
    samples: not 0 mg), the best candidate's 5 held-out blocks said to be too few, and the error
    put against the wrist floor as a ratio, not called explained (2.49 mg, 2.1x the 1.18 mg
    floor, measured 26 Nov 2026)."""
    from accelcal.pipeline.diagnose import diagnose
    out = diagnose(str(POINTS))
    assert out["missing_effect"] is None and out["noise_floor_measured"] is False
    assert "noise floor not measured" in out.report()
    text = out["explanation"]
    ratio = out["heldout_error_mg"] / out["wrist_floor_mg"]
    assert ratio > 1.25 and f"is {ratio:.1f}x a wrist floor" in text
    assert "a longer recording (more 2-hour blocks) would tell" in text
    assert "explains the data" not in text and "noise floor of 0.00" not in text
