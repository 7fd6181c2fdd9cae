"""Quality control and batches: each file's status and figures against what was built into it
(simulated truth, files broken on purpose), one bad file never stopping the batch, --strict,
--fallback, and a Dask LocalCluster giving what the local pool gives."""
import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from accelcal.files.recordings import open_recording
from accelcal.pipeline.scan import scan
from conftest import ROOT, run_cli

REAL = ROOT / "tests" / "data" / "real"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch")
    # seed 3 fills the paper profile's bins in a day at 10 Hz, seed 1 does not (xn = 1); the
    # batch runs the paper profile to have both
    for seed in (3, 1):
        r = run_cli("simulate", "wrist", "--days", 1, "--rate", 10, "--seed", seed, "-o", d / f"s{seed}.csv")
        assert r.returncode == 0, r.stderr
    lines = (d / "s3.csv").read_text().splitlines(keepends=True)
    (d / "short.csv").write_text("".join(lines[:3001]))          # 5 minutes
    (d / "morning.csv").write_text("".join(lines[:216_001]))     # the same device's first 6 h
    broken = lines[:400_000] + ["40000.0,0.1,zz,0.9\n"] + lines[400_000:]
    (d / "corrupt.csv").write_text("".join(broken))
    shutil.copy(REAL / "ax6_sample.cwa", d / "ax6.cwa")
    return d


def _batch(files, *extra):
    names = ["s3.csv", "short.csv", "corrupt.csv", "s1.csv", "ax6.cwa", "missing.csv"]
    summary = files / "summary.csv"
    r = run_cli("calibrate", *[files / n for n in names], "--summary", summary, "--json",
                "--profile", "paper", "--force", *extra)   # the summary is written anew each time
    recs = {Path(json.loads(x)["file"]).name: json.loads(x) for x in r.stdout.splitlines()}
    return r, recs, summary


def test_batch_reports_each_file_and_never_stops(files):
    r, recs, summary = _batch(files, "--jobs", 2)
    assert r.returncode == 0, r.stderr
    assert recs["s3.csv"]["status"] == "calibrated" and recs["s3.csv"]["calibration"] == "new"
    assert recs["s3.csv"]["error_after_mg"] < recs["s3.csv"]["error_before_mg"] / 5
    assert recs["s1.csv"]["status"] == "not_enough_data" and "xn=1" in recs["s1.csv"]["reason"]
    assert recs["short.csv"]["status"] == "not_enough_data"
    assert recs["short.csv"]["hours"] == pytest.approx(3000 / 10 / 3600, abs=1e-3)
    assert recs["corrupt.csv"]["status"] == "failed" and "zz" in recs["corrupt.csv"]["reason"]
    assert recs["ax6.cwa"]["status"] == "not_enough_data" and recs["ax6.cwa"]["rate_hz_device"] == 100
    assert recs["missing.csv"]["status"] == "failed" and "No such file" in recs["missing.csv"]["reason"]
    rows = list(csv.DictReader(open(summary)))
    assert [Path(x["file"]).name for x in rows] == ["s3.csv", "short.csv", "corrupt.csv", "s1.csv",
                                                    "ax6.cwa", "missing.csv"]
    assert {x["status"] for x in rows} == {"calibrated", "not_enough_data", "failed"}
    s3 = rows[0]
    assert float(s3["kxx"]) == recs["s3.csv"]["params"]["kxx"] and s3["bins_filled"] == "9"
    assert {x["profile"] for x in rows} == {"paper"}   # every row, the failed ones too
    # the batch's record of a file is the one-file record of it (less the timing)
    one = json.loads(run_cli("calibrate", files / "s3.csv", "--json", "--profile", "paper").stdout)
    assert {k: v for k, v in recs["s3.csv"].items() if k != "seconds"} == one
    # --strict: the same batch, now a failure
    r2, _, _ = _batch(files, "--strict", "--quiet")
    assert r2.returncode == 2


