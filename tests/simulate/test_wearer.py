"""The wearer simulator: a day that looks like a wrist's (uneven orientations, rest from seconds
to tens of minutes, a temperature trace that is not a function of time), a sensor with the
LIS3DH's noise and 12-bit quantisation, and ground truth that explains the data."""
import json

import numpy as np
import pytest

from accelcal.simulate import wearer
from accelcal.simulate.stimulus import read_stimulus
from acal.core.fixed import PARAM_NAMES
from conftest import run_cli

STILL = ("sleep", "awake_rest", "off_wrist")


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    d = tmp_path_factory.mktemp("wrist")
    r = run_cli("simulate", "wrist", "--days", 1, "--rate", 10, "--seed", 4, "-o", d / "w.csv",
                "--stimulus", d / "w.bin")
    assert r.returncode == 0, r.stderr
    rec = np.loadtxt(d / "w.csv", delimiter=",", skiprows=1)
    truth = json.loads((d / "w.truth.json").read_text())
    rate, stim, temp = read_stimulus(d / "w.bin")
    return rec, truth, stim, rate


def still_means(rec, truth, rate, trim_s=2):
    out = []
    for start, seconds, activity, _ in truth["segments"]:
        if activity in STILL and seconds > 2 * trim_s + 1:
            i0, i1 = int((start + trim_s) * rate), int((start + seconds - trim_s) * rate)
            out.append((rec[i0:i1, 1:4].mean(axis=0), seconds, rec[i0:i1, 1:4].std(axis=0)))
    return out


def test_truth_and_file(day):
    rec, truth, stim, rate = day
    assert rec.shape == (86400 * 10, 5) and rate == 10
    assert np.allclose(np.diff(rec[:, 0]), 0.1)
    assert set(truth["params"]) == set(PARAM_NAMES) and truth["effects"] == []
    p = np.array([truth["params"][n] for n in PARAM_NAMES])
    assert np.all(np.abs(p[:3] - 1) <= 0.03) and np.all(np.abs(p[3:6]) <= 0.011)
    assert np.all(np.abs(p[6:]) <= 0.06) and np.abs(p[6:]).max() > 0.005
    # 12-bit output registers at +-2 g: whole mg, within range.
    assert np.allclose(rec[:, 1:4] * 1000, np.rint(rec[:, 1:4] * 1000), atol=1e-6)
    assert np.abs(rec[:, 1:4]).max() <= 2.0
    assert abs(sum(truth["hours"].values()) - 24) < 0.01
    for activity in ("sleep", "walking", "typing", "off_wrist", "awake_rest"):
        assert truth["hours"].get(activity, 0) > 0.2, activity


def test_rest_lasts_seconds_to_tens_of_minutes(day):
    _, truth, _, _ = day
    s = truth["still_segments"]
    assert s["min_s"] < 10 and s["max_s"] > 20 * 60 and s["count"] > 100


def test_orientations_cluster_unevenly_but_reach_every_axis(day):
    rec, truth, _, rate = day
    means = np.array([m for m, _, _ in still_means(rec, truth, rate)])
    u = means / np.linalg.norm(means, axis=1, keepdims=True)
    for axis in range(3):  # all six half-axes are visited (the bins need them)...
        assert (u[:, axis] > 0.75).any() and (u[:, axis] < -0.75).any()
    # ...but unevenly (the paper's figure 5): the most visited of 20 direction cells (nearest
    # icosahedron face centre) holds far more than its share.
    phi = (1 + 5 ** 0.5) / 2
    verts = np.array([[-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0], [0, -1, phi],
                      [0, 1, phi], [0, -1, -phi], [0, 1, -phi], [phi, 0, -1], [phi, 0, 1],
                      [-phi, 0, -1], [-phi, 0, 1]], float)
    counts = np.bincount(np.argmax(u @ verts.T, axis=1), minlength=12)
    assert counts.max() > 4 * len(u) / 12 and (counts == 0).sum() >= 1


def test_temperature_is_not_collinear_with_time(day):
    rec, _, _, _ = day
    t, temp = rec[:, 0], rec[:, 4]
    assert abs(np.corrcoef(t, temp)[0, 1]) < 0.6
    assert temp.min() < 25 and temp.max() > 34   # off the wrist; under the blanket


def test_noise_and_truth_explain_the_still_data(day):
    rec, truth, stim, rate = day
    p = np.array([truth["params"][n] for n in PARAM_NAMES])
    from accelcal.methods import correct
    segs = [(m, s, sd) for m, s, sd in still_means(rec, truth, rate) if s > 600]
    assert len(segs) >= 5
    # Before quantisation the noise is the LIS3DH's 220 ug/sqrt(Hz) over 5 Hz: 0.49 mg.
    for start, seconds, activity, _ in truth["segments"]:
        if activity == "sleep" and seconds > 600:
            i0 = int((start + 5) * rate)
            sd = stim[i0:i0 + 3000].std(axis=0) * 1000
            assert np.all(np.abs(sd - truth["noise_mg"]) < 0.1 * truth["noise_mg"]), sd
            break
    # Long still segments, corrected with the true parameters, are 1 g within a milligram.
    a = correct(p, np.array([m for m, _, _ in segs]))
    assert np.abs(np.linalg.norm(a, axis=1) - 1).max() < 0.001
    # ...and uncorrected they are not (the errors are there to be calibrated away).
    raw = np.array([m for m, _, _ in segs])
    assert np.abs(np.linalg.norm(raw, axis=1) - 1).max() > 0.01


def test_simulate_wrist_bad_output_folder(tmp_path):
    r = run_cli("simulate", "wrist", "--days", 0.01, "-o", tmp_path / "nope" / "w.csv")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "does not exist" in r.stderr


def test_same_seed_same_recording(tmp_path):
    a = wearer.simulate_wrist(tmp_path / "a.csv", 0.02, 10, 9)
    b = wearer.simulate_wrist(tmp_path / "b.csv", 0.02, 10, 9)
    assert a["params"] == b["params"]
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
