"""The command line as a user meets it: outputs, --by, --save/apply, and bad input -> exit 2 with
one line on stderr, never a traceback."""
import json

import numpy as np
import pytest

from accelcal import simulate
from conftest import ROOT, relative, run_cli


@pytest.fixture
def points_csv(tmp_path):
    out = tmp_path / "pts.csv"
    r = run_cli("simulate", "paper", "--scenarios", 3, "--points", 200, "--seed", 4, "-o", out)
    assert r.returncode == 0, r.stderr
    return out


def one_error_line(r):
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    return lines[0]


def test_calibrate_by_device_json_recovers_truth(points_csv):
    truth = json.loads(points_csv.with_suffix(".truth.json").read_text())["params"]
    r = run_cli("calibrate", points_csv, "--by", "device", "--json", "--profile", "paper")
    assert r.returncode == 0, r.stderr
    recs = [json.loads(line) for line in r.stdout.splitlines()]
    assert [x["device"] for x in recs] == ["s0000", "s0001", "s0002"]
    assert all(x["profile"] == "paper" for x in recs)
    for rec in recs:
        for key in ("model", "params", "params_int", "iterations", "points", "error_before_mg", "error_after_mg"):
            assert key in rec
        assert rec["points"] == 18 and rec["iterations"] == 50
        t = truth[rec["device"]]
        assert max(abs(rec["params"][k] - t[k]) for k in ("kxx", "kyy", "kzz", "ox", "oy", "oz")) < 3e-3
        assert rec["error_after_mg"] < rec["error_before_mg"] / 10
        assert rec["params_int"]["kxx"] == round(rec["params"]["kxx"] * 2 ** 24)


def test_runtimes_agree_through_the_cli(points_csv):
    a = run_cli("calibrate", points_csv, "--by", "device", "--json")
    b = run_cli("calibrate", points_csv, "--by", "device", "--json", "--runtime", "micropython")
    pa = [json.loads(x)["params_int"] for x in a.stdout.splitlines()]
    pb = [json.loads(x)["params_int"] for x in b.stdout.splitlines()]
    assert pa == pb and len(pa) == 3


@pytest.mark.parametrize("method", ["lsq", "linauto"])
def test_reference_methods(points_csv, method):
    r = run_cli("calibrate", points_csv, "--by", "device", "--method", method, "--json")
    assert r.returncode == 0, r.stderr
    recs = [json.loads(x) for x in r.stdout.splitlines()]
    assert all(x["method"] == method and x["status"] == "calibrated" for x in recs)
    if method == "linauto":
        assert all(x["params"]["kxy"] == 0 for x in recs)


def test_recording_save_and_apply(tmp_path, rng):
    # A recording: 5 s rest segments at many orientations with motion between, 25 Hz.
    p = simulate.random_params(rng)
    rate, rows, t = 25, [], 0.0
    dirs = simulate.unit_points(rng, 150)
    for d in dirs:
        v = simulate.uncorrect(p, d[None, :])[0]
        seg = v + rng.normal(scale=0.002, size=(5 * rate, 3))
        move = rng.normal(scale=0.3, size=(5 * rate, 3)) + v
        for s in np.concatenate([seg, move]):
            rows.append((t, *s))
            t += 1 / rate
    rec = tmp_path / "rec.csv"
    np.savetxt(rec, np.array(rows), delimiter=",", header="t,x,y,z", comments="", fmt="%.6f")
    params = tmp_path / "params.json"
    r = run_cli("calibrate", rec, "--save", params, "--json", "--profile", "paper")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["rest_points"] >= 140 and out["error_after_mg"] < 3
    saved = json.loads(params.read_text())
    assert saved["params_int"] == out["params_int"] and saved["model"] == "base"
    cal = tmp_path / "cal.csv"
    r = run_cli("apply", params, rec, "-o", cal)
    assert r.returncode == 0, r.stderr
    a = np.loadtxt(cal, delimiter=",", skiprows=1)
    assert a.shape == (len(rows), 4)
    still = np.concatenate([np.arange(i * 10 * rate, i * 10 * rate + 5 * rate) for i in range(150)])
    before = np.abs(np.linalg.norm(np.array(rows)[still, 1:], axis=1) - 1).mean()
    after = np.abs(np.linalg.norm(a[still, 1:], axis=1) - 1).mean()
    assert after < before / 5


