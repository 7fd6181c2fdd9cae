"""Model discovery on recordings with hidden effects (seeds not used to choose the naming rule's
thresholds): diagnose names the effect, adding it brings the held-out error within 1.5x of what
the true sensor model achieves on the same points; on clean recordings it names nothing; two
effects are found one after the other.  Bad model specs and unsupported data: exit 2, one line."""
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from accelcal.bridge.runtime import Config
from accelcal.pipeline.diagnose import chosen, heldout_error_of
from accelcal.model.effects import CATALOGUE
from accelcal.pipeline.job import calibrate as calibrate_api
from acal.core.fixed import PARAM_NAMES
from conftest import ROOT, run_cli, run_main, simulate_wrists

DAYS, RATE = 3, 10
EFFECTS = ("temp_offset", "temp_scale", "drift", "nonlinear")


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("discovery")
    # "two" on seed 35.  The naming rule is held over seeds below (test_the_naming_rule_over_
    # seeds*), not on this one: on seeds 30-41 diagnose names one of the two hidden effects on 11
    # of 12 (drift better in 14-18 of 18 held-out blocks; on seed 33, since the Q10 format's
    # dither, in 12, one short of the rule's 70 %) and nothing on 12 of 12 clean seeds, the
    # board's discovery names both on 12 of 12 (drift in 14-18 blocks) and nothing on clean
    # data on 12 of 12 (measured 28 Nov 2026).  Seed 33 also fails the paper profile's composed
    # fit below (2.23 mg against its base's 1.76).
    cases = {"clean31": (31, ()), "clean32": (32, ()), "two": (35, ("temp_offset", "drift"))}
    cases.update({e: (31, (e,)) for e in EFFECTS})
    return simulate_wrists(d, cases, DAYS, RATE)


def diagnose(path, model="base", *extra):
    r = run_cli("diagnose", path, "--model", model, "--json", *extra)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def true_error(path):
    truth = json.loads(path.with_suffix(".truth.json").read_text())
    theta = [truth["params"][n] for n in PARAM_NAMES]
    model = "base"
    for e in truth["effects"]:
        theta += list(e["params"].values())
        model += "+" + e["effect"]
        ref = e["reference"]
    ref = truth["effects"][0]["reference"] if truth["effects"] else {"T0": 0.0, "t0": 0.0}
    return heldout_error_of(str(path), model, theta, ref)


@pytest.mark.parametrize("effect", EFFECTS)
def test_names_the_hidden_effect_and_adding_it_reaches_the_true_model(recordings, effect, tmp_path):
    path = recordings[effect]
    hist = tmp_path / "history.jsonl"
    first = diagnose(path, "base", "--history", hist, "--plots", tmp_path / "plots")
    assert first["missing_effect"] == effect, first["explanation"]
    assert {"model", "heldout_error_mg", "noise_floor_mg", "missing_effect", "candidates",
            "explanation"} <= set(first)
    assert (tmp_path / "plots" / "residuals.png").stat().st_size > 10000
    assert effect in first["explanation"] and "Next: accelcal calibrate --model base+" in first["explanation"]
    for c in first["candidates"]:   # the block count beside the share
        if c["heldout_error_mg"] is not None:
            assert round(100 * c["blocks_improved"] / c["blocks"], 6) == round(c["blocks_improved_pct"], 6)
    named = next(c for c in first["candidates"] if c["effect"] == effect)
    assert named["blocks"] >= 12 and named["evidence"] == "clear"   # days of 2-hour blocks
    # a curve's straight part named alone: a second step is due, the curve judged on top of it
    if effect == "temp_offset":
        assert first["what_remains"]["second_step"] == "temp_offset2"
        assert first["what_remains"]["model"] == "base+temp_offset"
        assert "A second step is due" in first["explanation"]
    else:
        assert first["what_remains"] is None and "second step" not in first["explanation"]
    second = diagnose(path, f"base+{effect}", "--history", hist)
    if effect == "temp_offset":   # the curve judged again as the device fits it: not named
        curve = next(c for c in second["candidates"] if c["effect"] == "temp_offset2")
        assert not curve["device_folds"]["named"], curve["device_folds"]
    truth = true_error(path)
    assert second["heldout_error_mg"] <= 1.5 * truth, (second["heldout_error_mg"], truth)
    assert first["heldout_error_mg"] > second["heldout_error_mg"]
    assert second["missing_effect"] is None
    r = run_cli("report", hist, "--plot", tmp_path / "steps.png")
    assert r.returncode == 0 and f"base+{effect}" in r.stdout and (tmp_path / "steps.png").exists()


