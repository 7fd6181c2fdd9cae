"""Where the last tenth goes (issue 50 part 5, accelcal.studies.tenth): on a clean held-back
wrist (seed 1), scored on the recording's own values, float least squares on every rest point
reaches the true sensor model and on the bins' points comes within 10 % of it (the bins' choice
of points costs little); the device's fit offered the file's own means comes within 1.15x;
so does its fit on Q10 samples rounded with a deterministic dither (the candidate fix); the
device's fit as it is (means of Q10 samples) does not: the 1 mg steps re-rounded onto 1/1024 g
are what remains (measured 28 Nov 2026: device 1.99x, device_file 1.09x, device_dither 1.08x,
lsq_bins 1.06x)."""
import pytest

pytestmark = pytest.mark.slow   # ~15 s: a 5-day simulation and three fits


@pytest.fixture(scope="module")
def seed1(tmp_path_factory):
    from accelcal.studies import tenth
    return tenth.run_seed(1, tmp_path_factory.mktemp("tenth"), auto=True)


def test_the_float_fits_and_the_unrounded_device_fit_reach_the_true_model(seed1):
    r = seed1
    assert r["lsq_all"] <= 1.02 * r["true"], r
    assert r["lsq_bins"] <= 1.10 * r["true"], r
    assert r["device_file"] <= 1.15 * r["true"], r
    # the candidate fix that keeps the Q10 format: the samples rounded with a deterministic
    # dither by sample index (measured 28 Nov 2026: 1.08x; its output 1.25x against 4.3x)
    assert r["device_dither"] <= 1.15 * r["true"], r
    assert r["output_dither"] < 0.5 * r["output"], r
    # the written output carries the input's Q10 rounding: above the device's fit scored on
    # the file's values, by about what the Q10 windows add
    assert r["output"] > r["device"] and abs(r["output"] - r["device_q10_windows"]) < 0.03, r


def test_auto_over_base_on_clean_wear_follows_the_rounding(seed1):
    """The default's auto model over the paper's model on this clean seed: 1.18 fitted on Q10
    means (the rounding's share, fitted by three more parameters), within 5 % fitted on dithered
    means (measured 28 Nov 2026: 0.964)."""
    assert abs(seed1["auto_over_base_dither"] - 1) <= 0.05, seed1
    assert abs(seed1["auto_over_base_q10"] - 1) > abs(seed1["auto_over_base_dither"] - 1), seed1


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "issue 50 part 5 not done: the device's points are means of Q10 samples (the 1 mg steps "
    "re-rounded onto 1/1024 g); measured 28 Nov 2026: 1.99x the true model on seed 1"))
def test_the_default_within_1_15x_the_true_model_on_clean_wear(seed1):
    assert seed1["device"] <= 1.15 * seed1["true"], seed1
