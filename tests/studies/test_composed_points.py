"""A composed model's points (acal.core.profile.WEAR_COMPOSED_MAX_COUNT, 14 per subset: 126 points
where a base fit keeps 8 per subset, 72), on the held-out wrist benchmark's temperature-gain
seeds (accelcal.studies.heldout: fitted on 3 days, scored on the next 2 days' strict still
windows), the device's base+temp_scale fit against the true sensor model's error.  Before the Q10
format's dither (acal.core.fixed) the rest means carried the rounding's bias and the 72 points
left seed 4 at 1.34x where the 126 brought it within 1.25x.  Since the dither both counts are
within 1.25x on every seed measured, and the contrast is a mean, not a seed: seeds 1-11 (28 Nov
2026) 126 points 1.022, 1.035, 1.022, 1.086, 1.116, 1.031, 1.026, 1.051, 1.018, 1.065, 0.975
(mean 1.041), 72 points 1.039, 1.145, 1.029, 1.054, 1.106, 1.064, 1.052, 1.063, 1.079, 1.045,
0.986 (mean 1.060): the 126 better on 8 of 11, worse on seeds 4, 5, 10.  The default suite holds
the bound on seed 4 (both counts); the slow test holds the mean over seeds 1-6."""
import pytest

from acal.core import profile
from acal.core.gaussnewton import MAX_POINTS
from acal.core.bins import N_SUBSETS
from accelcal.simulate import wearer
from accelcal.studies import heldout


def test_a_composed_model_holds_as_many_points_as_its_fit_is_proven_for():
    composed = profile.settings(profile.WEAR, True)["max_count"] * N_SUBSETS
    assert profile.settings(profile.WEAR)["max_count"] * N_SUBSETS < composed <= MAX_POINTS
    assert MAX_POINTS - composed < N_SUBSETS   # one more per subset would pass the bound


def _ratios(tmp_path, seed):
    """The device's base+temp_scale fit's held-out error over the true model's, with the
    composed model's points (None) and with the base's (WEAR_MAX_COUNT)."""
    whole, fit, test = (tmp_path / f"w{seed}.{x}csv" for x in ("", "fit.", "test."))
    truth = wearer.simulate_wrist(whole, heldout.FIT_DAYS + heldout.TEST_DAYS, heldout.RATE, seed,
                                  effect=["temp_scale"])
    heldout.split(whole, fit, test)
    win = heldout.strict_windows(test)
    true = heldout.true_score_mg(truth, win)
    ratio = {}
    for max_count in (None, profile.WEAR_MAX_COUNT):
        got, why = heldout.device_fit(fit, "wear", "base+temp_scale", max_count=max_count)
        assert why is None, why
        ratio[max_count] = heldout.score_mg(*got, win) / true
    return ratio


def test_a_composed_models_points_hold_a_hard_seed_within_1_25x_the_true_model(tmp_path):
    """Seed 4, the one the 126 points were for (1.34x with 72 before the dither): both counts
    within 1.25x (measured 1.086 and 1.054)."""
    ratio = _ratios(tmp_path, 4)
    assert ratio[None] <= 1.25 and ratio[profile.WEAR_MAX_COUNT] <= 1.25, ratio


@pytest.mark.slow
def test_the_points_of_a_composed_model_lower_the_mean_over_seeds(tmp_path):
    """Seeds 1-6 (minutes): the 126 points' mean ratio below the 72's (measured 1.052 against
    1.073), each within 1.25x."""
    got = [_ratios(tmp_path, seed) for seed in range(1, 7)]
    many = [r[None] for r in got]
    few = [r[profile.WEAR_MAX_COUNT] for r in got]
    assert max(many) <= 1.25 and sum(many) < sum(few), (many, few)


def test_a_step_early_in_the_fit_days_keeps_points_on_both_sides(tmp_path):
    """The benchmark's step seed 4 (a shock 19.4 h into the 3 fit days): the device's base+step
    fit comes within 1.25x the true model.  Its bins keep early points for a time effect
    (acal.core.bins: a spread slot's tie goes to the newest); when they kept the oldest point and the
    latest hours, 8 of 110 fit points were before the shock, the step search placed it 3.5 h
    late, the base fit was kept and scored 1.57x the true model."""
    whole, fit, test = (tmp_path / f"s.{x}csv" for x in ("", "fit.", "test."))
    truth = wearer.simulate_wrist(whole, heldout.FIT_DAYS + heldout.TEST_DAYS, heldout.RATE, 4,
                                  effect=["step"], events_within_days=heldout.FIT_DAYS)
    heldout.split(whole, fit, test)
    win = heldout.strict_windows(test)
    got, why = heldout.device_fit(fit, "wear", "base+step")
    assert why is None, why
    ts = truth["effects"][0]["reference"]["ts"]
    assert abs(got[2]["ts"] - ts) < 3600, (got[2]["ts"], ts)   # placed within the hour
    assert heldout.score_mg(*got, win) <= 1.25 * heldout.true_score_mg(truth, win)
