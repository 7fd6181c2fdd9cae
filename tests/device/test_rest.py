"""The rest detector against an independent numpy computation of the same definition."""
import numpy as np

from acal.core.rest import RestDetector, mean_q16
from accelcal.fixedpoint import g_to_sample


def expected_segments(q, length, threshold, axis):
    out = []
    for s in range(0, len(q) - length + 1, length):
        seg = q[s:s + length]
        spread = int(seg[:, axis].max() - seg[:, axis].min())
        still = spread < threshold
        means = [int(np.floor(int(seg[:, c].sum()) * 64 / length)) for c in range(3)] if still else None
        out.append((spread, still, means))
    return out


def run_detector(q, rate, seconds, threshold, axis, chunk):
    det = RestDetector(rate, seconds, threshold, axis)
    buf = q.ravel().tolist()
    got = []
    start, n = 0, len(q)
    while n > 0:
        used = det.add_samples(buf, start, min(n, chunk))
        start += used
        n -= used
        if det.ended:
            det.ended = False
            got.append((det.spread, det.still, [det.mean_x, det.mean_y, det.mean_z] if det.still else None))
    return got


def test_matches_definition_any_chunking(rng):
    rate, seconds = 10, 3
    segs = []
    for _ in range(50):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        segs.append(d + rng.normal(scale=rng.choice([0.002, 0.03, 0.3]), size=(rate * seconds, 3)))
    q = g_to_sample(np.concatenate(segs))
    for axis in range(3):
        exp = expected_segments(q, rate * seconds, 123, axis)
        for chunk in (1, 7, 30, 1000):
            assert run_detector(q, rate, seconds, 123, axis, chunk) == exp
    assert any(e[1] for e in exp) and not all(e[1] for e in exp)


def test_threshold_is_strict():
    # max - min exactly at the threshold is not rest; one below is.
    q = np.zeros((10, 3), dtype=np.int64)
    q[3, 0] = 123
    assert run_detector(q, 10, 1, 123, 0, 10)[0][1] is False
    q[3, 0] = 122
    assert run_detector(q, 10, 1, 123, 0, 10)[0][1] is True


def test_single_sample_interface_agrees(rng):
    q = g_to_sample(rng.normal(scale=0.01, size=(200, 3)) + [0, 0, 1])
    det = RestDetector(10, 2)
    means = []
    for x, y, z in q.tolist():
        if det.add(x, y, z) and det.still:
            means.append((det.mean_x, det.mean_y, det.mean_z))
    exp = [tuple(m) for _, s, m in expected_segments(q, 20, det.threshold, 0) if s]
    assert means == exp and len(means) == 10


def test_mean_q16_is_exact_floor(rng):
    for _ in range(2000):
        n = int(rng.integers(1, 65536))
        total = int(rng.integers(-16383 * n, 16383 * n + 1))
        assert mean_q16(total, n) == (total * 64) // n


def test_pipeline_does_not_offer_rest_while_not_worn():
    """The host's non-wear signal (Pipeline.worn): a still segment that closes while it is False
    is counted as excluded and never reaches the bins; the detector itself is unchanged."""
    from acal.core.pipeline import Pipeline
    still = [0, 0, 1024] * 50            # 50 samples = one 5 s segment at 10 Hz
    seen = []
    p = Pipeline(10, on_rest=lambda x, y, z, s: seen.append((x, y, z)))
    p.add_samples(still, 0, 50)
    p.worn = False
    p.add_samples(still, 0, 50)
    p.add_samples(still, 0, 50)
    p.worn = True
    p.add_samples(still, 0, 50)
    assert len(seen) == 2 and p.excluded == 2 and p.rest.segments == 4
    assert p.rest_count == 2
