"""The Python API's bad-input corpus, in-process, as tests/cli/test_bad_input.py is the CLI's:
every bad argument of accelcal.calibrate, diagnose, compare, apply and simulate_wrist raises
accelcal.InputError (nothing else: no ValueError, KeyError, TypeError, no silent default), its
message one line, and in the CLI's own words where the CLI has the option; nothing is written
over without force=True (the file keeps its bytes), and with force=True it is."""
import json
import math

import numpy as np
import pytest

from conftest import good_inputs, run_main

NAN = math.nan


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("apigood")
    return d, *map(str, good_inputs(d))


CALIBRATE = [dict(method="nope"), dict(model="nope"), dict(model=3), dict(profile="nope"),
             dict(runtime="nope"), dict(engine="nope"), dict(points="nope"),
             dict(seconds=0), dict(seconds=1.5), dict(seconds="5"), dict(seconds=True),
             dict(seconds=10 ** 9), dict(threshold=NAN), dict(threshold=0), dict(threshold=3),
             dict(threshold="x"), dict(threshold_g=math.inf), dict(axis="q"), dict(axis=7),
             dict(axis=None, min_count=0), dict(max_count=99), dict(min_count=5, max_count=2),
             dict(differ=-1), dict(differ=NAN), dict(select="x"), dict(policy="x"),
             dict(iterations=0), dict(iterations=10 ** 7), dict(rates=(1, 2)),
             dict(rates="3,8,2"), dict(discover=1), dict(foo=1), dict(cfg="x"), dict(cfg=None, seconds=0), dict(fallback=3),
             dict(effects=3)]
DIAGNOSE = [dict(model="nope"), dict(model=None), dict(model="base+nope"), dict(force="yes"),
            dict(history=3), dict(plots=b""), dict(effects=1.5)]
COMPARE = [dict(train="nope"), dict(methods="nope"), dict(methods=3), dict(split="nope"),
           dict(profile="nope"), dict(runtime="x"), dict(cfg=5), dict(model="nope")]
APPLY = [dict(range_g=3), dict(range_g=0), dict(range_g="8"), dict(range_g=NAN), dict(effects=3)]
SIMULATE = [dict(days=0), dict(days=1e9), dict(days=NAN), dict(days=-1), dict(days="1"),
            dict(days=math.inf), dict(rate=7), dict(rate=25.0), dict(range_g=3),
            dict(seed=-1), dict(seed=1.5), dict(seed=2 ** 40), dict(effect=["nope"]),
            dict(effect="drift"), dict(effect=["drift", "drift"]), dict(force="yes"),
            dict(events_within_days=0)]


def test_paths_must_be_paths(good, tmp_path):
    """A path argument that is not one (an int is a file descriptor to open(): never taken)."""
    import accelcal
    d, pts, rec, params = good
    out = str(tmp_path / "o.csv")
    for call in (lambda: accelcal.calibrate(3), lambda: accelcal.diagnose(None),
                 lambda: accelcal.compare(3), lambda: accelcal.apply(3, rec, out),
                 lambda: accelcal.apply(params, 3, out), lambda: accelcal.apply(params, rec, 3),
                 lambda: accelcal.simulate_wrist(3, 0.01, 10, 1),
                 lambda: accelcal.simulate_wrist(None, 0.01, 10, 1),
                 lambda: accelcal.simulate_wrist(out, 0.01, 10, 1, stimulus=2),
                 lambda: accelcal.calibrate_file(pts, "x"), lambda: accelcal.calibrate(""),
                 lambda: accelcal.Job.of(fallback=3)):
        said = _refused(call)
        assert "not a path" in said or "a Job" in said or "a file path, a numpy array" in said
    assert list(tmp_path.iterdir()) == []


def _refused(call):
    import accelcal
    with pytest.raises(accelcal.InputError) as e:
        call()
    assert type(e.value).__name__ in ("InputError", "InterpreterFailed")
    msg = str(e.value)
    assert msg and "\n" not in msg and len(msg) < 400, msg
    return msg


@pytest.mark.parametrize("kw", CALIBRATE, ids=repr)
def test_calibrate_refuses(good, kw):
    import accelcal
    _refused(lambda: accelcal.calibrate(good[1], **kw))


@pytest.mark.parametrize("kw", DIAGNOSE, ids=repr)
def test_diagnose_refuses(good, kw):
    import accelcal
    _refused(lambda: accelcal.diagnose(good[1], **kw))


@pytest.mark.parametrize("kw", COMPARE, ids=repr)
def test_compare_refuses(good, kw):
    import accelcal
    _refused(lambda: accelcal.compare(good[2], **kw))


