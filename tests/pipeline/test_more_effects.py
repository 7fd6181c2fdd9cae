"""Effects beyond the first four (issue 17): an offset curved in temperature (temp_offset2) and a
shock that moves the offsets once (step), hidden in simulated wear.  The discovery loop names them
(the curve after the linear part it hides behind) and ends within 1.5x of what the true sensor
model achieves on the same held-out points; the step's time is found, by the host's float search
and by the device's integer one (acal/core/changepoint.py); both are calibrated (lsq on every rest
point, and the device), saved and applied; an effect the device has no form for is refused by
the device in one line."""
import json

import numpy as np
import pytest

from accelcal.pipeline.restpoints import rest_points, usable
from conftest import run_cli, run_main, simulate_wrists, true_heldout_error

DAYS, RATE = 3, 10
CASES = {"step": (31, "step"), "curve31": (31, "temp_offset2"), "curve5": (5, "temp_offset2")}
# seed 4: the curve's cold ends (the first hour, three showers) all fall in held-out blocks
CHORD = {"curve4": (4, "temp_offset2")}


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    return simulate_wrists(tmp_path_factory.mktemp("more_effects"),
                           {name: (seed, (effect,))
                            for name, (seed, effect) in {**CASES, **CHORD}.items()},
                           DAYS, RATE)


def diagnose(path, model):
    r = run_cli("diagnose", path, "--model", model, "--json")
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def discovery_loop(path, steps=3):
    """diagnose, add what it names, until it names nothing: the models and their findings."""
    model, seen = "base", []
    for _ in range(steps):
        out = diagnose(path, model)
        seen.append(out)
        if out["missing_effect"] is None:
            break
        model += "+" + out["missing_effect"]
    return seen


@pytest.mark.parametrize("name", list(CASES))
def test_the_loop_names_the_hidden_effect_and_ends_near_the_true_model(recordings, name):
    path = recordings[name]
    effect = CASES[name][1]
    seen = discovery_loop(path)
    # a curve may be named with its straight part in one step (temp_offset+temp_offset2)
    named = [n for s in seen if s["missing_effect"] for n in s["missing_effect"].split("+")]
    assert effect in named, [s["explanation"] for s in seen]
    final = seen[-1]
    assert final["missing_effect"] is None
    truth = true_heldout_error(path)
    assert final["heldout_error_mg"] <= 1.5 * truth, (final["heldout_error_mg"], truth, named)
    assert seen[0]["heldout_error_mg"] > 2 * final["heldout_error_mg"]


def test_the_step_time_is_found(recordings):
    path = recordings["step"]
    truth = json.loads(path.with_suffix(".truth.json").read_text())
    ts = truth["effects"][0]["reference"]["ts"]
    first = diagnose(path, "base")
    step = next(c for c in first["candidates"] if c["effect"] == "step")
    assert abs(step["step_time_s"] - ts) < 600, (step["step_time_s"], ts)
    assert "--model base+step" in first["explanation"] and "host only" not in first["explanation"]
    after = diagnose(path, "base+step")
    assert abs(after["reference"]["ts"] - ts) < 600