def test_save_by_device_then_apply_one(points_csv, tmp_path):
    params = tmp_path / "all.json"
    assert run_cli("calibrate", points_csv, "--by", "device", "--save", params).returncode == 0
    rec = tmp_path / "rec.csv"
    rec.write_text("t,x,y,z\n0,0.1,0.2,0.97\n0.01,0.1,0.2,0.97\n")
    line = one_error_line(run_cli("apply", params, rec, "-o", tmp_path / "o.csv"))
    assert "holds 3 devices" in line and "s0001" in line
    r = run_cli("apply", params, rec, "-o", tmp_path / "o.csv", "--device", "s0001")
    assert r.returncode == 0, r.stderr
    assert "no device 'zz'" in one_error_line(run_cli("apply", params, rec, "-o", tmp_path / "o.csv", "--device", "zz"))


def write(tmp_path, text, name="bad.csv"):
    f = tmp_path / name
    f.write_text(text)
    return f


@pytest.mark.parametrize("text,needle", [
    ("x,y,z\n0.1,abc,1\n", "non-numeric value 'abc' in column y"),
    ("x,y,z\n0.1,,1\n", "missing value in column y"),
    ("x,y,z\n0.1,nan,1\n", "nan in column y"),
    ("x,y,z\n0.1,0.2\n", "expected 3 values"),
    ("a,b,c\n1,2,3\n", "header needs columns x,y,z"),
    ("", "empty file"),
    ("x,y,z\n", "no data rows"),
])
def test_bad_files(tmp_path, text, needle):
    line = one_error_line(run_cli("calibrate", write(tmp_path, text)))
    assert needle in line


def test_missing_file(tmp_path):
    assert "cannot open" in one_error_line(run_cli("calibrate", tmp_path / "nope.csv"))


def test_too_few_points_says_how_many_each_bin_got(tmp_path):
    f = write(tmp_path, "x,y,z\n1,0,0\n-1,0,0\n0,1,0\n0,-1,0\n0,0,1\n")
    line = one_error_line(run_cli("calibrate", f))
    assert "bins did not fill" in line and "xn=1" in line and "need >= 2 each" in line and "5 points" in line


def test_one_hemisphere_does_not_fill(tmp_path, rng):
    a = simulate.unit_points(rng, 500)
    a[:, 2] = np.abs(a[:, 2])
    f = tmp_path / "hemi.csv"
    np.savetxt(f, a, delimiter=",", header="x,y,z", comments="", fmt="%.6f")
    line = one_error_line(run_cli("calibrate", f))
    assert "zn=0" in line


def test_diverging_fit(points_csv):
    r = run_cli("calibrate", points_csv, "--by", "device", "--rates", "3,8,2", "--profile", "paper")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 3 and all("diverged" in x and "no parameters" in x for x in lines)
    assert "Traceback" not in r.stderr


def test_bad_options(points_csv, tmp_path):
    r = run_cli("calibrate", points_csv, "--rates", "0.35,0.8,0.2")
    assert r.returncode == 2 and "multiples of 0.1" in r.stderr
    assert "unknown effect 'warp'" in one_error_line(run_cli("calibrate", points_csv, "--model", "base+warp"))
    assert "no column" in one_error_line(run_cli("calibrate", points_csv, "--by", "serial"))
    bad = write(tmp_path, "{}", "p.json")
    assert "params_int" in one_error_line(run_cli("apply", bad, points_csv, "-o", tmp_path / "o.csv"))


def test_help_for_every_command():
    for cmd in (["--help"], ["calibrate", "--help"], ["apply", "--help"], ["simulate", "paper", "--help"],
                ["paper", "table2", "--help"], ["bench", "--help"]):
        r = run_cli(*cmd)
        assert r.returncode == 0 and "usage:" in r.stdout


