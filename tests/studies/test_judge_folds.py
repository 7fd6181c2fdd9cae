"""studies/judge_folds.py's selection: what the device's bins keep of rest points, the points a
judge "as the device fits" is fitted on (docs/model-discovery.md "Curves", curve seed 4).  The
bins' spread slots keep each subset's temperature extremes, so a rare cold spell is held far
beyond its share of the rest points: the chord that makes a straight line misfit a curve."""
import numpy as np

from acal.core import profile
from accelcal.model.effects import ModelSpec
from accelcal.pipeline.restpoints import RestPoints
from accelcal.simulate.scenarios import unit_points
from accelcal.pipeline.foldjudge import bins_selection


def test_the_bins_keep_input_points_and_over_hold_a_rare_cold_spell():
    rng = np.random.default_rng(4)
    n = 3000
    v = unit_points(rng, n)
    temp = rng.uniform(31.0, 35.5, n)
    cold = rng.random(n) < 0.02   # a rare cold spell, as a shower off the wrist
    temp[cold] = rng.uniform(25.0, 28.0, cold.sum())
    t = np.arange(n) * 60.0
    sel = bins_selection(ModelSpec.parse("base+temp_offset"), RestPoints(v, t, temp, np.zeros(n), "x"))
    most = profile.settings(profile.WEAR, True)["max_count"]   # the wear profile's composed bins
    assert 27 <= len(sel) <= 9 * most
    # every kept point is an input point (Q16 g), at its own temperature (Q2 degC)
    d = np.abs(sel.v[:, None, :] - v[None, :, :]).max(axis=2)
    j = d.argmin(axis=1)
    assert np.all(d[np.arange(len(sel)), j] <= 1 / 65536)
    assert np.all(np.abs(sel.temp - temp[j]) <= 0.125)
    # the cold spell is held well beyond its 2 % share: the spread slots keep extremes
    assert np.mean(sel.temp < 30) > 0.08
