"""The vectorised twin (accelcal.bridge.twin) against the device modules, bit for bit, on random and
adversarial streams: segment and chunk boundaries, ties at the threshold, clipping, gaps."""
import json

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from acal.core.fixed import C_TEMP, C_TIME, C_SUPPLY
from acal.core.calibration import Calibration
from acal.core.rest import RestDetector
from accelcal.bridge import twin
from conftest import run_cli


def device_segments(q, rate, seconds, threshold, axis, gaps=()):
    """What the device's detector reports, fed sample by sample with resets at gaps."""
    det = RestDetector(rate, seconds, threshold, axis)
    gaps = set(int(g) for g in gaps)
    out = []
    for i, (x, y, z) in enumerate(q.tolist()):
        if i in gaps:
            det.reset()
        if det.add(x, y, z):
            mean = (det.mean_x, det.mean_y, det.mean_z) if det.still else (None,) * 3
            out.append((i, det.still, det.spread, *mean))
    return out


def as_tuples(s: twin.Segments):
    # the device leaves a moving segment's mean unset: compare means of still segments only
    return [(int(e), bool(st_), int(sp), *(map(int, m) if st_ else (None,) * 3)) for e, st_, sp, m in
            zip(s.end, s.still, s.spread, s.mean)]


def stream(draw_values, n):
    return np.array(draw_values, dtype=np.int64).reshape(n, 3)