@pytest.mark.parametrize("kw", APPLY, ids=repr)
def test_apply_refuses(good, kw, tmp_path):
    import accelcal
    d, pts, rec, params = good
    _refused(lambda: accelcal.apply(params, rec, str(tmp_path / "out.csv"), **kw))
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("kw", SIMULATE, ids=repr)
def test_simulate_wrist_refuses(kw, tmp_path):
    import accelcal
    args = dict(days=0.01, rate=10, seed=1) | kw
    _refused(lambda: accelcal.simulate_wrist(tmp_path / "w.csv", **args))
    assert list(tmp_path.iterdir()) == []      # refused before anything is written


@pytest.mark.parametrize("api,cli", [
    (lambda p: dict(seconds=0), ["--seconds", "0"]),
    (lambda p: dict(axis="q"), ["--axis", "q"]),
    (lambda p: dict(profile="nope"), ["--profile", "nope"]),
    (lambda p: dict(iterations=0), ["--iterations", "0"]),
    (lambda p: dict(select="x"), ["--select", "x"]),
], ids=["seconds", "axis", "profile", "iterations", "select"])
def test_the_api_says_what_the_cli_says(good, capsys, api, cli):
    """The same bad option, the same words: the API's message is the CLI's line less its
    `accelcal: error: ` and its pointer to --help."""
    import accelcal
    msg = _refused(lambda: accelcal.calibrate(good[1], **api(good)))
    code, _, err = run_main(capsys, ["calibrate", good[1], *cli])
    assert code == 2
    assert msg in err, (msg, err)


def test_nothing_written_over_without_force(good, tmp_path):
    """simulate_wrist and apply keep a file that exists, byte for byte, unless force=True."""
    import accelcal
    d, pts, rec, params = good
    for name in ("w.csv", "w.truth.json"):
        f = tmp_path / name
        f.write_text("mine\n")
        with pytest.raises(accelcal.InputError, match="--force|force"):
            accelcal.simulate_wrist(tmp_path / "w.csv", 0.01, 10, seed=1)
        assert f.read_text() == "mine\n"
        f.unlink()
    out = tmp_path / "out.csv"
    out.write_text("mine\n")
    with pytest.raises(accelcal.InputError):
        accelcal.apply(params, rec, str(out))
    assert out.read_text() == "mine\n"
    (tmp_path / "w.csv").write_text("mine\n")
    truth = accelcal.simulate_wrist(tmp_path / "w.csv", 0.01, 10, seed=1, force=True)
    assert (tmp_path / "w.csv").read_text().startswith("t,x,y,z") and truth["samples"] == 8640
    accelcal.apply(params, rec, str(out), force=True)
    assert out.read_text().startswith("t,x,y,z")


def test_good_keywords_are_the_cli_s_options(good, capsys):
    """The keywords that pass are taken as the CLI takes its options: the same record."""
    import accelcal
    d, pts, rec, params = good
    kw = dict(profile="wear", seconds=10, threshold=0.1, axis="y", min_count=2, max_count=8,
              differ=0.2, select="first", iterations=30, rates=(3, 8, 2))
    api = accelcal.calibrate(pts, **kw)
    code, out, err = run_main(capsys, ["calibrate", pts, "--json", "--profile", "wear",
                                       "--seconds", "10", "--threshold", "0.1", "--axis", "y",
                                       "--min-count", "2", "--max-count", "8", "--differ", "0.2",
                                       "--select", "first", "--iterations", "30",
                                       "--rates", "0.3,0.8,0.2"])
    assert code == 0, err
    assert json.loads(api.to_json()) == json.loads(out)
    # every setting, not only those a points file uses: the Config each makes
    from accelcal.cli import build_parser
    from accelcal.cli.options import pipeline_config
    args = build_parser().parse_args(["calibrate", pts, "--profile", "wear", "--seconds", "10",
                                      "--threshold", "0.1", "--axis", "y", "--min-count", "2",
                                      "--max-count", "8", "--differ", "0.2", "--select", "first",
                                      "--iterations", "30", "--rates", "0.3,0.8,0.2"])
    assert accelcal.Job.of(**kw).cfg == pipeline_config(args)
    for k, v in (("seconds", 11), ("axis", "x"), ("threshold", 0.2), ("differ", 0.3)):
        assert accelcal.Job.of(**(kw | {k: v})).cfg != pipeline_config(args)
    assert accelcal.calibrate(pts, threshold="auto", axis=3, policy="centre", differ_g=0.1).ok
