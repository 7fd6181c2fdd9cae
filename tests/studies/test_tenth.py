"""Where the last tenth goes (issue 50 part 5, accelcal.studies.tenth): on a clean held-back
wrist (seed 1), scored on the recording's own values, float least squares on every rest point
reaches the true sensor model and on the bins' points comes within 10 % of it (the bins' choice
of points costs little); the default's fit, on the device's Q10 samples rounded with the
format's dither (acal.core.fixed.DITHER_STEP), comes within 1.15x, as does its fit offered the
file's own means; rounded to the nearest LSB (the format before) the same fit does not: the
1 mg steps re-rounded onto 1/1024 g were the last tenth (measured 28 Nov 2026: device 1.10x,
device_file 1.09x, device_nearest 2.00x, lsq_bins 1.07x).  The written output (apply's path)
within 1.15x on every seed of the table, since the base apply keeps K o exact and rounds its
output with a dither (fixed.py "apply").  The default suite checks the roundings themselves
(tests/test_fixedpoint.py, tests/device/test_ranges.py's still window's mean)."""
import pytest

pytestmark = pytest.mark.slow   # ~15 s: a 5-day simulation and five fits


@pytest.fixture(scope="module")
def seed1(tmp_path_factory):
    from accelcal.studies import tenth
    return tenth.run_seed(1, tmp_path_factory.mktemp("tenth"), auto=True)


def test_the_float_fits_and_the_unrounded_device_fit_reach_the_true_model(seed1):
    r = seed1
    assert r["lsq_all"] <= 1.02 * r["true"], r
    assert r["lsq_bins"] <= 1.10 * r["true"], r
    assert r["device_file"] <= 1.15 * r["true"], r
    # the format before the dither: the nearest LSB's bias in every rest mean, fitted
    assert r["device_nearest"] > 1.5 * r["true"], r
    # the written output (apply's path) carries the input's rounding: with the dither under
    # half the nearest LSB's error (measured: 1.12x against 4.2x the true model); what it keeps
    # over the fit is the Q10 input's dither and the Q13 output's (docs/real-recordings.md)
    assert r["output"] < 0.5 * r["output_nearest"], r
    assert r["output"] >= r["device"] and abs(r["device_q10_windows"] - r["device"]) < 0.01, r


def test_the_written_output_within_1_15x_the_true_model_on_every_seed(seed1, tmp_path):
    """The issue's goal scored on the written output, on the 8 seeds of the reference's table
    (measured 28 Nov 2026: 1.05-1.12x, mean 1.08; 1.07-1.34 with the apply's Q14 offsets and
    nearest-LSB output).  ~2 min."""
    from accelcal.studies import tenth
    rows = [seed1] + [tenth.run_seed(s, tmp_path) for s in range(2, 9)]
    over = {r["seed"]: round(r["output"] / r["true"], 3) for r in rows}
    assert max(over.values()) <= 1.15, over


def test_auto_over_base_on_clean_wear_follows_the_rounding(seed1):
    """The default's auto model over the paper's model on this clean seed: within 5 % on the
    dithered Q10 means (measured 28 Nov 2026: 0.958), 1.18 on nearest-LSB means (the rounding's
    share, fitted by three more parameters)."""
    assert abs(seed1["auto_over_base"] - 1) <= 0.05, seed1
    assert abs(seed1["auto_over_base_nearest"] - 1) > abs(seed1["auto_over_base"] - 1), seed1


def test_the_default_within_1_15x_the_true_model_on_clean_wear(seed1):
    assert seed1["device"] <= 1.15 * seed1["true"], seed1