@st.composite
def streams(draw):
    rate = draw(st.sampled_from([1, 2, 3, 5, 10]))
    seconds = draw(st.integers(1, 4))
    n = draw(st.integers(0, 200))
    kind = draw(st.sampled_from(["random", "near_threshold", "clipped"]))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    threshold = draw(st.sampled_from([0, 1, 50, 123, 400]))   # 0: rest.AUTO, the noise gauge
    if kind == "random":
        q = rng.integers(-2048, 2048, (n, 3))
    elif kind == "near_threshold":  # spreads equal to, one under and one over the threshold
        base = rng.integers(-1024, 1024, 3)
        q = base + rng.integers(0, max(threshold, 8) + 2, (n, 3)) * rng.integers(0, 2, (n, 1))
    else:  # clipped at +-2 g (12-bit), and the +-16 g extremes
        q = np.clip(rng.integers(-2600, 2600, (n, 3)), -2048, 2047)
        if n:
            q[rng.integers(0, n, max(1, n // 10))] = rng.choice([-16383, 16383], 3)
    gaps = sorted(set(rng.integers(0, n + 1, draw(st.integers(0, 4))).tolist())) if n else []
    chunk = draw(st.one_of(st.none(), st.integers(1, 60)))
    axis = draw(st.integers(0, 3))   # 3: rest.ALL_AXES
    return q.astype(np.int64), rate, seconds, threshold, axis, gaps, chunk


@settings(max_examples=300, deadline=None)
@given(streams())
def test_rest_segments_equal_the_device_detector(case):
    q, rate, seconds, threshold, axis, gaps, chunk = case
    dev = device_segments(q, rate, seconds, threshold, axis, gaps)
    vec = twin.rest_segments(q, rate, seconds, threshold, axis, gaps, chunk)
    assert as_tuples(vec) == dev
    # every axis's min and max (the host's quality checks), against the segment's own samples
    length = rate * seconds
    for e, lo, hi in zip(vec.end, vec.lo, vec.hi):
        w = q[e - length + 1:e + 1]
        assert (lo == w.min(axis=0)).all() and (hi == w.max(axis=0)).all()


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(1, 3000), st.integers(1, 700))
def test_noise_gauge_twin_equals_the_device_gauge(seed, n, chunk):
    """The threshold every segment is judged by: the device's NoiseGauge, one spread at a time,
    against the twin's over arrays fed in chunks (updates, halving, spreads of 0 and >= 128)."""
    from acal.core.rest import NoiseGauge
    rng = np.random.default_rng(seed)
    spread = rng.choice([0, 1, 2, 3, 5, 9, 40, 127, 128, 900], n, p=[.05, .2, .2, .2, .1, .1, .05,
                                                                    .04, .03, .03])
    spread = np.where(rng.random(n) < 0.3, rng.integers(0, 140, n), spread).astype(np.int64)
    dev, g = [], NoiseGauge()
    for s in spread.tolist():
        dev.append(g.threshold)
        g.add(s)
    gauge = twin.NoiseGaugeTwin()
    got = np.concatenate([gauge.thresholds(spread[a:a + chunk]) for a in range(0, n, chunk)])
    assert got.tolist() == dev
    assert (gauge.threshold, gauge.level, gauge.count, gauge.seen) == (g.threshold, g.level, g.count, g.seen)
    assert gauge.hist.tolist() == g.hist


def test_noise_gauge_halves_its_counts():
    from acal.core.rest import NOISE_HALVE, NoiseGauge
    g = NoiseGauge()
    for _ in range(NOISE_HALVE + 40):
        g.add(3)
    assert g.count < NOISE_HALVE and g.threshold == 3 * 2 + 2


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.sampled_from([1, 2, 7, 128, 512]), st.integers(50, 40_000))
def test_noise_gauge_twin_through_many_halvings(seed, at_once, chunk):
    """Updates computed together (NoiseGaugeTwin.AT_ONCE at a time, up to each halving) over
    ~7 halvings of the counts: the device's NoiseGauge's thresholds and state, whatever the
    chunks and the number computed at once."""
    from acal.core.rest import NoiseGauge
    rng = np.random.default_rng(seed)
    n = 60_000
    level = np.repeat(rng.integers(1, 40, 12), n // 12)          # the sensor's noise changes
    spread = np.where(rng.random(n) < 0.1, rng.integers(0, 200, n),
                      rng.poisson(level)).astype(np.int64)
    dev, g = [], NoiseGauge()
    for s in spread.tolist():
        dev.append(g.threshold)
        g.add(s)
    gauge = twin.NoiseGaugeTwin()
    gauge.AT_ONCE = at_once
    got = np.concatenate([gauge.thresholds(spread[a:a + chunk]) for a in range(0, n, chunk)])
    assert got.tolist() == dev and len(set(dev)) > 5
    assert (gauge.threshold, gauge.level, gauge.count, gauge.seen) == (g.threshold, g.level, g.count, g.seen)
    assert gauge.hist.tolist() == g.hist


def test_chunking_never_changes_the_segments(rng):
    q = rng.integers(-1100, 1100, (10_007, 3))
    q[2000:4500] = rng.integers(-10, 10, (2500, 3)) + [0, 0, 1024]   # a long rest
    gaps = [0, 1234, 5000, 5001, 9999]
    whole = as_tuples(twin.rest_segments(q, 10, 5, 123, 0, gaps))
    assert whole == device_segments(q, 10, 5, 123, 0, gaps)
    assert sum(s[1] for s in whole) >= 40
    for chunk in (1, 7, 49, 50, 51, 999, 10_007):
        assert as_tuples(twin.rest_segments(q, 10, 5, 123, 0, gaps, chunk)) == whole


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-(1 << 24) // 4, (1 << 24) // 4), min_size=6, max_size=6),
       st.lists(st.integers(750, 1250), min_size=3, max_size=3), st.integers(0, 2 ** 32 - 1),
       st.sampled_from([2, 4, 8, 16]))
def test_apply_equals_the_device_calibration(off, diag, seed, range_g):
    rng = np.random.default_rng(seed)
    # Q24 parameters inside the calibration bounds: k_ii 0.75..1.25, |k_ij| <= 0.125, |o| <= 0.25 g
    p = [d * (1 << 24) // 1000 for d in diag] + [v // 2 for v in off[:3]] + off[3:]
    fs = 2048 * range_g // 2   # the range's full scale, and readings past it (clamped)
    q = np.r_[rng.integers(-fs, fs, (200, 3)), [[fs - 1] * 3, [-fs] * 3], rng.integers(-16383, 16384, (20, 3))]
    cal = Calibration(range_g=range_g)
    cal.set(p)
    buf = q.ravel().tolist()
    cal.apply_samples(buf, 0, len(q))
    assert (twin.apply_params(p, q, range_g=range_g) == np.array(buf).reshape(-1, 3)).all()


@pytest.mark.parametrize("range_g", [2, 8])
def test_the_apps_calibrated_blocks_are_the_twins(rng, range_g, tmp_path):
    """What the app hands on_samples (Processor.feed: the block copied and applied in one pass)
    is the twin's output at the board's full scale, in Q(13 - e) g."""
    from array import array
    from acal.core import fixed
    from acal.logger import log
    from acal.logger.processor import Processor
    p = [int(v) for v in rng.integers(15 << 20, 17 << 20, 3)] + \
        [int(v) for v in rng.integers(-(1 << 20), 1 << 20, 6)]
    proc = Processor(log.Log(str(tmp_path / "log.bin")), 100, range_g=range_g)
    proc.calibration.set(p)
    proc.calibrations = 1
    got = []
    proc.on_samples = lambda buf, n: got.extend(buf[:3 * n])
    n = log.SAMPLES_PER_RECORD
    q = rng.integers(-1100 * range_g, 1100 * range_g, (4 * n, 3))
    for b in range(4):
        proc.feed(array("i", q[b * n:(b + 1) * n].ravel().tolist()), n)
    assert proc.calibration.out_q == fixed.apply_out_q(range_g)
    assert (np.array(got).reshape(-1, 3) == twin.apply_params(p, q, range_g=range_g)).all()


@st.composite
def composed_cases(draw):
    """A composed model of any of the device's effects inside the calibration bounds at any full
    scale, samples to the extremes, dT, dt and the supply's dV past the device's clamps, a step's
    time anywhere."""
    from acal.core import effects as deff
    kinds = draw(st.lists(st.sampled_from(sorted(deff.NAMES)), min_size=1, max_size=4, unique=True))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    one = 1 << 24
    p = [int(v) for v in rng.integers(3 * one // 4, 5 * one // 4, 3)]
    p += [int(v) for v in rng.integers(-one // 8, one // 8, 3)] + [int(v) for v in rng.integers(-one // 4, one // 4, 3)]
    for k in kinds:
        b = deff.BOUNDS[k]
        p += [int(v) for v in rng.choice([-b, b, *rng.integers(-b, b, 3)], 3)]
    range_g = draw(st.sampled_from([2, 4, 8, 16]))
    n = 300
    fs = 1024 * range_g
    q = rng.integers(-fs, fs, (n, 3))
    q[:8] = rng.choice([-16383, -fs, fs - 1, 16383], (8, 3))
    dT = rng.integers(-50, 51, n)
    dt = rng.integers(-(1 << 21), 1 << 21, n)
    dt[n // 2:] = rng.integers(-(1 << 15), 1 << 15, n - n // 2)   # inside the generic clamp too
    step_time = int(rng.integers(-(1 << 15), 1 << 15))
    dV = rng.integers(-3000, 3001, n)
    return tuple(kinds), p, q.astype(np.int64), dT, dt, step_time, dV, range_g


@settings(max_examples=150, deadline=None)
@given(composed_cases())
def test_composed_apply_equals_the_device_calibration(case):
    kinds, p, q, dT, dt, step_time, dV, range_g = case
    cal = Calibration(kinds, range_g)
    cal.set(p, (0, 0, 120), step_time)
    dev = []
    for (x, y, z), a, b, c in zip(q.tolist(), dT.tolist(), dt.tolist(), dV.tolist()):
        cal.now[C_TEMP], cal.now[C_TIME], cal.now[C_SUPPLY] = a, b, c + 120
        cal.apply(x, y, z)
        dev.append((cal.x, cal.y, cal.z))
    assert (twin.apply_params(p, q, kinds, dT, dt, range_g, step_time, dV) == np.array(dev)).all()
    # and the block form (apply_samples) gives the one-sample form's integers
    cal.now[C_TEMP], cal.now[C_TIME], cal.now[C_SUPPLY] = int(dT[-1]), int(dt[-1]), int(dV[-1]) + 120
    buf = q[-50:].ravel().tolist()
    cal.apply_samples(buf, 0, 50)
    assert (np.array(buf).reshape(-1, 3)[-1] == dev[-1]).all()


def _with_gaps(src, dst):
    """The recording with two stretches removed (gaps in t), one of them mid-segment."""
    lines = src.read_text().splitlines(keepends=True)
    keep = lines[:1] + lines[1:200_003] + lines[230_017:600_000] + lines[601_234:]
    dst.write_text("".join(keep))
    return dst


@pytest.mark.parametrize("model", ["base", "base+temp_offset"])
def test_calibrate_engines_give_identical_results(tmp_path, model):
    rec = tmp_path / "day.csv"
    args = ["simulate", "wrist", "--days", 1, "--rate", 10, "--seed", 17, "-o", rec]
    if model != "base":
        args += ["--effect", "temp_offset"]
    assert run_cli(*args).returncode == 0
    rec = _with_gaps(rec, tmp_path / "gaps.csv")
    out = {}
    for engine in ("vector", "device"):
        r = run_cli("calibrate", rec, "--model", model, "--engine", engine, "--json")
        assert r.returncode in (0, 2), r.stderr
        out[engine] = (r.returncode, r.stdout, r.stderr)
    assert out["vector"] == out["device"]
    rec = json.loads(out["vector"][1])
    assert rec["rest_points"] > 1000
    # the device engine was told to exclude the same non-wear segments (W lines)
    assert rec["excluded"]["nonwear"] > 20 and rec["gaps"] == 2


def test_streaming_scan_memory_does_not_grow_with_the_file(tmp_path, monkeypatch):
    """Arrow's blocks go through one at a time: the memory numpy holds while scanning a file
    three times as long is what one block needs (tracemalloc counts numpy's buffers).

    The read-ahead thread is taken out here (its queue's bound is the next test's): with it, the
    number of chunks alive at once depends on how the two threads are scheduled, and a longer
    file only has more chances to meet the worst case (peaks of 4.5 against 7 MB were seen on a
    loaded machine), which is not growth with the file."""
    import tracemalloc

    from accelcal.files.recordings import open_recording
    from accelcal.pipeline import scan as scan_module
    from accelcal.pipeline.scan import scan
    monkeypatch.setattr(scan_module, "prefetched", lambda chunks, **how: chunks)
    rng = np.random.default_rng(3)
    peaks = []
    for n in (1_000_000, 3_000_000):
        f = tmp_path / f"r{n}.csv"
        t = np.arange(n) / 100
        v = np.round(rng.normal([0, 0, 1], 0.002, (n, 3)), 3)
        np.savetxt(f, np.column_stack([t, v]), fmt=["%.2f", "%.3f", "%.3f", "%.3f"], delimiter=",",
                   header="t,x,y,z", comments="")
        tracemalloc.start()
        sc = scan(open_recording(f), 5, 123, 0)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert sc.n_samples == n and sc.segments.still.sum() == n // 500
    assert peaks[1] < 1.3 * peaks[0], peaks
    assert peaks[0] < 150e6


def test_read_ahead_holds_at_most_its_depth():
    """prefetched() reads ahead by at most `depth` chunks whatever the pace of its consumer, and
    hands over the same chunks in the same order."""
    import time

    from accelcal.pipeline.scan import prefetched
    produced = []

    def chunks():
        for i in range(20):
            produced.append(i)
            yield i

    got = []
    for ch in prefetched(chunks(), depth=2):
        time.sleep(0.01)    # a slow consumer: the reader fills the queue and waits
        # the reader may hold one more, made and waiting to be put
        assert len(produced) - len(got) <= 2 + 2, (len(produced), len(got))
        got.append(ch)
    assert got == list(range(20))


def test_planar_of_a_readers_axes_is_samples_planar_to_the_bit():
    """twin.planar_of converts (n, 3) float32 (actfast's) or float64 arrays in their own dtype
    and three columns as they are: the same Q10 samples as samples_planar of float64 columns,
    rounding ties, the clip at +-16 g and signed zeros included."""
    rng = np.random.default_rng(11)
    n = 20_000
    g = np.concatenate([rng.normal(0, 3, n), rng.uniform(-40, 40, n),
                        (rng.integers(-20000, 20000, n) + 0.5) / 1024,     # exact ties
                        np.array([-0.0, 0.0, 16.0, -16.0, 15.9995, -16.0005, 256.0, -256.0])])
    g = g[: len(g) // 3 * 3].reshape(-1, 3)
    for xyz in (g, g.astype(np.float32)):
        want = twin.samples_planar(*(xyz[:, i].astype(np.float64) for i in range(3)))
        got = twin.planar_of(xyz)
        assert got.dtype == np.int32 and got.flags.c_contiguous
        assert np.array_equal(got, want)
        assert np.array_equal(twin.planar_of(tuple(xyz[:, i].astype(np.float64) for i in range(3))),
                              want)