def test_profiles_and_points_in_the_records(points_csv):
    """Every record says which profile ran and, for a float method, what it was fitted on."""
    wear = [json.loads(x) for x in run_cli("calibrate", points_csv, "--by", "device", "--json").stdout.splitlines()]
    assert all(x["profile"] == "wear" and x["status"] == "calibrated" for x in wear)
    assert all(x["points"] > 18 for x in wear)   # up to 8 per subset, less the outliers
    for pts in ("bins", "all"):
        r = run_cli("calibrate", points_csv, "--by", "device", "--method", "lsq", "--points", pts, "--json")
        recs = [json.loads(x) for x in r.stdout.splitlines()]
        assert r.returncode == 0 and all(x["points_from"] == pts for x in recs)
        if pts == "all":
            assert all(x["points"] >= 190 for x in recs)   # every usable point of each device
    line = one_error_line(run_cli("calibrate", points_csv, "--points", "all"))
    assert "--points applies to the float methods" in line
    for bad in ("nan", "inf", "-0.1", "x"):
        r = run_cli("calibrate", points_csv, "--threshold", bad)
        assert r.returncode == 2 and "Traceback" not in r.stderr


def test_apply_at_the_full_scale_and_says_what_it_clipped(tmp_path):
    """apply runs the device's per-sample code at a full scale: readings past it are clipped,
    as the device's would be, and counted; --range keeps them (its format: one bit less)."""
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"model": "base", "scale": "Q24", "params_int": {
        "kxx": 1 << 24, "kyy": 1 << 24, "kzz": 1 << 24, "kxy": 0, "kxz": 0, "kyz": 0,
        "ox": 0, "oy": 0, "oz": 0}}))
    rec = tmp_path / "rec.csv"
    rec.write_text("t,x,y,z\n0,0,0,1\n0.1,3.0,0,1\n0.2,0,-2.5,1\n")
    out = tmp_path / "o.csv"
    r = run_cli("apply", params, rec, "-o", out)
    assert r.returncode == 0 and "2 samples past that full scale were clipped" in r.stderr, r.stderr
    a = np.loadtxt(out, delimiter=",", skiprows=1)
    assert a[1, 1] == pytest.approx(2097 / 1024) and a[2, 2] == pytest.approx(-2097 / 1024)
    r = run_cli("apply", params, rec, "-o", out, "--range", "4", "--force")
    assert r.returncode == 0 and "clipped" not in r.stderr
    a = np.loadtxt(out, delimiter=",", skiprows=1)
    assert a[1, 1] == pytest.approx(3.0, abs=2e-3) and a[2, 2] == pytest.approx(-2.5, abs=2e-3)


def test_apply_composed_at_8_g_at_the_device_outputs_full_resolution(tmp_path, rng):
    """A composed model at +-8 g (a composed model was held at +-2 g): readings to 7.5 g are
    not clipped, and what apply writes is the device's output, Q11 g at 8 g, to the last bit
    (the twin's integers back from the CSV, exactly), within the format's rounding of the
    float model; at --range 2 the same file is clipped."""
    from acal.core import fixed
    from accelcal.bridge import twin
    from accelcal.fixedpoint import g_to_sample
    from accelcal.model.effects import ModelSpec
    spec = ModelSpec.parse("base+temp_offset")
    theta = np.array([1.02, 0.98, 1.01, 0.01, -0.02, 0.005, 0.05, -0.03, 0.02,
                      0.002, -0.001, 0.0015])       # g per degC from T0
    p_int = [int(v) for v in spec.to_int(theta)]
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"model": str(spec), "reference": {"T0": 25.0, "t0": 0.0},
                                  "params_int": dict(zip(spec.param_names, p_int))}))
    n = 2000
    xyz = rng.uniform(-7.5, 7.5, (n, 3))
    temp = rng.uniform(15, 35, n).round(1)
    rec = tmp_path / "rec.csv"
    np.savetxt(rec, np.c_[np.arange(n) / 10, xyz, temp], delimiter=",", header="t,x,y,z,temp",
               comments="", fmt="%.6f")
    out = tmp_path / "o.csv"
    r = run_cli("apply", params, rec, "-o", out, "--range", "8")
    assert r.returncode == 0 and "clipped" not in r.stderr, r.stderr
    a = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:4]
    one_g = 1 << fixed.apply_out_q(8)
    assert one_g == 2048
    written = np.loadtxt(rec, delimiter=",", skiprows=1)   # the recording as apply reads it
    q, temp = g_to_sample(written[:, 1:4]), written[:, 4]
    quarter = 1 << fixed.TEMP_Q     # the device's temperature: Q2 degC
    dT = np.rint(temp * quarter).astype(np.int64) - 25 * quarter
    want_int = twin.apply_params(p_int, q, spec.kinds, relative(n, dT), 8)
    assert (np.rint(a * one_g).astype(np.int64) == want_int).all()
    assert np.abs(a * one_g - want_int).max() < 0.01   # written to 1e-6 g: every step kept
    want = spec.correct(spec.from_int(p_int), q / 1024, np.rint(temp * quarter) / quarter, np.zeros(n),
                        {"T0": 25.0, "t0": 0.0}, {})
    assert np.abs(a - want).max() < 3 / one_g       # K Q14, offsets and effect Q12, output Q11
    r = run_cli("apply", params, rec, "-o", out, "--range", "2", "--force")
    assert r.returncode == 0 and "were clipped" in r.stderr, r.stderr