def test_host_effects_calibrate_save_and_apply(recordings, tmp_path):
    path = recordings["step"]
    params = tmp_path / "params.json"
    r = run_cli("calibrate", path, "--model", "base+step", "--method", "lsq", "--points", "all",
                "--save", params, "--json")
    assert r.returncode == 0, r.stderr
    rec = json.loads(r.stdout)
    truth = json.loads(path.with_suffix(".truth.json").read_text())
    true_j = np.array(list(truth["effects"][0]["params"].values()))
    got_j = np.array([rec["params"][n] for n in ("jx", "jy", "jz")])
    assert np.abs(got_j - true_j).max() < 0.0005          # 0.5 mg of 3-8 mg steps
    assert rec["error_after_mg"] < 0.5 * rec["error_before_mg"]
    saved = json.loads(params.read_text())
    assert saved["model"] == "base+step" and "ts" in saved["reference"]
    out = tmp_path / "calibrated.csv"
    r = run_cli("apply", params, path, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "the device's apply" in r.stderr      # the step is one of the device's effects
    # the applied recording's rest points: the step is gone, nothing left to name
    after = diagnose(out, "base")
    assert after["missing_effect"] is None, after["explanation"]
    assert after["heldout_error_mg"] < 0.5 * diagnose(path, "base")["heldout_error_mg"]


def rest_gap_around(path, ts):
    """The times of the last rest point before ts and the first from ts on (s)."""
    t = usable(rest_points(str(path))).t
    return t[t < ts].max(), t[t >= ts].min()


def test_the_device_finds_the_step_and_fits_it_in_integers(recordings, capsys):
    """The wear profile's pipeline on the shock recording: the change-point search on the held
    points puts ts after the last held point before the true shock, and the integer fit's error
    on every rest point is within 0.02 mg of the float fit of all of them.  (It was held within
    1.12x while both carried the Q10 rounding's bias in every rest mean, ~0.17 mg: 0.263 against
    0.237 mg, 0.026 mg over; with the format's dither, acal.core.fixed, 0.078 against 0.066 mg,
    0.012 mg over, 1.19x of the smaller floor.  1.08x until the bins kept a time effect's early
    points, acal.core.bins; 1.11x since on this shock at 44 h of 72, which leaves fewer held
    points after it; a shock at 19 h had 8 of 110 before it, 1.57x held out:
    tests/studies/test_composed_points.py.)  (The search and the
    step's fit run bit-identical and heap-locked on the 32-bit port: tests/device/test_heap.py.)"""
    path = recordings["step"]
    truth = json.loads(path.with_suffix(".truth.json").read_text())["effects"][0]
    code, text, err = run_main(capsys, ["calibrate", str(path), "--model", "base+step", "--json"])
    assert code == 0, err
    dev = json.loads(text)
    assert dev["status"] == "calibrated" and "note" not in dev, dev.get("note")
    before, after = rest_gap_around(path, truth["reference"]["ts"])
    ts = dev["reference"]["ts"]
    assert before < ts <= after + 3 * 3600, (before, ts, after)   # a held point after the shock
    got = np.array([dev["params"][n] for n in ("jx", "jy", "jz")])
    assert np.abs(got - np.array(list(truth["params"].values()))).max() < 0.0005
    code, text, err = run_main(capsys, ["calibrate", str(path), "--model", "base+step", "--json",
                                        "--method", "lsq", "--points", "all"])
    lsq = json.loads(text)
    assert dev["error_after_mg"] <= lsq["error_after_mg"] + 0.02, (dev["error_after_mg"], lsq["error_after_mg"])


def test_the_device_refuses_what_it_cannot_fit_in_one_line(recordings, tmp_path, capsys):
    path = recordings["curve31"]
    cubed = tmp_path / "cubed.py"     # a power of the reading: no device form
    cubed.write_text("EFFECTS = [dict(name='cubic', regressor='reading', power=3, unit='1/g^2', "
                     "bound=0.01, explanation='x')]")
    for args, says in (
            (["calibrate", path, "--model", "base+step", "--profile", "paper"], "wear profile"),
            (["deploy", "--port", tmp_path / "no-port", "--model", "base+step", "--profile",
              "paper"], "wear profile"),
            (["calibrate", path, "--model", "base+cubic", "--effects", cubed], "no device form"),
            (["calibrate", path, "--model", "base+cubic", "--effects", cubed, "--method", "lsq"],
             "no device form"),
            (["deploy", "--port", tmp_path / "no-port", "--model", "base+cubic", "--effects", cubed],
             "no device form")):
        code, _, err = run_main(capsys, [str(a) for a in args])
        assert code == 2 and err.count("\n") == 1, err
        assert says in err and "Traceback" not in err
    # on the host it is fitted on every rest point, saved and applied in float64
    params, out = tmp_path / "cubic.json", tmp_path / "applied.csv"
    code, _, err = run_main(capsys, ["calibrate", str(path), "--model", "base+cubic", "--effects",
                                     str(cubed), "--method", "lsq", "--points", "all", "--save",
                                     str(params)])
    assert code == 0, err
    head = tmp_path / "head.csv"      # the apply's path, on the recording's first hour
    with open(path) as f:
        head.write_text("".join(line for _, line in zip(range(36001), f)))
    code, _, err = run_main(capsys, ["apply", "--effects", str(cubed), str(params), str(head),
                                     "-o", str(out)])
    assert code == 0 and "applied on the host in float64" in err, err
    assert len(out.read_text().splitlines()) == 36001


@pytest.mark.parametrize("kind", ["step", "supply_offset"])
def test_a_stored_step_or_supply_resumes_after_a_reboot(tmp_path, kind):
    """The app's calibration store keeps a step's time (or a supply_offset's reference supply,
    mV) in its EFFECT record's time field, beside a drift's reference time; a reboot takes them
    back, a time relative to the restarted clock."""
    from acal.core import effects as deff
    from acal.logger import log
    from acal.logger.app import Processor
    from acal.core.fixed import C_TEMP, C_TIME, C_SUPPLY
    rate = 25
    unit = deff.DT_UNIT_S * rate
    store = log.CalStore(str(tmp_path / "a.bin"), str(tmp_path / "b.bin"))
    one = 1 << 24
    cal = (100 * unit, 1, 0, 5, 70, 1000, 10) + (one, one, one, 0, 0, 0, 0, 0, 0)
    held = 150 if kind == "step" else 3912
    store.save(cal, [(100 * unit, deff.DRIFT, 30, 80, 1000, -1000, 0),
                     (100 * unit, deff.parse_model("base+" + kind)[0], 30, held, 20000, 0, -20000)])
    proc = Processor(log.Log(str(tmp_path / "log.bin")), rate, store=store,
                     model="base+drift+" + kind)
    c = proc.calibration
    assert c.ref[C_TIME] == 80 - 100 and c.ref[C_TEMP] == 30
    if kind == "step":
        assert c.step_time == 150 - 80 and c.ref[C_SUPPLY] == 0
    else:
        assert c.ref[C_SUPPLY] == 3912 and c.step_time == 0
    assert proc.params[-6:] == [1000, -1000, 0, 20000, 0, -20000]


DECLARED = '''
EFFECTS = [
    dict(name="ageing2", regressor="time", power=2, unit="g/day^2", bound=0.005,
         explanation="The offset ages faster and faster."),
]
'''


@pytest.fixture(scope="module")
def declared(tmp_path_factory):
    """A declared effect (time squared) hidden in simulated wear by the same file."""
    d = tmp_path_factory.mktemp("declared")
    eff = d / "mine.py"
    eff.write_text(DECLARED)
    rec = d / "age.csv"
    r = run_cli("simulate", "wrist", "--days", DAYS, "--rate", RATE, "--seed", 31, "--effects", eff,
                "--effect", "ageing2", "-o", rec)
    assert r.returncode == 0, r.stderr
    return eff, rec


def test_a_declared_effect_is_found_once_declared(declared, tmp_path):
    eff, rec = declared
    r = run_cli("diagnose", rec, "--effects", eff, "--json")
    assert r.returncode == 0, r.stderr
    first = json.loads(r.stdout)
    assert first["missing_effect"] == "ageing2", first["explanation"]
    r = run_cli("diagnose", rec, "--effects", eff, "--model", "base+ageing2", "--json")
    second = json.loads(r.stdout)
    assert second["missing_effect"] is None
    assert second["heldout_error_mg"] <= 1.5 * true_heldout_error(rec, eff)
    # calibrate (lsq, every rest point), save, apply: the effect is gone from the applied file
    params, out = tmp_path / "p.json", tmp_path / "applied.csv"
    r = run_cli("calibrate", rec, "--effects", eff, "--model", "base+ageing2", "--method", "lsq",
                "--points", "all", "--save", params, "--json")
    assert r.returncode == 0, r.stderr
    truth = json.loads(rec.with_suffix(".truth.json").read_text())
    true_p = np.array(list(truth["effects"][0]["params"].values()))
    got = json.loads(r.stdout)["params"]
    assert np.abs(np.array([got[f"ageing2_{a}"] for a in "xyz"]) - true_p).max() < 0.2 * np.abs(true_p).max()
    r = run_cli("apply", params, rec, "-o", out)
    assert r.returncode == 2 and "ageing2" in r.stderr      # apply needs the file too
    r = run_cli("apply", "--effects", eff, params, rec, "-o", out)
    assert r.returncode == 0, r.stderr
    assert diagnose(out, "base")["heldout_error_mg"] < 0.5 * first["heldout_error_mg"]


def test_a_declared_effect_of_a_device_shape_runs_on_the_device(declared, capsys):
    """time^2 is one of the device's generic offsets: the board's fit (wear profile, integers)
    finds the declared effect near its true value, and the board is given the device's name."""
    from accelcal.model.declared import register
    from accelcal.model.effects import ModelSpec
    eff, rec = declared
    code, text, err = run_main(capsys, ["calibrate", str(rec), "--effects", str(eff), "--model",
                                        "base+ageing2", "--json"])
    assert code == 0, err
    dev = json.loads(text)
    assert dev["method"] == "device" and dev["status"] == "calibrated" and "note" not in dev
    truth = json.loads(rec.with_suffix(".truth.json").read_text())
    true_p = np.array(list(truth["effects"][0]["params"].values()))
    got = np.array([dev["params"][f"ageing2_{a}"] for a in "xyz"])
    assert np.abs(got - true_p).max() < 0.25 * np.abs(true_p).max(), (got, true_p)
    assert dev["error_after_mg"] < 0.5 * dev["error_before_mg"]
    register(str(eff))
    assert ModelSpec.parse("base+drift+ageing2").device_model == "base+drift+time_offset2"


def test_without_the_declaration_the_loop_says_what_remains(declared):
    _, rec = declared
    seen = discovery_loop(rec, steps=4)
    final = seen[-1]
    assert final["missing_effect"] is None
    # what no catalogue effect explains is said, with where and what would fit, when well above
    # the noise floor
    if final["heldout_error_mg"] > 1.5 * final["noise_floor_mg"]:
        wr = final["what_remains"]
        assert wr and wr["regressor"] and wr["shape"] in ("trend", "curve", "step")
        assert wr["text"] in final["explanation"] and wr["suggests"]


@pytest.mark.parametrize("body, says", [
    ("EFFECTS = [dict(name='a', regressor='time'", "syntax error"),
    ("X = 1", "must define EFFECTS"),
    ("EFFECTS = [dict(name='a', regressor='time', unit='g')]", "lacks bound, explanation"),
    ("EFFECTS = [dict(name='a', regressor='battery', unit='g', bound=0.1, explanation='x')]",
     "regressor must be one of"),
    ("EFFECTS = [dict(name='a', regressor='time', unit='g', bound=0.1, explanation='x', "
     "colour='red')]", "unknown field 'colour'"),
    ("EFFECTS = [dict(name='drift', regressor='time', unit='g', bound=0.1, explanation='x')]",
     "already an effect"),
    ("EFFECTS = [dict(name='a', regressor='time', unit='g', bound=float('nan'), "
     "explanation='x')]", "bound must be a number"),
    ("EFFECTS = [dict(name='a', regressor='temperature', step=True, unit='g', bound=0.1, "
     "explanation='x')]", "only for the time regressor"),
    ("raise RuntimeError('no')", "running it failed: RuntimeError: no"),
])
def test_a_bad_effects_file_is_one_line(recordings, tmp_path, capsys, body, says):
    f = tmp_path / "bad.py"
    f.write_text(body)
    for cmd in (["diagnose", recordings["step"]], ["calibrate", recordings["step"]],
                ["apply", tmp_path / "none.json", recordings["step"], "-o", tmp_path / "out.csv"]):
        code, _, err = run_main(capsys, [*cmd, "--effects", f])
        assert code == 2 and err.count("\n") == 1, err
        assert says in err and "Traceback" not in err


def test_a_regressor_the_recording_lacks_is_one_line(tmp_path):
    f = tmp_path / "warm.py"
    f.write_text("EFFECTS = [dict(name='warm2', regressor='temperature', power=2, unit='g', "
                 "bound=0.01, explanation='x')]")
    rec = tmp_path / "notemp.csv"     # rest points with times and no temperature
    t = np.arange(0, 40 * 3600, 600.0)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(len(t), 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    np.savetxt(rec, np.column_stack([d, t]), delimiter=",", header="x,y,z,t", comments="",
               fmt="%.5f")
    r = run_cli("diagnose", rec, "--effects", f, "--model", "base+warm2")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "temperature" in r.stderr, r.stderr


def test_a_clear_curve_is_named_with_its_straight_part_in_one_step(recordings):
    """A curve and its straight part are one candidate too (diagnose.curves), named when it
    passes the rule and leaves 1.5x less held-out error than the best single effect (the step's
    parsimony factor): on seed 5 it does (2.6x), and on seed 31 (4.0x; 1.2x, the straight part
    named first and the curve in the next step, while the rest means carried the Q10 rounding's
    bias, before the format's dither, acal.core.fixed)."""
    out = diagnose(recordings["curve5"], "base")
    assert out["missing_effect"] == "temp_offset+temp_offset2", out["explanation"]
    c = {x["effect"]: x for x in out["candidates"]}
    pair, line = c["temp_offset+temp_offset2"], c["temp_offset"]
    assert pair["heldout_error_mg"] * 1.5 < line["heldout_error_mg"]
    assert pair["single_ratio"] == pytest.approx(line["heldout_error_mg"] / pair["heldout_error_mg"])
    assert set(pair["params"]) == {"cx", "cy", "cz", "ex", "ey", "ez"}
    assert "Both parts at once" in out["explanation"]
    assert "--model base+temp_offset+temp_offset2" in out["explanation"]
    first = diagnose(recordings["curve31"], "base")
    assert first["missing_effect"] == "temp_offset+temp_offset2", first["explanation"]


def test_a_curve_the_device_would_fit_as_a_chord_is_named_as_the_device_fits_it(recordings,
                                                                                monkeypatch):
    """On seed 4 the curve's cold ends (the first hour, three showers) all fall in held-out
    blocks: while the rest means carried the Q10 rounding's bias the fit on every training point
    found the curve no better than its straight part, and the device's bins, which keep them,
    would fit base+temp_offset as the curve's chord.  With the format's dither (acal.core.fixed)
    the every-point judge names it itself (18 of 18 blocks; no seed of 1-3 and 6 left it to the
    fallback); the fallback is then judged with the every-point judge silenced: diagnose judges
    the curve again as the device fits it, in both folds of its split (pipeline/foldjudge.py),
    and names it: the effect the simulation hid."""
    from acal.discover import rule
    from accelcal.pipeline import diagnose as dg
    plain = diagnose(recordings["curve4"], "base+temp_offset")
    assert plain["missing_effect"] == "temp_offset2", plain["explanation"]
    c = next(x for x in plain["candidates"] if x["effect"] == "temp_offset2")
    assert rule.names(plain["heldout_error_mg"], c["heldout_error_mg"], c["blocks_improved"],
                      c["blocks"])   # the every-point judge alone

    class EveryPointSilent:   # the rule, but the every-point judge names nothing
        def __getattr__(self, name):
            return getattr(rule, name)

        @staticmethod
        def names(*args):
            return False

    monkeypatch.setattr(dg, "rule", EveryPointSilent())
    out = dg.diagnose(str(recordings["curve4"]), "base+temp_offset")
    assert out["missing_effect"] == "temp_offset2", out["explanation"]
    c = next(x for x in out["candidates"] if x["effect"] == "temp_offset2")
    judged = c["device_folds"]
    assert judged["named"] and judged["clear"] and c["evidence"] == "clear"
    assert judged["blocks"] > c["blocks"] == out["heldout_blocks"]   # both halves held out in turn
    assert judged["after_mg"] < judged["before_mg"]
    assert "as the device fits it" in out["explanation"]
    from accelcal.pipeline.results import DiagnoseResult
    from accelcal.report.pages import diagnose_page
    shown = "as the device fits it, each half held out in turn"
    assert f"{shown}: {judged['before_mg']:.2f} -> {judged['after_mg']:.2f} mg" in \
        DiagnoseResult(out).report()
    assert shown in diagnose_page(DiagnoseResult(out), {}, None)
    assert "--model base+temp_offset+temp_offset2" in out["explanation"]


def test_what_remains_names_the_shape_and_where():
    from accelcal.pipeline.remains import what_remains
    rng = np.random.default_rng(3)
    n = 3000
    t = np.sort(rng.uniform(0, 72, n))
    temp = rng.uniform(28, 36, n)
    ax = rng.uniform(-1, 1, n)
    noise = rng.normal(scale=0.3, size=n)
    regs = {"time_h": t, "temp_c": temp, "ax": ax}
    step = what_remains(regs, noise + 2.0 * (t >= 40.0))
    assert step["regressor"] == "time_h" and step["shape"] == "step" and abs(step["at"] - 40) < 1
    assert "step" in step["suggests"]
    curve = what_remains(regs, noise + 0.2 * (temp - 32) ** 2)
    assert curve["regressor"] == "temp_c" and curve["shape"] == "curve"
    assert "temp_offset2" in curve["suggests"]
    trend = what_remains(regs, noise + 0.05 * t)
    assert trend["regressor"] == "time_h" and trend["shape"] == "trend"
    assert what_remains(regs, noise) is None


def test_the_device_fits_the_curved_temperature_response(recordings):
    """temp_offset2 has a device form: the wear profile's integer fit of the loop's final model
    comes near lsq on every rest point (the device fits the 72 points its bins hold)."""
    path = recordings["curve31"]
    model = "base+temp_offset+temp_offset2"
    r = run_cli("calibrate", path, "--model", model, "--json")
    assert r.returncode == 0, r.stderr
    dev = json.loads(r.stdout)
    r = run_cli("calibrate", path, "--model", model, "--method", "lsq", "--points", "all", "--json")
    lsq = json.loads(r.stdout)
    assert dev["status"] == lsq["status"] == "calibrated" and dev["model"] == model
    assert dev["error_after_mg"] <= 1.5 * lsq["error_after_mg"], (dev["error_after_mg"],
                                                                   lsq["error_after_mg"])
    assert dev["error_after_mg"] < 0.5 * dev["error_before_mg"]


def test_compare_fits_a_declared_model_beside_the_methods(declared, capsys):
    """compare --model with --effects: the composed model by the device and by lsq on the same
    training part, scored on the same held-out points, well below the 9-parameter methods."""
    eff, rec = declared
    code, text, err = run_main(capsys, ["compare", str(rec), "--methods", "device,lsq", "--model",
                                        "base+ageing2", "--effects", str(eff), "--json"])
    assert code == 0, err
    rows = {(r["method"], r.get("model", "base")): r for r in json.loads(text)["rows"]}
    assert set(rows) == {("device", "base"), ("lsq", "base"), ("device", "base+ageing2"),
                         ("lsq", "base+ageing2")}
    best_base = min(rows[("device", "base")]["error_after_mg"], rows[("lsq", "base")]["error_after_mg"])
    for m in ("device", "lsq"):
        r = rows[(m, "base+ageing2")]
        assert r["status"] == "calibrated" and r["error_after_mg"] < 0.6 * best_base, (r, best_base)
    code, _, err = run_main(capsys, ["compare", str(rec), "--model", "base+ageing3"])
    assert code == 2 and "unknown effect 'ageing3'" in err and err.count("\n") == 1


def test_diagnose_places_a_step_among_the_held_out_points_of_its_gap():
    """A shock inside a held-out stretch, between two training points: place_step puts the
    step's time between the held-out points either side of the shock, and the true model's
    jumps leave those points less wrong placed than at the fitted time; leave-one-out never
    claims less than in-sample (simulated truth, no noise but the sensor's)."""
    from accelcal import simulate
    from accelcal.model.effects import ModelSpec
    from accelcal.pipeline.diagnose import place_step
    from accelcal.pipeline.restpoints import RestPoints
    truth = np.array([1.02, 0.98, 1.01, 0.004, -0.006, 0.003, 0.03, -0.02, 0.04])
    jump = np.array([0.004, -0.006, 0.005])
    # s: training points at ..., 6000 and 8000, ...: the fitted time halfway (change_point)
    shock, ts_fitted = 6400.0, 7000.0
    rng = np.random.default_rng(3)

    def points(t):
        d = simulate.unit_points(rng, len(t))
        v = simulate.uncorrect(truth, d) + np.where(t[:, None] >= shock, jump, 0.0)
        v += rng.normal(scale=0.0003, size=v.shape)
        return RestPoints(v, t, None, np.full(len(t), 1e-4), "test")

    train = points(np.r_[np.arange(0.0, 6001.0, 500.0), np.arange(8000.0, 14001.0, 500.0)])
    test = points(np.r_[np.arange(6100.0, 7901.0, 200.0), np.arange(14100.0, 16001.0, 300.0)])
    spec = ModelSpec.parse("base+step")
    theta = np.r_[truth, jump]
    placed = place_step(spec, theta, train, test, {"ts": ts_fitted})
    inside = test.t[(test.t > 6000) & (test.t < 8000)]
    below, above = inside[inside < shock].max(), inside[inside >= shock].min()
    assert placed["step_gap_points"] == len(inside)
    assert below < placed["step_time_placed_s"] < above, placed
    unplaced = float(np.mean(np.abs(np.linalg.norm(
        spec.correct(theta, test.v, np.zeros(len(test.t)), test.t, {"ts": ts_fitted}, {}),
        axis=1) - 1)) * 1e3)
    assert placed["heldout_error_placed_insample_mg"] <= placed["heldout_error_placed_mg"] < unplaced
    # in-sample is the model scored directly at the placed time (every held-out point)
    direct = float(np.mean(np.abs(np.linalg.norm(spec.correct(
        theta, test.v, np.zeros(len(test.t)), test.t, {"ts": placed["step_time_placed_s"]}, {}),
        axis=1) - 1)) * 1e3)
    assert placed["heldout_error_placed_insample_mg"] == pytest.approx(direct, rel=1e-9)
