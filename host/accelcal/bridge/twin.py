"""The vectorised numpy twin of the device's per-sample stages, for files of weeks at 100 Hz.

Not a second implementation of the method: the twin of acal.core.rest.RestDetector (segmenting, the
max - min rest test on one axis or all, the noise gauge's threshold, per-axis sums, Q16 means) and of acal.core.calibration.Calibration.apply_samples for
the paper's model and composed ones, on int64 arrays, tied to those modules by bit-exact tests
(tests/bridge/test_vector.py, property-based).  The bins and the optimiser are not per-sample: the rest
means go to the device's own Pipeline.offer in stream order.

Integer formats as the device's (device/acal/core/fixed.py): samples Q10 g, sums < 2^30 (segments of
<= 65 535 samples), means Q16 = floor(sum * 2^6 / n) (the device computes the same floor in two
steps to stay below 2^30; int64 needs no such care), parameters Q24 -> the apply's (K Q14,
offsets Q(14 - e)), calibrated samples Q(13 - e) g at the full scale's shift e.

Streaming: RestStream.feed takes consecutive chunks; the open segment's samples (fewer than one
segment) carry over to the next chunk, as the device's detector carries lo/hi/sums across FIFO
reads, so any chunking gives the same segments as one pass.  A gap drops the open segment (the
device's reset()).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acal.core import effects as deff
from acal.core import fixed
from acal.core import rest as drest
from acal.core.calibration import _base_params
from acal.core.rest import ALL_AXES, AUTO, DEFAULT_SECONDS, DEFAULT_THRESHOLD
from accelcal import fixedpoint


@dataclass
class Segments:
    """Closed segments of one feed, in stream order.  Besides what the device's detector
    reports (end, still, spread, mean), every axis's min and max: the host's quality checks
    (non-wear, imputed constants, clipping) read them; the device's rest test does not."""
    end: np.ndarray      # (n,) int64: stream index of each segment's last sample
    still: np.ndarray    # (n,) bool
    spread: np.ndarray   # (n,) int64: max - min of the rest axis (ALL_AXES: the largest), Q10 g
    mean: np.ndarray     # (n, 3) int64: Q16 g (meaningful where still)
    lo: np.ndarray       # (n, 3) int64: each axis's min, Q10 g
    hi: np.ndarray       # (n, 3) int64: each axis's max, Q10 g
    extra: np.ndarray    # (n, k) float64: sums of the feeder's extra per-sample columns (k >= 0)
    threshold: np.ndarray  # (n,) int64: the threshold each segment was judged by, Q10 g

    FIELDS = ("end", "still", "spread", "mean", "lo", "hi", "extra", "threshold")

    @staticmethod
    def empty(k: int = 0) -> "Segments":
        z3 = np.zeros((0, 3), np.int64)
        return Segments(np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, np.int64), z3, z3, z3,
                        np.zeros((0, k)), np.zeros(0, np.int64))

    @staticmethod
    def concat(parts: list["Segments"]) -> "Segments":
        if not parts:
            return Segments.empty()
        return Segments(*(np.concatenate([getattr(p, f) for p in parts]) for f in Segments.FIELDS))

    def take(self, sel) -> "Segments":
        return Segments(*(getattr(self, f)[sel] for f in Segments.FIELDS))

    def __len__(self):
        return len(self.end)


