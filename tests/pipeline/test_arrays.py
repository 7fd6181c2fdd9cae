"""Samples a researcher already holds (issue 51, files/arrays.py): a numpy array, a pandas or a
polars frame go through the same scan and device code as the CSV holding the same samples, so
they give the same calibration integers; apply gives back the kind it was given, calibrated as
the device's apply calibrates the file."""
import numpy as np
import pytest

import accelcal


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    d = tmp_path_factory.mktemp("arrays")
    accelcal.simulate_wrist(d / "wrist.csv", 1, 10, seed=3)
    cols = np.loadtxt(d / "wrist.csv", delimiter=",", skiprows=1)   # t,x,y,z,temp
    rec = accelcal.calibrate(str(d / "wrist.csv"))
    assert rec.ok
    return d, cols, rec


def same_fit(got, want):
    assert got.ok and got["params_int"] == want["params_int"]
    skip = ("file", "format")
    assert {k: v for k, v in got.items() if k not in skip} == \
        {k: v for k, v in want.items() if k not in skip}


def test_a_numpy_array_gives_the_file_s_integers(day):
    _, c, want = day
    same_fit(accelcal.calibrate(c[:, 1:4], time=c[:, 0], temp=c[:, 4]), want)
    assert np.array_equal(c[:, 0], np.arange(len(c)) / 10)   # the file's clock: 10 Hz from 0
    xyz = np.ascontiguousarray(c[:, 1:4])     # float64, contiguous: read in place, not copied
    got = accelcal.calibrate(xyz, rate=10, temp=c[:, 4])
    assert got["params_int"] == want["params_int"] and got["format"] == "numpy array"
    assert np.array_equal(xyz, c[:, 1:4])      # nothing writes into the caller's samples
    with pytest.raises(accelcal.InputError, match="rate= .Hz. or time="):
        accelcal.calibrate(c[:, 1:4])
    with pytest.raises(accelcal.InputError, match=r"\(n, 3\)"):
        accelcal.calibrate(c[:, 1:3], rate=10)


def test_pandas_frames_give_the_file_s_integers(day):
    pd = pytest.importorskip("pandas")
    _, c, want = day
    df = pd.DataFrame(c[:, 1:5], columns=["x", "y", "z", "temp"],
                      index=pd.to_datetime(c[:, 0], unit="s"))
    same_fit(accelcal.calibrate(df), want)
    secs = pd.DataFrame(c[:, 1:5], columns=["X", "Y", "Z", "Temperature"], index=c[:, 0])
    same_fit(accelcal.calibrate(secs), want)


def test_polars_frames_give_the_file_s_integers(day):
    pl = pytest.importorskip("polars")
    _, c, want = day
    df = pl.DataFrame({"time": (c[:, 0] * 1e6).astype("int64"), "x": c[:, 1], "y": c[:, 2],
                       "z": c[:, 3], "temp": c[:, 4]}).with_columns(
        pl.col("time").cast(pl.Datetime("us")))
    same_fit(accelcal.calibrate(df), want)
    same_fit(accelcal.calibrate(pl.DataFrame({"t": c[:, 0], "x": c[:, 1], "y": c[:, 2],
                                              "z": c[:, 3], "temp": c[:, 4]})), want)


def test_apply_gives_back_the_kind_it_was_given(day):
    d, c, rec = day
    rec.save(d / "p.json", force=True)
    out = accelcal.apply(d / "p.json", d / "wrist.csv", d / "cal.csv", force=True)
    file_xyz = np.loadtxt(d / "cal.csv", delimiter=",", skiprows=1)[:, 1:4]
    assert out["samples"] == len(c)
    a = accelcal.apply(rec, c[:, 1:4], rate=10, temp=c[:, 4])     # a result, or its file
    assert isinstance(a, np.ndarray) and np.array_equal(np.round(a, 6), file_xyz)
    # the device's apply: each calibrated sample nearer 1 g at rest than the raw one, on average
    assert np.abs(np.linalg.norm(a, axis=1) - 1).mean() < np.abs(np.linalg.norm(c[:, 1:4], axis=1) - 1).mean()
    try:
        import pandas as pd
    except ImportError:
        pd = None
    if pd is not None:
        df = pd.DataFrame(c[:, 1:5], columns=["x", "y", "z", "temp"],
                          index=pd.to_datetime(c[:, 0], unit="s"))
        got = accelcal.apply(d / "p.json", df)
        assert isinstance(got, pd.DataFrame) and got.index.equals(df.index)
        assert np.array_equal(got[["x", "y", "z"]].to_numpy(), a) and got["temp"].equals(df["temp"])
        assert np.array_equal(df[["x", "y", "z"]].to_numpy(), c[:, 1:4])   # input untouched
    try:
        import polars as pl
    except ImportError:
        return
    pf = pl.DataFrame({"t": c[:, 0], "x": c[:, 1], "y": c[:, 2], "z": c[:, 3], "temp": c[:, 4]})
    got = accelcal.apply(rec, pf)
    assert isinstance(got, pl.DataFrame) and np.array_equal(got.select("x", "y", "z").to_numpy(), a)


def test_compare_and_diagnose_read_an_array_as_the_file(day):
    from accelcal.files.arrays import as_input
    from accelcal.pipeline.restpoints import rest_points
    d, c, _ = day
    arr = accelcal.compare(c[:, 1:4], time=c[:, 0], temp=c[:, 4], methods=["device"])
    path = accelcal.compare(str(d / "wrist.csv"), methods=["device"])
    timeless = lambda rows: [{k: v for k, v in r.items() if k != "fit_ms"} for r in rows]  # noqa: E731
    assert timeless(arr["rows"]) == timeless(path["rows"]) and arr["input"] == "<numpy array>"
    # diagnose's input: the rest points of the file (pipeline/composed_lsq.prepare)
    a = rest_points(as_input(c[:, 1:4], time=c[:, 0], temp=c[:, 4]))
    b = rest_points(str(d / "wrist.csv"))
    assert np.array_equal(a.v, b.v) and np.array_equal(a.temp, b.temp) and np.array_equal(a.t, b.t)


@pytest.mark.slow
def test_diagnose_finds_in_an_array_what_it_finds_in_the_file(day):
    d, c, _ = day
    found = accelcal.diagnose(c[:, 1:4], time=c[:, 0], temp=c[:, 4])
    want = accelcal.diagnose(str(d / "wrist.csv"))
    assert found.to_dict() == {**want.to_dict(), "input": "<numpy array>"}