def test_fallback_is_reported_not_silent(files, tmp_path):
    params = tmp_path / "last_good.json"
    assert run_cli("calibrate", files / "s3.csv", "--save", params).returncode == 0
    morning = files / "morning.csv"
    r = run_cli("calibrate", morning, "--fallback", params, "--json")
    rec = json.loads(r.stdout)
    assert r.returncode == 0
    assert rec["status"] == "not_enough_data" and rec["calibration"] == "fallback"
    assert rec["fallback"] == str(params)
    saved = json.loads(params.read_text())
    assert rec["params_int"] == saved["params_int"]
    # the default (auto) saved the paper's model and a temperature offset (s3 has 24-35 degC):
    # the fallback's record is that model, its error on this file the saved parameters scored
    # here on the kept rest means (the default profile's rest test: every axis, the threshold
    # from the noise), each offset by c (T - T0) at its own mean temperature first
    assert saved["model"] == rec["model"] == "base+temp_offset" and rec["reference"] == saved["reference"]
    sc = scan(open_recording(morning), 5, 0, 3)
    kept = sc.masks()["kept"]
    v = sc.segments.mean[kept] / 65536.0
    p = saved["params"]
    dT = sc.seg_temp[kept] - saved["reference"]["T0"]
    v = v - np.outer(dT, [p["cx"], p["cy"], p["cz"]])
    K = np.array([[p["kxx"], 0, 0], [p["kxy"], p["kyy"], 0], [p["kxz"], p["kyz"], p["kzz"]]])
    a = (v + [p["ox"], p["oy"], p["oz"]]) @ K.T
    assert rec["error_after_mg"] == pytest.approx(1e3 * np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)), rel=1e-6)
    assert rec["error_after_mg"] < rec["error_before_mg"] / 3
    text = run_cli("calibrate", morning, "--fallback", params).stdout
    assert "NOT ENOUGH DATA" in text and "fallback" in text
    assert run_cli("calibrate", morning).returncode == 2   # no fallback: a failure
    # the saved temperature offset cannot be applied to a file without temperature: one line
    import pyarrow.csv as pacsv
    bare = tmp_path / "bare.csv"
    pacsv.write_csv(pacsv.read_csv(morning).drop_columns(["temp"]), bare)
    r = run_cli("calibrate", bare, "--fallback", params)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "temperature column" in r.stderr, r.stderr


@pytest.mark.slow   # CI's time limit (stop 37)
def test_dask_local_cluster_gives_the_local_pool_results(files):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        r, recs, _ = _batch(files, "--dask", cluster.scheduler_address)
    assert r.returncode == 0, r.stderr
    _, local, _ = _batch(files, "--jobs", 2)
    strip = lambda d: {k: {kk: vv for kk, vv in v.items() if kk != "seconds"} for k, v in d.items()}
    assert strip(recs) == strip(local)
    r = run_cli("calibrate", files / "s3.csv", files / "s1.csv", "--dask", "tcp://127.0.0.1:9",
                "--summary", files / "unreachable.csv")
    assert r.returncode == 2 and "cannot reach" in r.stderr


def test_nonwear_found_where_the_simulated_wearer_took_it_off(files):
    """The simulator's truth says when the device lay off the wrist (a shower, face up, room
    temperature); the host's non-wear check finds that time and little else."""
    sc = scan(open_recording(files / "s3.csv"), 5, 123, 0)
    m = sc.masks()
    truth = json.loads((files / "s3.truth.json").read_text())
    starts = np.array([s[0] for s in truth["segments"]])
    act = np.array([s[2] for s in truth["segments"]])[np.searchsorted(starts, sc.seg_t - 2.5, "right") - 1]
    off = (act == "off_wrist") & m["still"]
    found = m["nonwear"]
    assert off.sum() > 100
    assert (found & off).sum() >= 0.7 * off.sum()          # recall
    assert (found & off).sum() >= 0.8 * found.sum()        # precision (just back on: still cool)