class NoiseGaugeTwin:
    """The twin of acal.core.rest.NoiseGauge over arrays of spreads: the threshold each segment is
    judged by, the gauge's state carried from call to call (bit-exact: tests/bridge/test_vector.py)."""

    def __init__(self):
        self.hist = np.zeros(drest.NOISE_BINS, np.int64)
        self.count = 0
        self.seen = 0
        self.threshold = 0
        self.level = 0

    def thresholds(self, spread: np.ndarray) -> np.ndarray:
        """Per segment (in stream order): the threshold in force when it closed; then its
        spread counted, as RestDetector._close does.  The updates (every NOISE_EVERY quiet
        segments) are computed together up to the next halving of the counts: each one's
        histogram is the running sum of what was counted since (a few hundred updates at once,
        not one Python step each: 0.2 s of a 3-day 10 Hz file's 1 s)."""
        out = np.empty(len(spread), np.int64)
        quiet = np.flatnonzero((spread > 0) & (spread < drest.NOISE_BINS))
        vals = spread[quiet]
        every = drest.NOISE_EVERY
        # the quiet segments at which an update happens (after it has been counted): their
        # place among the quiet ones and among all
        first = (every - self.seen % every) - 1
        ev_q = np.arange(first, len(quiet), every)
        events = quiet[ev_q]
        prev_seg = 0
        prev_q = 0
        j = 0
        while j < len(events):
            stop, thr = self._updates(vals, prev_q, ev_q[j:j + self.AT_ONCE] + 1)
            bounds = np.r_[prev_seg, events[j:j + stop] + 1]
            out[prev_seg:bounds[-1]] = np.repeat(np.r_[self.threshold, thr[:stop - 1]],
                                                 np.diff(bounds))   # judged before each update
            self.threshold = int(thr[stop - 1])
            prev_seg, prev_q = int(bounds[-1]), int(ev_q[j + stop - 1]) + 1
            j += stop
        out[prev_seg:] = self.threshold
        self._count(vals[prev_q:])
        return out

    AT_ONCE = 512      # updates computed together at most (a halving comes every ~128)

    def _updates(self, vals: np.ndarray, start: int, ends: np.ndarray):
        """The updates after counting vals[start:ends[i]] for each i, up to and with the first
        that halves the counts: (how many, their thresholds); the state as after the last."""
        bins = drest.NOISE_BINS
        n = len(ends)
        sizes = np.diff(np.r_[start, ends])
        rows = np.repeat(np.arange(n), sizes)
        added = np.bincount(rows * bins + vals[start:ends[-1]], minlength=n * bins).reshape(n, bins)
        hist = self.hist + np.cumsum(added, axis=0)           # each update's histogram
        count = self.count + np.cumsum(sizes)
        need = (count + drest.NOISE_QUANTILE - 1) // drest.NOISE_QUANTILE
        # the first bin whose running count reaches need (0 when need is 0): searchsorted's
        q = (np.cumsum(hist, axis=1) < need[:, None]).sum(axis=1)
        thr = np.clip(drest.NOISE_MUL * q + drest.NOISE_ADD, drest.THRESHOLD_MIN,
                      drest.THRESHOLD_MAX)
        halves = np.flatnonzero(count >= drest.NOISE_HALVE)
        stop = int(halves[0]) + 1 if len(halves) else n
        self.hist = hist[stop - 1].copy()
        self.count = int(count[stop - 1])
        self.seen += int(ends[stop - 1] - start)
        self.level = int(q[stop - 1])
        if self.count >= drest.NOISE_HALVE:
            self.hist >>= 1
            self.count = int(self.hist.sum())
        return stop, thr

    def _count(self, v: np.ndarray) -> None:
        if len(v):
            self.hist += np.bincount(v, minlength=drest.NOISE_BINS)
            self.count += len(v)
            self.seen += len(v)


def segment_stats(p: np.ndarray, length: int, threshold: int, axis: int, first: int,
                  extra: np.ndarray | None = None, gauge: NoiseGaugeTwin | None = None) -> Segments:
    """Every full segment of a contiguous run p (3 x m Q10 ints, planar: one row per axis, m a
    multiple of length) that starts at stream index `first`; extra (k x m floats): summed per
    segment too.  axis ALL_AXES: the largest spread of the three; threshold AUTO: the gauge's."""
    n = p.shape[1] // length
    k = 0 if extra is None else extra.shape[0]
    ext = (extra[:, : n * length].reshape(k, n, length).sum(axis=2).T if k
           else np.zeros((n, 0)))
    seg = p[:, : n * length].reshape(3, n, length)
    lo = seg.min(axis=2).T.astype(np.int64)
    hi = seg.max(axis=2).T.astype(np.int64)
    sums = seg.sum(axis=2, dtype=np.int64).T
    mean = (sums << fixed.POINT_FROM_SAMPLE_SHIFT) // length   # floor, as mean_q16
    spread = (hi - lo).max(axis=1) if axis == ALL_AXES else hi[:, axis] - lo[:, axis]
    end = first + (np.arange(1, n + 1, dtype=np.int64) * length) - 1
    thr = gauge.thresholds(spread) if threshold == AUTO else np.full(n, threshold, np.int64)
    return Segments(end, spread < thr, spread, mean, lo, hi, ext, thr)


