"""The device's sample format on the host (accelcal.fixedpoint.g_to_sample, twin.planar_of): the
rounding onto Q10 with the format's dither (acal.core.fixed.DITHER_STEP, issue 50 part 5).  A
still window's mean of a source's 1 mg steps survives the re-rounding onto 1/1024 g (the
nearest LSB kept up to 0.49 mg of it, the same in every window of a posture); the samples
depend only on each sample's index in its stream (chunks give the whole's), on neither the
float's width nor anything else; a value on the Q10 grid is kept as it is."""
import numpy as np

from acal.core import fixed
from accelcal.bridge import twin
from accelcal.fixedpoint import dither, g_to_sample


def test_a_still_windows_mean_keeps_the_sources_1_mg_steps(rng):
    """Every 1 mg value of +-2 g, a 5 s window at 10 Hz of a still sensor (0.49 mg of noise,
    written in the LIS3DH's 1 mg digits) at a random place in a stream: its mean of Q10 samples
    is the mean of the source's values within 0.06 mg (the dither's Weyl sequence over 50
    samples), against up to 0.4 mg rounded to the nearest LSB (the reference, np.rint)."""
    k = np.arange(-2048, 2048)
    n = 50
    src = np.round(k[:, None] + rng.normal(scale=0.49, size=(len(k), n))) / 1000.0   # g, 1 mg
    own = src.mean(axis=1)
    ours, near = [], []
    for i, w in enumerate(src):
        first = int(rng.integers(0, 10 ** 7))
        ours.append(g_to_sample(w[:, None], first).mean() / fixed.SAMPLE_ONE_G)
        near.append(np.rint(w * fixed.SAMPLE_ONE_G).mean() / fixed.SAMPLE_ONE_G)
    err = (np.array(ours) - own) * 1e3
    err_near = (np.array(near) - own) * 1e3
    assert np.abs(err).max() < 0.06 and abs(err.mean()) < 0.005, (np.abs(err).max(), err.mean())
    assert np.abs(err_near).max() > 0.3        # what the format's rounding was


def test_each_sample_is_its_index_in_the_stream_and_chunks_give_the_whole(rng):
    """floor(g * 1024 + d_i), d_i = ((i * DITHER_STEP) & DITHER_MASK) / 2**14 (the definition,
    in floats); a stream in chunks, each given its first index, gives the whole stream's
    samples; planar_of gives the same, from float32 as from its float64 copy; |error| < 1 LSB."""
    g = rng.normal(scale=0.7, size=(10_000, 3))
    whole = g_to_sample(g)
    i = np.arange(len(g))
    want = np.floor(g * 1024 + (((i * 10127) % 16384) / 16384.0)[:, None])
    assert np.array_equal(whole, want)
    assert np.array_equal(dither(0, len(g)), (i * fixed.DITHER_STEP) & fixed.DITHER_MASK)
    assert len(np.unique(dither(0, 1 << 14))) == 1 << 14        # the step is odd: every value
    cuts = [0, 1, 333, 4096, 7777, len(g)]
    parts = [g_to_sample(g[a:b], a) for a, b in zip(cuts[:-1], cuts[1:])]
    assert np.array_equal(np.vstack(parts), whole)
    assert np.array_equal(twin.planar_of(g).T, whole)
    assert np.array_equal(twin.planar_of(tuple(g.T)).T, whole)
    g32 = g.astype(np.float32)
    assert np.array_equal(twin.planar_of(g32), twin.planar_of(g32.astype(np.float64)))
    assert np.abs(whole / 1024.0 - g).max() < 1 / 1024


def test_values_on_the_grid_are_kept_and_the_range_clipped():
    """A .cwa's 1/256 g, a board's logged Q10 samples: every value on the grid stays itself
    whatever the dither; past +-16 g the samples clip at SAMPLE_MAX."""
    q = np.arange(-fixed.SAMPLE_MAX, fixed.SAMPLE_MAX + 1)
    g = np.column_stack([q, q[::-1], np.roll(q, 5)]) / 1024.0
    assert np.array_equal(g_to_sample(g, 123_456), (g * 1024).astype(np.int64))
    big = np.array([[20.0, -20.0, 16.0], [1e9, -1e9, 0.0]])
    assert g_to_sample(big, 7).tolist() == [[16383, -16383, 16383], [16383, -16383, 0]]
