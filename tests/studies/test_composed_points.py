"""A composed model's points (acal.core.profile.WEAR_COMPOSED_MAX_COUNT, 14 per subset): on the
held-out wrist benchmark's temperature-gain seed 4 (accelcal.studies.heldout: fitted on 3 days,
scored on the next 2 days' strict still windows), the device's base+temp_scale fit on its 126
points comes within 1.25x the true sensor model's error, where the 72 points (8 per subset) it
had left it above (1.34x, docs/model-discovery.md "Points for a composed model") while the rest
means carried the Q10 rounding's bias.  Since the format's dither (acal.core.fixed) the 72 points
are within it too (measured: 1.054x, and 1.086x on the 126), so only the 126's bound is held."""
from acal.core import profile
from acal.core.gaussnewton import MAX_POINTS
from acal.core.bins import N_SUBSETS
from accelcal.simulate import wearer
from accelcal.studies import heldout


def test_a_composed_model_holds_as_many_points_as_its_fit_is_proven_for():
    composed = profile.settings(profile.WEAR, True)["max_count"] * N_SUBSETS
    assert profile.settings(profile.WEAR)["max_count"] * N_SUBSETS < composed <= MAX_POINTS
    assert MAX_POINTS - composed < N_SUBSETS   # one more per subset would pass the bound


def test_the_points_of_a_composed_model_bring_a_hard_seed_within_1_25x_the_true_model(tmp_path):
    whole, fit, test = (tmp_path / f"w.{x}csv" for x in ("", "fit.", "test."))
    truth = wearer.simulate_wrist(whole, heldout.FIT_DAYS + heldout.TEST_DAYS, heldout.RATE, 4,
                                  effect=["temp_scale"])
    heldout.split(whole, fit, test)
    win = heldout.strict_windows(test)
    true = heldout.true_score_mg(truth, win)
    ratio = {}
    for max_count in (None, profile.WEAR_MAX_COUNT):
        got, why = heldout.device_fit(fit, "wear", "base+temp_scale", max_count=max_count)
        assert why is None, why
        ratio[max_count] = heldout.score_mg(*got, win) / true
    print(ratio)
    assert ratio[None] <= 1.25 and ratio[profile.WEAR_MAX_COUNT] <= 1.25, ratio


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
