"""The .cwa reader's held temperature index (files/recordings.py held_index): one pass, the same
index as a binary search per sample."""
import numpy as np

from accelcal.files.recordings import held_index


def test_held_index_is_the_last_reading_at_or_before_each_sample():
    rng = np.random.default_rng(0)
    for _ in range(2000):
        # coarse integer times: many ties between samples and readings, readings before the
        # first sample and after the last, several readings at one time
        t = np.sort(rng.integers(0, 30, rng.integers(0, 50))).astype(float)
        tl = np.sort(rng.integers(-5, 35, rng.integers(1, 10))).astype(float)
        want = np.clip(np.searchsorted(tl, t, side="right") - 1, 0, None)
        got = held_index(tl, t)
        assert got.shape == want.shape and (got == want).all(), (t, tl, got, want)
