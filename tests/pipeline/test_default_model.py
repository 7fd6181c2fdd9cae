"""`--model auto` (issue 50 part 1): a temperature offset beside the paper's model where the data
has temperature (the GGIR family's default), the paper's model where it has none.  On the real
wrist day in the suite (sleeppy's GENEActiv demo, its rest points: tests/data/real/sleeppy/) the
auto model's held-out error is at or below float 9-parameter least squares on every training
rest point on every split, where the paper's model alone is not (tests/pipeline/test_real_halves.py);
on simulated wear with no effect hidden it loses nothing against the paper's model, held back
(slow)."""
import json

import numpy as np
import pytest

from conftest import ROOT, run_main

POINTS = ROOT / "tests" / "data" / "real" / "sleeppy" / "demo_restpoints.csv"
SPLITS = ("blocks", "first-half", "second-half")


@pytest.mark.parametrize("split", SPLITS)
def test_auto_on_the_real_day_is_held_out_at_or_below_lsq_on_every_point(capsys, split):
    """compare's composed device row is the auto model's fit (the same settings) on the
    training part: below the paper's model by the device and below float lsq of the 9
    parameters on every training rest point, scored on the same held-out points (measured 28
    Nov 2026: blocks 2.12 / 2.62 / 2.49 mg, first half 2.78 / 4.43 / 4.42, second half
    2.78 / 3.03 / 4.91)."""
    code, out, err = run_main(capsys, ["compare", POINTS, "--methods", "device,lsq", "--train",
                                       "all", "--split", split, "--model", "base+temp_offset",
                                       "--json"])
    assert code == 0, err
    rows = {(r["method"], r.get("model", "base")): r for r in json.loads(out)["rows"]}
    auto = rows[("device", "base+temp_offset")]
    assert auto["status"] == "calibrated", auto
    assert auto["error_after_mg"] <= rows[("lsq", "base")]["error_after_mg"], rows
    assert auto["error_after_mg"] < rows[("device", "base")]["error_after_mg"], rows


def test_auto_chooses_by_the_data(capsys, tmp_path):
    """The real day (temperature 24.9-33.8 degC over its rest points): base+temp_offset, said
    so; a points file without temperature: the paper's model, the reason said; --by refuses
    auto in one line."""
    code, out, err = run_main(capsys, ["calibrate", POINTS, "--model", "auto", "--json"])
    rec = json.loads(out)
    assert code == 0 and rec["model"] == "base+temp_offset" and "temperature" in rec["auto"], rec
    assert rec["error_after_mg"] < 0.7 * rec["error_before_mg"]
    rng = np.random.default_rng(1)
    v = rng.normal(size=(400, 3))
    v = v / np.linalg.norm(v, axis=1, keepdims=True) * 1.02 + 0.01
    bare = tmp_path / "bare.csv"
    np.savetxt(bare, v, delimiter=",", header="x,y,z", comments="", fmt="%.6f")
    code, out, err = run_main(capsys, ["calibrate", bare, "--model", "auto"])
    assert code == 0 and "calibrated base by device" in out and "model auto: the paper's" in out
    assert "temperature column" in out, out
    code, out, err = run_main(capsys, ["calibrate", POINTS, "--model", "auto", "--by", "x"])
    assert code == 2 and err.count("\n") == 1 and "--model auto" in err, err


def test_auto_is_the_default_of_the_device_method(capsys):
    """calibrate without --model: the auto record, byte for byte; the float methods and
    --discover keep the paper's model by default (--model auto or base+EFFECT asks for more)."""
    runs = {}
    for name, opts in (("auto", ["--model", "auto"]), ("default", []), ("lsq", ["--method", "lsq"]),
                       ("base", ["--model", "base"])):
        code, out, err = run_main(capsys, ["calibrate", POINTS, *opts, "--json"])
        assert code == 0, err
        runs[name] = json.loads(out)
    assert runs["default"] == runs["auto"] and runs["default"]["model"] == "base+temp_offset"
    assert runs["lsq"]["model"] == "base" and "auto" not in runs["lsq"]
    assert runs["base"]["model"] == "base" and "auto" not in runs["base"]
    import accelcal
    assert accelcal.calibrate(str(POINTS)).to_dict() == runs["auto"]


@pytest.mark.slow
def test_auto_loses_nothing_on_clean_wear_and_finds_a_hidden_offset(tmp_path):
    """The held-back wrist benchmark's protocol (accelcal.studies.heldout: fitted on 3 days,
    scored on the next 2 days' strict still windows), 8 clean seeds.  Issue 50's "loses nothing
    where no effect is hidden (within 2 %)" is held to here as: the auto model's error over the
    paper's model's, mean and median of the 8 seeds, at most 1.02; and no seed above 1.08 (a
    single seed's ratio spreads about +-5 % either way: two fits of the same points, one with
    three more parameters, not a loss that shows in the mean).  Measured 28 Nov 2026 (twice, the
    same): 0.969, 0.956, 1.049, 0.927, 1.039, 1.053, 0.943, 0.999 (mean 0.992, median 0.984,
    worst 1.053).  With temp_offset hidden (seed 1) within 1.15x the true sensor model, where
    the paper's model is 5x it."""
    from accelcal.simulate import wearer
    from accelcal.studies import heldout

    def scores(seed, effects):
        whole, fit, test = (tmp_path / f"{seed}{x}.csv" for x in ("", ".fit", ".test"))
        truth = wearer.simulate_wrist(whole, heldout.FIT_DAYS + heldout.TEST_DAYS, heldout.RATE,
                                      seed, effect=effects)
        heldout.split(whole, fit, test)
        win = heldout.strict_windows(test)
        out = {"true": heldout.true_score_mg(truth, win)}
        for m in ("base", "base+temp_offset"):
            got, why = heldout.device_fit(fit, "wear", m)
            assert why is None, why
            out[m] = heldout.score_mg(*got, win)
        for f in (whole, fit, test):
            f.unlink()
        return out
    clean = [scores(s, []) for s in range(1, 9)]
    ratios = [c["base+temp_offset"] / c["base"] for c in clean]
    print("auto / base on clean seeds:", [round(r, 3) for r in ratios])
    assert np.mean(ratios) <= 1.02 and np.median(ratios) <= 1.02, ratios
    assert max(ratios) <= 1.08, ratios
    hidden = scores(1, ["temp_offset"])
    assert hidden["base+temp_offset"] <= 1.15 * hidden["true"] < hidden["base"] / 3, hidden


def test_a_recording_without_temperature_gets_the_paper_s_model_from_one_read(tmp_path):
    """A recording whose header has no temperature: the default is the paper's model, said so,
    with the same record as --model base (its header tells: the composed model is not tried)."""
    import accelcal
    import pyarrow.csv as pacsv
    from accelcal.simulate import wearer
    whole, bare = tmp_path / "w.csv", tmp_path / "bare.csv"
    wearer.simulate_wrist(whole, 1, 10, 3)
    pacsv.write_csv(pacsv.read_csv(whole).drop_columns(["temp"]), bare)
    rec, base = accelcal.calibrate(str(bare)), accelcal.calibrate(str(bare), model="base")
    assert rec["auto"] == ("the paper's model: base+temp_offset does not apply (no temperature "
                           "column)")
    assert {k: v for k, v in rec.items() if k != "auto"} == base.to_dict()
    assert rec.ok and rec["model"] == "base"