@pytest.mark.parametrize("name", ["clean31", "clean32"])
def test_names_nothing_on_clean_data(recordings, name):
    out = diagnose(recordings[name])
    assert out["missing_effect"] is None, out["explanation"]
    assert out["heldout_error_mg"] <= 1.5 * true_error(recordings[name])
    assert "No catalogue effect explains" in out["explanation"]


def test_two_effects_found_one_after_the_other(recordings):
    path = recordings["two"]
    first = diagnose(path)
    named = first["missing_effect"]
    assert named in ("temp_offset", "drift"), first["explanation"]
    second = diagnose(path, f"base+{named}")
    other = ({"temp_offset", "drift"} - {named}).pop()
    assert second["missing_effect"] == other, second["explanation"]
    third = diagnose(path, f"base+{named}+{other}")
    assert third["missing_effect"] is None
    assert third["heldout_error_mg"] <= 1.5 * true_error(path)


def test_calibrate_composed_model_recovers_the_effect(recordings):
    path = recordings["temp_offset"]
    # the paper profile's rest test keeps the arm hanging (x along gravity, the one posture that
    # shows cx), which the wear profile's all-axis test mostly leaves out as sway
    r = run_cli("calibrate", path, "--model", "base+temp_offset", "--method", "lsq", "--points", "all",
                "--profile", "paper", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    truth = json.loads(path.with_suffix(".truth.json").read_text())["effects"][0]["params"]
    fitted = np.array([out["params"][k] for k in ("cx", "cy", "cz")])
    assert np.abs(fitted - np.array(list(truth.values()))).max() < 0.0002  # 0.2 mg/degC
    assert out["params_int"]["cx"] == round(out["params"]["cx"] * 16 * 2 ** 24)  # per 16 degC, Q24
    assert out["params_int"]["kxx"] == round(out["params"]["kxx"] * 2 ** 24)


def test_bad_model_specs_and_data(recordings, tmp_path):
    path = recordings["clean31"]
    cases = [
        (("diagnose", path, "--model", "base+warp"), "unknown effect 'warp'"),
        (("calibrate", path, "--model", "base+drift", "--method", "linauto"),
         "composed models are fitted by --method device"),
    ]
    no_temp = tmp_path / "no_temp.csv"
    rec = np.loadtxt(path, delimiter=",", skiprows=1, max_rows=200000)
    np.savetxt(no_temp, rec[:, :4], delimiter=",", header="t,x,y,z", comments="", fmt="%.4f")
    cases.append((("diagnose", no_temp, "--model", "base+temp_scale"), "temp_scale needs a temperature column"))
    flat = tmp_path / "flat_temp.csv"
    rec[:, 4] = 30.0 + 0.1 * np.sin(rec[:, 0])
    np.savetxt(flat, rec, delimiter=",", header="t,x,y,z,temp", comments="", fmt="%.4f")
    cases.append((("diagnose", flat, "--model", "base+temp_offset"),
                  "temp_offset needs >= 3 degC of temperature spread across rest points; "))
    cases.append((("diagnose", flat, "--model", "base+drift"), "drift needs rest points spanning >= 12 h"))
    # The device's own composed fit checks the same before it runs.
    cases.append((("calibrate", no_temp, "--model", "base+temp_scale"), "temp_scale needs a temperature column"))
    cases.append((("calibrate", flat, "--model", "base+temp_offset"), "needs >= 3 degC of temperature spread"))
    cases.append((("calibrate", no_temp, "--model", "base+drift"), "drift needs rest points spanning >= 12 h"))
    for args, msg in cases:
        r = run_cli(*args)
        assert r.returncode == 2 and r.stderr.count("\n") == 1, (args, r.stderr)
        assert msg in r.stderr, (msg, r.stderr)


def calibrate(path, model, *extra):
    r = run_cli("calibrate", path, "--model", model, "--json", *extra)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


# The paper profile's 200-iteration composed fits take 15-35 s each in CPython: two of them (one
# effect and two) stay in the default suite, the rest run with `-m slow` (CI's time limit).
PAPER_DEFAULT = ("drift", "temp_offset+drift")
FITS = [pytest.param(e, p, marks=() if p == "wear" or e in PAPER_DEFAULT else pytest.mark.slow)
        for e in EFFECTS + ("temp_offset+drift",) for p in ("paper", "wear")]


@pytest.mark.parametrize("effect, profile", FITS)
def test_device_fits_the_composed_model_in_integers(recordings, effect, profile):
    """The device pipeline itself (bins spread in temperature and time, integer optimiser) fits
    base+EFFECT: better than its own base fit, and in the range of the float fit on all points
    (the paper profile sees 36 points, lsq all of them: docs/model-discovery.md "Bins for composed models"; the
    wear profile up to 126, fitted to their optimum: within 1.5x of lsq on all points)."""
    path = recordings["two" if "+" in effect else effect]
    base = calibrate(path, "base", "--profile", profile)
    dev = calibrate(path, f"base+{effect}", "--profile", profile)
    lsq = calibrate(path, f"base+{effect}", "--method", "lsq", "--points", "all", "--profile", profile)
    assert lsq["points_from"] == "all" and lsq["points"] > 10 * dev["points"]
    assert dev["status"] == "calibrated" and dev["profile"] == profile
    if profile == "paper":
        assert dev["points"] == 36 and dev["iterations"] == 200
    assert list(dev["params_int"]) == list(lsq["params_int"])  # same names, same order
    assert dev["error_after_mg"] < 0.8 * base["error_after_mg"], (dev, base)
    assert dev["error_after_mg"] < (3.5 if profile == "paper" else 1.5) * lsq["error_after_mg"], (dev, lsq)


def test_composed_device_fit_is_bit_identical_under_micropython(recordings, tmp_path):
    """The composed pipeline (bins spread in temperature and time, the fit) on every 8th rest
    point of the recording, as a points file with t and temp: the same record under MicroPython
    (every rest point through the MicroPython bins takes half a minute; the fraction keeps the
    spread and the coverage)."""
    from accelcal.pipeline.restpoints import rest_points
    p = rest_points(str(recordings["temp_offset"]))
    pts = tmp_path / "points.csv"
    np.savetxt(pts, np.column_stack([p.v, p.t, p.temp])[::8], delimiter=",", fmt="%.6f",
               header="x,y,z,t,temp", comments="")
    cp = calibrate(pts, "base+temp_offset")
    mp = calibrate(pts, "base+temp_offset", "--runtime", "micropython")
    assert cp.pop("runtime") == "cpython" and mp.pop("runtime") == "micropython"
    assert cp == mp and cp["status"] == "calibrated" and cp["points"] >= 36


def test_applying_the_composed_calibration_leaves_nothing_to_name(recordings, tmp_path):
    """apply uses the device's per-sample Calibration with the effect: on the calibrated file
    diagnose finds no effect left (the base-calibrated file still shows temp_offset)."""
    path = recordings["temp_offset"]
    saved = tmp_path / "p.json"
    assert run_cli("calibrate", path, "--model", "base+temp_offset", "--save", saved).returncode == 0
    out = tmp_path / "calibrated.csv"
    r = run_cli("apply", saved, path, "-o", out)
    assert r.returncode == 0, r.stderr
    after = diagnose(out)
    assert after["missing_effect"] is None, after["candidates"]
    notemp = tmp_path / "notemp.csv"
    notemp.write_text("t,x,y,z\n0,0,0,1\n0.1,0,0,1\n")
    r = run_cli("apply", saved, notemp, "-o", tmp_path / "x.csv")
    assert r.returncode == 2 and "needs a temperature column" in r.stderr


def test_few_blocks_are_weak_evidence_and_explanations_fit_the_device():
    """3 of 3 held-out blocks better happens one time in eight by chance: weak; 6 of 6 (1 in 64)
    and 12 of 14 (1 in 150) are clear.  An ActiGraph file's explanation quotes no LIS3DH
    figure; a recording CSV (accelcal's LIS3DH) does."""
    from accelcal.files.recordings import sensor_of
    from accelcal.model.effects import CATALOGUE
    from accelcal.pipeline.diagnose import block_evidence
    assert [block_evidence(*c) for c in ((3, 3), (4, 5), (6, 6), (12, 14))] == \
        ["weak", "weak", "clear", "clear"]
    real = ROOT / "tests" / "data" / "real"
    gt3x = sensor_of(real / "ggir" / "actigraph_testfile.gt3x")
    assert gt3x == "ActiGraph GT3X" and sensor_of(real / "ax3_sample.cwa") == "Axivity CWA"
    for name in ("nonlinear", "temp_offset", "temp_scale"):
        assert "LIS3DH" not in CATALOGUE[name].explain(gt3x)
        assert "Typical for the LIS3DH" in CATALOGUE[name].explain("LIS3DH")


def test_too_few_blocks_to_tell_is_said_by_the_sign_test():
    """A split whose least share the rule names (70 %) would still be weak evidence says a
    longer recording would tell: 5 blocks (4 of 5: 6 in 32 by chance) and 14 (10 of 14) do, 16
    (12 of 16: 1 in 26) and 18 do not."""
    from accelcal.pipeline.explain import few_blocks
    assert [bool(few_blocks(b)) for b in (3, 5, 14, 16, 18, 36)] == [True, True, True, False, False,
                                                                     False]
    assert "4 of 5 better would be weak evidence" in few_blocks(5)


DISCOVER = Config.for_profile("wear", discover=True)


def test_the_board_names_what_diagnose_names(recordings, capsys):
    """The board's own discovery (`calibrate --discover`, device/acal/discover/search.py) on the
    recordings diagnose names temp_offset on and nothing on (the tests above): the same, the
    effect better in >= 70 % of >= 12 held-out blocks; `--json` carries it; bad options are one
    line, exit 2, before the file is read."""
    code, out, err = run_main(capsys, ["calibrate", recordings["temp_offset"], "--discover",
                                       "--json"])
    d = json.loads(out)["discovery"]
    assert code == 0 and d["effect"] == "temp_offset" and d["model"] == "base+temp_offset", d
    assert d["heldout_error_after_mg"] < 0.9 * d["heldout_error_before_mg"]
    assert 10 * d["blocks_better"] >= 7 * d["blocks"] and d["blocks"] >= 12, d
    assert set(d["params"]) >= {"cx", "cy", "cz"} and len(d["candidates"]) == 8
    clean = calibrate_api(str(recordings["clean31"]), cfg=DISCOVER)["discovery"]
    assert clean["effect"] is None and clean["closest"] is not None, clean
    for bad in (["--model", "base+drift"], ["--method", "lsq"], ["--profile", "paper"]):
        code, out, err = run_main(capsys, ["calibrate", recordings["clean31"], "--discover", *bad])
        assert code == 2 and len(err.strip().splitlines()) == 1 and "--discover" in err, err


def test_the_board_discovers_two_hidden_effects_in_two_rounds(recordings, capsys):
    """After an adoption the board's discovery runs again from the adopted model (`rounds`,
    up to the model's limit of two effects): on the recording with temp_offset and drift
    hidden it names both (against the simulation's truth), the second round lowering the
    held-out error again; with one hidden effect or none the second round adopts nothing (or
    none runs)."""
    code, out, err = run_main(capsys, ["calibrate", recordings["two"], "--discover", "--json"])
    d = json.loads(out)["discovery"]
    truth = json.loads(recordings["two"].with_suffix(".truth.json").read_text())
    hidden = {e["effect"] for e in truth["effects"]}
    assert code == 0 and len(d["rounds"]) == 1 and set(d["effects"]) == hidden, d
    second = d["rounds"][0]
    assert d["effect"] in hidden and second["effect"] == "+".join(d["effects"]), d
    assert second["model"] == "base+" + second["effect"] and set(second["params"]) >= {"cx", "dx"}
    assert second["heldout_before"] == d["heldout_after"]     # from the adopted model
    assert second["heldout_error_after_mg"] < 0.9 * second["heldout_error_before_mg"]
    assert len(second["candidates"]) < len(d["candidates"])  # no curve pair, not the first again
    one = calibrate_api(str(recordings["temp_offset"]), cfg=DISCOVER)["discovery"]
    assert one["effects"] == ["temp_offset"] and len(one["rounds"]) == 1, one
    assert one["rounds"][0]["effect"] is None and one["rounds"][0]["model"] == "base+temp_offset"
    clean = calibrate_api(str(recordings["clean31"]), cfg=DISCOVER)["discovery"]
    assert clean["effects"] == [] and clean["rounds"] == [], clean
    code, out, err = run_main(capsys, ["calibrate", recordings["two"], "--discover"])
    assert "discovery, round 2: the board adopts" in out, out


def test_what_the_discovery_finds_is_what_is_saved_and_applied(recordings, capsys, tmp_path):
    """`calibrate --discover --save p.json` on a recording with drift hidden: the record, the
    report and p.json carry the model the discovery ended with (base+drift, model_from
    discovery), and `apply p.json` gives every sample the discovered model's error against the
    simulation's true sensor model, well under the base fit's (kept in the record as base_fit)."""
    import pyarrow.csv as pacsv
    from conftest import true_corrected
    path = recordings["drift"]
    p = tmp_path / "p.json"
    code, out, err = run_main(capsys, ["calibrate", path, "--discover", "--save", p])
    assert code == 0 and "calibrated base+drift by device" in out, out + err
    assert "the model the discovery ended with" in out, out
    saved = json.loads(p.read_text())
    assert saved["model"] == "base+drift" and saved["model_from"] == "discovery", saved
    assert saved["discovery"]["model"] == "base+drift"
    assert saved["params_int"] == saved["discovery"]["params_int"]
    assert {"T0", "t0"} <= set(saved["reference"])
    assert saved["error_after_mg"] < saved["base_fit"]["error_after_mg"]
    base = tmp_path / "base.json"
    base.write_text(json.dumps({"model": "base", "params_int": saved["base_fit"]["params_int"]}))
    t = pacsv.read_csv(path)
    raw = np.column_stack([t[c].to_numpy() for c in ("t", "x", "y", "z", "temp")])
    truth = true_corrected(path, raw[:, 1:4], raw[:, 4], raw[:, 0], {})
    err_mg = {}
    for name, params in (("discovered", p), ("base", base)):
        o = tmp_path / f"{name}.csv"
        code, out, err = run_main(capsys, ["apply", params, path, "-o", o])
        assert code == 0, err
        a = pacsv.read_csv(o)
        a = np.column_stack([a[c].to_numpy() for c in ("x", "y", "z")])
        err_mg[name] = float(np.mean(np.linalg.norm(a - truth, axis=1)) * 1e3)
    # measured: 0.58 mg discovered, 2.79 mg base (mean |a - a_true| per sample, seed 31)
    assert err_mg["discovered"] < 1.0 and err_mg["base"] > 3 * err_mg["discovered"], err_mg


SWEEP_FAST = (33, 34)     # 33: the seed diagnose falls short on; 34: the board's closest (14 of 18)
SWEEP_SLOW = tuple(range(30, 42))


def _sweep(tmp_path_factory, seeds):
    d = tmp_path_factory.mktemp("sweep")
    cases = {f"two{s}": (s, ("temp_offset", "drift")) for s in seeds}
    cases.update({f"clean{s}": (s, ()) for s in seeds})
    return simulate_wrists(d, cases, DAYS, RATE)


def test_the_naming_rule_over_seeds_on_the_board(tmp_path_factory):
    """The board's discovery (its rule: better in >= 70 % of >= 12 held-out blocks) on two
    seeds with temp_offset and drift hidden, and on the same seeds clean: both effects named on
    every one (on seeds 30-41 drift is better in 14-18 of 18 blocks, the rule needs 13), nothing
    named on any clean one.  The same rule on twelve seeds, and diagnose's: the slow test below."""
    rec = _sweep(tmp_path_factory, SWEEP_FAST)
    for s in SWEEP_FAST:
        d = calibrate_api(str(rec[f"two{s}"]), cfg=DISCOVER)["discovery"]
        assert sorted(d["effects"]) == ["drift", "temp_offset"], (s, d["effects"])
        clean = calibrate_api(str(rec[f"clean{s}"]), cfg=DISCOVER)["discovery"]
        assert clean["effects"] == [], (s, clean["effects"])


@pytest.mark.slow
def test_the_naming_rule_over_seeds(tmp_path_factory):
    """Twelve seeds (30-41; minutes: this and the composed points' sweep took 15 together on two
    shared cores): diagnose names one of the two hidden effects on >= 10
    (measured 11: on seed 33 drift is better in 12 of 18 blocks, one short) and nothing on any
    clean seed; the board's discovery names both on >= 11 (measured 12) and nothing clean."""
    rec = _sweep(tmp_path_factory, SWEEP_SLOW)
    named = sum(diagnose(rec[f"two{s}"])["missing_effect"] in ("temp_offset", "drift")
                for s in SWEEP_SLOW)
    assert named >= 10, named
    for s in SWEEP_SLOW:
        assert diagnose(rec[f"clean{s}"])["missing_effect"] is None, s
    both = sum(sorted(calibrate_api(str(rec[f"two{s}"]), cfg=DISCOVER)["discovery"]["effects"])
               == ["drift", "temp_offset"] for s in SWEEP_SLOW)
    assert both >= 11, both
    for s in SWEEP_SLOW:
        assert calibrate_api(str(rec[f"clean{s}"]), cfg=DISCOVER)["discovery"]["effects"] == [], s


def test_the_single_candidate_is_chosen_as_the_board_chooses():
    """diagnose chooses among its single candidates by the device's rule.best (acal/discover/
    rule.py), on held-out errors in mg: the lowest, untestable ones skipped, a change point giving
    way to the best effect without one within 1.5x of it - a change point the device cannot run
    (a gain step: no device kind) as well as the step."""
    gain_step = dataclasses.replace(CATALOGUE["step"], name="gain_step", form="gain")
    assert gain_step.kind is None and gain_step.change_point
    pool = {e.name: e for e in (CATALOGUE["temp_offset"], CATALOGUE["drift"], CATALOGUE["step"],
                                gain_step)}

    def c(name, err):
        return {"effect": name, "heldout_error_mg": err}

    assert chosen(pool, [c("temp_offset", 0.8), c("drift", 0.6)])["effect"] == "drift"
    assert chosen(pool, [c("temp_offset", None), c("drift", 0.6)])["effect"] == "drift"
    assert chosen(pool, [c("temp_offset", None), c("drift", None)]) is None
    assert chosen(pool, [c("drift", 0.6), c("temp_offset", 0.6)])["effect"] == "drift"  # a tie: the first
    for step in ("step", "gain_step"):
        assert chosen(pool, [c("temp_offset", 1.5), c(step, 1.0)])["effect"] == "temp_offset"
        assert chosen(pool, [c("temp_offset", 1.51), c(step, 1.0)])["effect"] == step
        assert chosen(pool, [c(step, 1.0), c("drift", None)])["effect"] == step   # none plain