@pytest.mark.parametrize("argv", [["--help"], ["calibrate", "--help"], ["apply", "--help"],
                                  ["diagnose", "--help"], ["bench", "--help"]])
def test_help_loads_no_heavy_library(argv):
    """Issue 30 part 4: the parser imports no method. What --help loaded is read from
    sys.modules in a fresh interpreter (not timed), so it holds however loaded the machine is."""
    import subprocess
    import sys
    code = ("import sys\nfrom accelcal.cli import main\n"
            f"try:\n    main({argv!r})\nexcept SystemExit:\n    pass\n"
            "heavy = ('scipy', 'matplotlib', 'pandas', 'dask', 'pyarrow', 'sklearn')\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & set(heavy)), file=sys.stderr)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stderr.strip().splitlines()[-1] == "[]", out.stderr


def test_calibrate_and_apply_load_what_they_use(points_csv, tmp_path):
    """Issue 30 part 4: `calibrate` (a points file, a recording CSV, a .cwa) and `apply` on the
    in-process runtime load no float library they do not call and not the emulated chip (its
    firmware and build tools: only the chip runtimes use it), nor numpy.ma; the CWA reader
    does not load Arrow.  Read from sys.modules in a fresh interpreter (not timed)."""
    import subprocess
    import sys
    params = tmp_path / "p.json"
    assert run_cli("calibrate", points_csv, "--by", "device", "--save", params).returncode == 0
    rec = tmp_path / "rec.csv"
    rec.write_text("t,x,y,z,temp\n" + "".join(f"{i / 100},0.1,0.2,0.97,30\n" for i in range(3000)))
    cwa = ROOT / "tests" / "data" / "real" / "ax3_sample.cwa"
    heavy = ("accelcal.bridge.rp2040", "numpy.ma")     # np.median's masked-array check: 0.05-0.2 s
    for argv, also in ((["calibrate", str(points_csv), "--quiet"], ()),
                       (["calibrate", str(rec), "--quiet"], ()),
                       (["calibrate", str(cwa), "--quiet"], ("pyarrow",)),
                       (["apply", str(params), str(rec), "-o", str(tmp_path / "o.csv"), "--device",
                         "s0001", "--quiet"], ())):
        code = ("import sys\nfrom accelcal.cli import main\n"
                f"try:\n    main({argv!r})\nexcept SystemExit:\n    pass\n"
                f"print(sorted(m for m in sys.modules if m in {heavy + also!r} or "
                "m.split('.')[0] in ('scipy', 'matplotlib', 'pandas', 'dask', 'sklearn')), "
                "file=sys.stderr)")
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert out.stderr.strip().splitlines()[-1] == "[]", (argv, out.stderr)