class RestStream:
    """The device's RestDetector over numpy chunks.  rate_hz, seconds, threshold (Q10 g), axis
    as RestDetector."""

    def __init__(self, rate_hz: int, seconds: int = DEFAULT_SECONDS, threshold: int = DEFAULT_THRESHOLD,
                 axis: int = 0):
        length = rate_hz * seconds
        if length < 1 or length > fixed.SEGMENT_MAX_SAMPLES:
            raise ValueError("segment must hold 1..65535 samples")
        if axis not in (0, 1, 2, ALL_AXES):
            raise ValueError("axis must be 0, 1, 2 or ALL_AXES")
        self.length, self.threshold, self.axis = length, threshold, axis
        self.gauge = NoiseGaugeTwin() if threshold == AUTO else None
        self.pending = np.zeros((3, 0), np.int32)   # the open segment's samples, planar
        self.pending_extra = None                   # and their extra columns, if fed any
        self.position = 0                           # stream index of the next sample

    def feed(self, q: np.ndarray, gaps=()) -> Segments:
        """q: the next chunk (m x 3 Q10 ints); gaps: chunk-relative indices where a new
        contiguous run starts (the open segment is dropped there, as by RestDetector.reset())."""
        return self.feed_planar(np.ascontiguousarray(np.asarray(q, dtype=np.int32).reshape(-1, 3).T), gaps)

    def feed_planar(self, p: np.ndarray, gaps=(), extra: np.ndarray | None = None) -> Segments:
        """As feed, with the chunk planar: 3 x m Q10 ints (int32: |sample| < 2**14).  extra:
        k x m floats per sample (the host's: time, temperature, |v|...) summed per segment
        (Segments.extra); the same k on every call."""
        m = p.shape[1]
        cuts = [0, *sorted(int(g) for g in gaps if 0 <= g <= m), m]
        parts = []
        starts_run = set(cuts[1:-1])
        if extra is not None and self.pending_extra is None:
            self.pending_extra = np.zeros((extra.shape[0], 0))
        for k, (a, b) in enumerate(zip(cuts[:-1], cuts[1:])):
            run = p[:, a:b]
            ext = None if extra is None else extra[:, a:b]
            if k == 0 and a not in starts_run:   # continues the open segment
                first = self.position - self.pending.shape[1]
                if self.pending.shape[1]:
                    run = np.concatenate([self.pending, run], axis=1)
                    if ext is not None:
                        ext = np.concatenate([self.pending_extra, ext], axis=1)
            else:
                first = self.position + a
            full = (run.shape[1] // self.length) * self.length
            if full:
                parts.append(segment_stats(run[:, :full], self.length, self.threshold, self.axis,
                                           first, None if ext is None else ext[:, :full], self.gauge))
            self.pending = np.array(run[:, full:], dtype=np.int32)
            if ext is not None:
                self.pending_extra = np.array(ext[:, full:])
        self.position += m
        return Segments.concat(parts) if parts else Segments.empty(0 if extra is None else extra.shape[0])


def rest_segments(q: np.ndarray, rate_hz: int, seconds: int = DEFAULT_SECONDS,
                  threshold: int = DEFAULT_THRESHOLD, axis: int = 0, gaps=(),
                  chunk: int | None = None) -> Segments:
    """All closed segments of a whole stream (m x 3 Q10 ints), fed in chunks of `chunk` samples
    (None: one)."""
    rs = RestStream(rate_hz, seconds, threshold, axis)
    gaps = np.asarray(sorted(gaps), dtype=np.int64)
    step = chunk or max(len(q), 1)
    parts = []
    for a in range(0, len(q), step):
        b = min(a + step, len(q))
        g = gaps[(gaps >= a) & (gaps < b)] - a
        parts.append(rs.feed(q[a:b], g))
    return Segments.concat(parts)


def samples_planar(x, y, z, first: int = 0) -> np.ndarray:
    """Floats in g (three columns) -> the device's samples, planar 3 x m int32 Q10 g: rounded as
    the device's format is (fixedpoint.g_to_sample: the dither of each sample's index in the
    stream, the first being first), clipped to +-16 g, without the m x 3 copy."""
    out = np.empty((3, len(x)), np.int32)
    d = fixedpoint.dither(first, len(x))
    for i, c in enumerate((x, y, z)):
        fixedpoint.to_samples(c, d, out[i])
    return out


def planar_of(axes, first: int = 0) -> np.ndarray:
    """samples_planar of a reader's axes (recordings.Chunk.axes, the chunk's first sample at
    stream index first): three (n,) columns, or an (n, 3) array of floats in g, float32 or
    float64, converted in its own dtype without a float64 copy first.  The same samples to the
    bit: the scale is a power of two and the floor exact in either dtype (the dither is added to
    the ints), so a float32 value gives what its float64 copy gives."""
    if isinstance(axes, tuple):
        return samples_planar(*axes, first=first)
    return samples_planar(axes[:, 0], axes[:, 1], axes[:, 2], first)


def apply_params(p_int, q: np.ndarray, kinds=(), dT=None, dt=None, range_g: int = 2,
                 step_time: int = 0, dV=None, first: int = 0) -> np.ndarray:
    """The twin of Calibration(kinds, range_g).set(p, ref) + apply_samples: Q24 parameters
    (9, then 3 per effect), Q10 samples in, calibrated samples out in Q(13 - e) g
    (fixed.apply_out_q(range_g)) (m x 3 int64), the format of the full scale range_g (fixed.py),
    readings clamped to it.  A composed model also takes each
    sample's dT (Q2 degC, fixed.TEMP_Q, from the reference temperature) and dt (64 s units from the reference
    time), as the device's now - ref columns (temperature, time), and dV (mV of the board's supply
    from its reference); clamped as the device clamps (dT, dt, dV, and the reading after each
    effect); a step from dt >= step_time on.  first: the base model's count of samples applied
    before q's first (the output's dither, fixed.APPLY_DITHER_STEP: the device's
    Calibration.dither after that many)."""
    e = fixed.apply_range_shift(range_g)
    m = fixed.APPLY_IN_MAX << e
    q = np.clip(np.asarray(q, dtype=np.int64).reshape(-1, 3), -m, m)   # the full scale, as the device
    if not kinds:
        return _apply_base(p_int, q, e, first)
    k = [(int(v) + (1 << (fixed.APPLY_PARAM_SHIFT - 1))) >> fixed.APPLY_PARAM_SHIFT for v in p_int[:6]]
    shift = fixed.APPLY_PARAM_SHIFT + e   # the offsets in Q(14 - e)
    k += [(int(v) + (1 << (shift - 1))) >> shift for v in p_int[6:9]]
    off = np.array(k[6:9], dtype=np.int64)
    u = q << (fixed.APPLY_FROM_SAMPLE_SHIFT - e)
    _remove_effects(u, q, p_int, kinds, dT, dt, step_time, dV, e)
    u += off
    s = fixed.APPLY_OUT_SHIFT
    half = 1 << (s - 1)
    out = np.empty_like(u)
    out[:, 0] = (k[0] * u[:, 0] + half) >> s
    out[:, 1] = (k[3] * u[:, 0] + k[1] * u[:, 1] + half) >> s
    out[:, 2] = (k[4] * u[:, 0] + k[5] * u[:, 1] + k[2] * u[:, 2] + half) >> s
    return out


def _apply_base(p_int, q: np.ndarray, e: int, first: int) -> np.ndarray:
    """calibration._apply_block's base model on the clamped readings q (Q10 g): D = K - I in
    Q(18 - e) and c = K o in Q(28 - e) g as calibration._base_params makes them (its exact
    floors: Python's ints), a = ((x << (18 - e)) + D x + c + r_i) >> 15, r_i the output's
    dither of sample first + i.  D and c are the device's own (_base_params: per calibration,
    not per sample)."""
    k = [0] * 9
    _base_params([int(v) for v in p_int[:9]], k, e)
    d, c = k[:6], k[6:]
    s = fixed.APPLY_OUT_SHIFT
    r = ((first + np.arange(len(q), dtype=np.int64)) * fixed.APPLY_DITHER_STEP) & \
        fixed.APPLY_DITHER_MASK
    t = fixed.APPLY_D_Q - e
    x, y, z = q[:, 0], q[:, 1], q[:, 2]
    out = np.empty_like(q)
    out[:, 0] = ((x << t) + d[0] * x + c[0] + r) >> s
    out[:, 1] = ((y << t) + d[3] * x + d[1] * y + c[1] + r) >> s
    out[:, 2] = ((z << t) + d[4] * x + d[5] * y + d[2] * z + c[2] + r) >> s
    return out


def _remove_effects(w: np.ndarray, q: np.ndarray, p_int, kinds, dT, dt, step_time: int, dV,
                    e: int) -> None:
    """The effects of calibration._apply_composed on every sample, by the table's forms
    (effects.block_terms): out of w (Q(14 - e) g, in place), last first, each clamped after;
    q: the clamped readings (Q10 g)."""
    m = len(q)
    dT = np.clip(np.broadcast_to(np.asarray(0 if dT is None else dT, np.int64), (m,)),
                 -deff.APPLY_DT_MAX, deff.APPLY_DT_MAX)[:, None]
    dt_raw = np.broadcast_to(np.asarray(0 if dt is None else dt, np.int64), (m,))[:, None]
    dV = np.broadcast_to(np.asarray(0 if dV is None else dV, np.int64), (m,))[:, None]
    for j in range(len(kinds) - 1, -1, -1):   # last first, as calibration._apply_composed
        kind = kinds[j]
        _name, _source, _power, form, _post, ps, rs = deff.EFFECTS[kind][:7]
        ke = [0, 0, 0]
        deff.apply_params(kind, [int(v) for v in p_int[9 + 3 * j:12 + 3 * j]], 0, ke, 0)
        ke = np.array(ke, dtype=np.int64)
        if form == deff.FORM_NONLINEAR:    # effects.block_terms' forms, by the table's row
            w -= (ke * ((q * q) >> (10 + e))) >> 14
        else:
            r = regressor(kind, dT, dt_raw, step_time, dV) >> rs
            if form == deff.FORM_OFFSET:
                w -= (ke * r) >> (26 + e - ps - rs)
            else:                          # FORM_SCALE
                w -= (((ke * r) >> (22 - ps - rs)) * w) >> 18
        np.clip(w, -fixed.APPLY_W_MAX, fixed.APPLY_W_MAX, out=w)   # after each, as the device


def regressor(kind: int, dT: np.ndarray, dt: np.ndarray, step_time: int,
              dV: np.ndarray | int = 0) -> np.ndarray:
    """The twin of acal.core.effects.regressor(..., fit=False) (Q16, the apply's clamps),
    vectorised: a step's indicator, the board's supply (clamped), or the clamped temperature or
    time to its power (each an exact floor in Q16, as acal/core/wide.py's mul_shift gives it),
    shifted by the row's post."""
    _name, source, power, _form, post = deff.EFFECTS[kind][:5]
    if source == deff.SOURCE_STEP:
        return np.where(dt >= step_time, 65536, 0).astype(np.int64)
    if source == deff.SOURCE_SUPPLY:
        base = np.clip(np.asarray(dV, np.int64), -deff.SUPPLY_MAX, deff.SUPPLY_MAX) << 6
    elif source == deff.SOURCE_TEMP:
        base = np.clip(dT, -deff.APPLY_DT_MAX, deff.APPLY_DT_MAX) << 10   # Q2 degC / 16 in Q16
    else:
        reach = deff.EFFECTS[kind][7][1]
        base = np.clip(dt, -reach, reach) << 3
    x = base
    for _ in range(power - 1):
        x = (x * base) >> 16      # < 2**37: exact in int64
    return x << post