def test_imputed_and_clipped_segments_are_kept_from_the_bins(files, tmp_path):
    """A stretch padded with a repeated sample (as exporters fill gaps) and a stretch pinned at
    the full scale on y while x is calm (the paper's x-only rest test passes it): both are
    still to the device's test and both are excluded, counted, and the clipping share is the
    number of samples put at the full scale."""
    lines = (files / "s3.csv").read_text().splitlines(keepends=True)
    n_imp, n_clip = 3000, 1000
    for i in range(200_001, 200_001 + n_imp):
        t = lines[i].split(",")[0]
        lines[i] = f"{t},0.123,-0.456,0.789,30.00\n"
    for i in range(500_001, 500_001 + n_clip):
        t = lines[i].split(",")[0]
        lines[i] = f"{t},{0.300 + 0.001 * (i % 3):.3f},2.047,0.100,30.00\n"   # x: noise
    f = tmp_path / "edited.csv"
    f.write_text("".join(lines))
    rec = json.loads(run_cli("calibrate", f, "--json").stdout)
    base = json.loads(run_cli("calibrate", files / "s3.csv", "--json").stdout)
    assert rec["excluded"]["imputed"] >= n_imp // 50 - 1
    assert rec["excluded"]["clipped"] >= n_clip // 50 - 1
    assert rec["full_scale_g"] == 2.0
    truth_clipped = json.loads((files / "s3.truth.json").read_text())["clipped_samples"]
    assert rec["clipped_pct"] == pytest.approx(100 * (n_clip + truth_clipped) / 864000, abs=1e-4)
    assert rec["still_windows"] < base["still_windows"]


def test_relative_temperature_uses_the_cooling_test_only(files, tmp_path):
    """An LIS3DH's temperature without a reference is relative (here: 25 degC low throughout).
    Below 25 degC everywhere, yet only the cooling (taking the device off) counts as non-wear."""
    import pyarrow.csv as pacsv
    tab = pacsv.read_csv(files / "s3.csv")
    cols = {c: tab.column(c).to_numpy() for c in tab.column_names}
    cols["temp"] = cols["temp"] - 25.0
    f = tmp_path / "relative.csv"
    np.savetxt(f, np.column_stack([cols[c] for c in ("t", "x", "y", "z", "temp")]), delimiter=",",
               fmt=["%.4f", "%.3f", "%.3f", "%.3f", "%.2f"], header="t,x,y,z,temp", comments="")
    absolute = scan(open_recording(files / "s3.csv"), 5, 123, 0).masks()
    relative = scan(open_recording(f), 5, 123, 0).masks()
    assert 0 < relative["nonwear"].sum() < absolute["nonwear"].sum()
    assert (relative["nonwear"] & ~absolute["nonwear"]).sum() == 0


def test_one_file_and_a_batch_follow_one_rule(files, tmp_path):
    """calibrate FILE and the same FILE in a batch go through one calibrate_file: the same record
    (less the batch's timing) for a recording and for points files, --fallback taken by either
    kind of file that does not calibrate, and a bad file's one-line error the batch's reason."""
    params = tmp_path / "last_good.json"
    assert run_cli("calibrate", files / "s3.csv", "--save", params).returncode == 0
    r = run_cli("simulate", "paper", "--scenarios", 1, "--seed", 5, "-o", tmp_path / "pts.csv")
    assert r.returncode == 0, r.stderr
    head, *rows = (tmp_path / "pts.csv").read_text().splitlines(keepends=True)
    (tmp_path / "few.csv").write_text(head + "".join(rows[:6]))    # bins cannot fill
    names = [files / "morning.csv", tmp_path / "pts.csv", tmp_path / "few.csv", files / "corrupt.csv"]
    opts = ["--fallback", params, "--profile", "paper", "--json"]
    r = run_cli("calibrate", *names, *opts, "--summary", tmp_path / "sum.csv")
    assert r.returncode == 0, r.stderr
    batch = [json.loads(x) for x in r.stdout.splitlines()]
    assert [b["status"] for b in batch] == ["not_enough_data", "calibrated", "not_enough_data",
                                            "failed"]
    assert [b["calibration"] for b in batch] == ["fallback", "new", "fallback", "none"]
    for name, b in zip(names, batch):
        one = run_cli("calibrate", name, *opts)
        if b["status"] == "failed":
            assert one.returncode == 2 and one.stdout == ""
            assert one.stderr.strip() == f"accelcal: error: {b['reason']}"
        else:
            assert one.returncode == 0, one.stderr
            assert json.loads(one.stdout) == {k: v for k, v in b.items() if k != "seconds"}
