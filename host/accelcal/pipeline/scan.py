"""One pass over a recording, chunk by chunk, in constant memory: the device's rest segments (by
the vectorised twin, accelcal.bridge.twin) and what a quality report needs (hours, gaps, clipping,
temperature).  Then the host's quality checks decide which still segments are not the wearer's
rest and are kept from the bins (docs/real-recordings.md "False rest kept out"):

* imputed / idle-sleep: every axis constant for a whole segment.  A real sensor's noise moves
  at least one axis by a digit in 5 s; files pad gaps with repeated values or zeros.  Constant
  in the device's samples' terms: a spread of at most one LSB on every axis (the Q10 format's
  dither, acal.core.fixed, makes a constant value off the grid floor(g * 1024) or one more; a
  1 mg digit moves a sample by 1.024 LSB, over 50 samples with the dither by 2 LSB);
* clipped: a sample at the full scale in the segment (the mean is not gravity's);
* non-wear: still on every axis (not only the rest-test axis) while the device is colder than
  skin (below WEAR_TEMP_C) or cooling fast (faster than COOLING_C_PER_MIN): off the wrist
  (Zhou et al. 2015 use temperature the same way).  Files without temperature: not detected;
  files whose temperature never reaches skin's (relative LIS3DH readings): the cooling test only.

What is kept is decided per segment, so both engines (this twin and the device modules fed every
sample) see the same: the device's Pipeline gets `worn = False` over the excluded segments.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acal.core import fixed
from accelcal.bridge import twin
from accelcal.errors import InputError
from accelcal.files.checks import check_units
from accelcal.files.recordings import STANDARD_RANGES_G, Recording, gap_limit
from accelcal.files.table import median

IMPUTED_SPREAD = 1          # Q10 LSB: a constant value's samples, dithered (above)
WEAR_TEMP_C = 25.0          # worn wrist devices read 28-35 degC; off the wrist: the room's
SKIN_MIN_C = 28.0           # a file that never reads this has relative temperatures (an LIS3DH
                            # without a reference) or was never worn: no "cold" test there
COOLING_C_PER_MIN = 0.3     # taken off: skin -> room with a ~15 min time constant, ~0.6 degC/min
COOLING_WINDOW_S = 120      # slope over 2 min: an AX3's 0.29 degC steps stay below the rate
CLIP_FRACTION = 0.99925     # at full scale: within 1.5 mg of 2 g (the LIS3DH's last digits)


def clip_level(range_g: float) -> int:
    """The Q10 magnitude at and past which a sample counts as clipped at that full scale."""
    return int(np.ceil(range_g * CLIP_FRACTION * fixed.SAMPLE_ONE_G))


@dataclass
class Scan:
    """A recording's rest segments and quality figures.  Arrays are per closed segment."""
    path: str
    format: str
    rate_hz: int
    n_samples: int = 0
    t_first: float = 0.0
    t_last: float = 0.0
    gap_starts: list[int] = field(default_factory=list)   # stream indices starting a new run
    segments: twin.Segments = field(default_factory=twin.Segments.empty)
    seg_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    seg_temp: np.ndarray | None = None
    temp_min: float | None = None
    temp_max: float | None = None
    abs_max_q10: int = 0
    clip_counts: dict = field(default_factory=dict)        # range_g -> samples at that level
    range_g: float | None = None                           # declared by the file, if at all
    length: int = 0                                        # samples per segment
    threshold: int = 0                                     # Q10 g
    # with scan(extras=True), per segment the means of: t (s), temperature (degC; 0 without),
    # |v| and |v|^2 of the file's own float samples (g, g^2), then each further column's
    # (Recording.columns, in order: seg_column())
    seg_means: np.ndarray | None = None
    columns: list[str] = field(default_factory=list)
    # threshold AUTO: the noise gauge at the end (Q10 g): its threshold and the noise level
    noise_threshold: int | None = None
    noise_level: int | None = None
    # the time the samples span within their contiguous runs (s, the steps between samples that
    # are not gaps): the measured rate is the steps over it, kept as measured (a float)
    run_seconds: float = 0.0

    def seg_column(self, name: str) -> np.ndarray:
        """Per segment, the mean of a further recording column (scan(extras=True))."""
        return self.seg_means[:, 4 + self.columns.index(name)]

    @property
    def measured_rate_hz(self) -> float:
        """The sample rate as the file's clock measured it over every contiguous run: the steps
        between samples within runs over the time they span (66.67 Hz, 1.5625 Hz, a drifting
        rate's mean); rate_hz, the nearest whole rate, is what the device's segments count in."""
        steps = self.n_samples - 1 - len(self.gap_starts)
        return steps / self.run_seconds if steps > 0 and self.run_seconds > 0 \
            else float(self.rate_hz)

    @property
    def hours(self) -> float:
        """The hours the samples stand for (gaps left out), at the measured rate."""
        return self.n_samples / self.measured_rate_hz / 3600.0

    # -- quality -----------------------------------------------------------------------------
    @property
    def full_scale_g(self) -> float | None:
        """The full scale the samples were clipped at: the file's declared range, else the
        standard range the samples reached (None: they never reached one)."""
        if self.range_g:
            return self.range_g
        peak = self.abs_max_q10 / fixed.SAMPLE_ONE_G
        for r in STANDARD_RANGES_G:
            if peak <= r * 1.03:
                return float(r) if peak >= r * CLIP_FRACTION else None
        return None

    @property
    def clipped_samples(self) -> int:
        r = self.full_scale_g
        return int(self.clip_counts.get(r, 0)) if r else 0

    def masks(self) -> dict[str, np.ndarray]:
        """Per segment: still (the device's rest test) and the reasons a still segment is kept
        from the bins (imputed, clipped, nonwear); `kept` = still and none of them."""
        s = self.segments
        still = s.still
        rng = s.hi - s.lo
        imputed = (rng <= IMPUTED_SPREAD).all(axis=1)
        r = self.full_scale_g
        if r:
            clipped = np.maximum(s.hi.max(axis=1), -s.lo.min(axis=1)) >= clip_level(r)
        else:
            clipped = np.zeros(len(s), bool)
        nonwear = np.zeros(len(s), bool)
        if self.seg_temp is not None and len(s):
            all_still = (rng < s.threshold[:, None]).all(axis=1)
            absolute = self.temp_max is not None and self.temp_max >= SKIN_MIN_C
            cold = (self.seg_temp < WEAR_TEMP_C) if absolute else np.zeros(len(s), bool)
            # temperature slope over the last COOLING_WINDOW_S, per minute
            k = np.searchsorted(self.seg_t, self.seg_t - COOLING_WINDOW_S)
            dt = self.seg_t - self.seg_t[k]
            with np.errstate(invalid="ignore", divide="ignore"):
                slope = np.where(dt > 0, (self.seg_temp - self.seg_temp[k]) * 60.0 / dt, 0.0)
            nonwear = all_still & (cold | (slope < -COOLING_C_PER_MIN))
        imputed &= still
        clipped &= still & ~imputed
        nonwear &= still & ~imputed & ~clipped
        return {"still": still, "imputed": imputed, "clipped": clipped, "nonwear": nonwear,
                "kept": still & ~imputed & ~clipped & ~nonwear}

    def excluded_runs(self, kept: np.ndarray) -> np.ndarray:
        """(k, 2) sample-index runs [start, stop) of the still segments not kept: where the
        device's pipeline must not offer (worn = False)."""
        ex = self.segments.still & ~kept
        end = self.segments.end[ex]
        return np.column_stack([end - self.length + 1, end + 1]).astype(np.int64).reshape(-1, 2)


def prefetched(chunks, depth: int = 2, prepare=None):
    """The chunks of an iterator read ahead in a thread: the reader (Arrow's parser, actfast,
    the checks) and the detector's twin work on both cores at once, numpy and Arrow releasing
    the GIL; the same chunks in the same order, the reader's exception raised here.
    prepare(chunk), if given, runs in the reading thread on each chunk before it is handed on."""
    import queue
    import threading
    q: queue.Queue = queue.Queue(maxsize=depth)
    done = object()
    stop = threading.Event()

    def read():
        try:
            for ch in chunks:
                if prepare is not None:
                    prepare(ch)
                while not stop.is_set():
                    try:
                        q.put(ch, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            q.put(done)
        except BaseException as e:   # handed to the consumer, raised there
            q.put(e)
    th = threading.Thread(target=read, daemon=True)
    th.start()
    try:
        while True:
            item = q.get()
            if item is done:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        stop.set()


def _gaps(rec: Recording, ch, last_t: float | None, limit: float) -> tuple[np.ndarray, float]:
    """Where in ch a new contiguous run starts (a step in time over limit), and the seconds the
    steps within runs span; InputError where time does not increase.  steps[i]: t[i] minus the
    sample before it (the first sample of all: no step, so neither a gap nor a fault, nor
    time); the checks are reductions, with a pass more only for a find."""
    t = ch.t
    if not len(t):
        return np.zeros(0, np.int64), 0.0
    steps = np.empty(len(t))
    steps[0] = limit if last_t is None else t[0] - last_t
    np.subtract(t[1:], t[:-1], out=steps[1:])
    if steps.min() <= 0:
        i = int(np.argmax(steps <= 0))
        where = f"{rec.path}:{ch.first + i + 2}" if rec.format == "CSV" else \
            f"{rec.path}: sample {ch.first + i}"
        prev = t[i - 1] if i > 0 else last_t
        raise InputError(f"{where}: time does not increase (t={t[i]!r} after {prev!r})")
    span = float(t[-1] - t[0]) + (0.0 if last_t is None else float(steps[0]))
    if steps.max() <= limit:
        return np.zeros(0, np.int64), span
    gaps = np.flatnonzero(steps > limit)
    return gaps, span - float(steps[gaps].sum())


def _count_clipping(sc, p: np.ndarray) -> None:
    # the largest |sample| so far and, per standard range, the samples at its clip level
    peak = max(int(p.max()), -int(p.min()))
    sc.abs_max_q10 = max(sc.abs_max_q10, peak)
    at = [r for r in sc.clip_counts if peak >= clip_level(r)]
    if at:      # most chunks reach no range's clip level: no per-sample pass for them
        am = np.abs(p).max(axis=0)
        for r in at:
            sc.clip_counts[r] += int(np.count_nonzero(am >= clip_level(r)))


def _to_samples(ch) -> None:
    # run in the reading thread, beside the detector on the other core: on the 14-day .cwa the
    # conversion was 3.2 s of the detector thread's 8.6 s, which was the longer of the two
    ch.planar = twin.planar_of(ch.axes, ch.first)


def scan(rec: Recording, seconds: int, threshold: int, axis: int, rate_hz: int | None = None,
         keep_samples: bool = False, progress=None, extras: bool = False):
    """Stream rec through the twin's detector.  rate_hz None: from the first chunk's median time
    step.  keep_samples: also return the whole recording (t, xyz Q10 m x 3, temp) for the
    device engine.  extras: also each segment's means of t, temperature, |v|, |v|^2 and the
    recording's further columns (Scan.seg_means, for diagnose and column effects).  progress(samples_done) after each chunk."""
    sc = None
    stream = None
    parts, seg_t, seg_temp = [], [], []
    kept_t, kept_q, kept_temp = [], [], []
    last_t = None
    for ch in prefetched(rec.chunks(), prepare=_to_samples):
        t = ch.t
        if sc is None:
            if len(t) < 2:
                raise InputError(f"{rec.path}: a recording needs at least 2 samples")
            check_units(rec.path, ch.axes)   # m/s^2 or counts: the fix, before any work
            given = rate_hz
            if rate_hz is None:
                d = np.diff(t[: 1 << 16])
                med = median(d)
                if not med > 0:
                    raise InputError(f"{rec.path}: time does not increase")
                rate_hz = int(round(1.0 / med))
                if rate_hz < 1:
                    raise InputError(f"{rec.path}: sample rate {1.0 / med:.3g} Hz is below 1 Hz")
            length = rate_hz * seconds
            if length > fixed.SEGMENT_MAX_SAMPLES:
                raise InputError(f"{rec.path}: {seconds} s segments at {rate_hz} Hz exceed "
                                 f"{fixed.SEGMENT_MAX_SAMPLES} samples")
            sc = Scan(rec.path, rec.format, rate_hz, t_first=float(t[0]), range_g=rec.range_g,
                      length=length, threshold=threshold, columns=list(rec.columns))
            sc.clip_counts = {float(r): 0 for r in STANDARD_RANGES_G}
            stream = twin.RestStream(rate_hz, seconds, threshold, axis)
            limit = gap_limit(rate_hz if given else 1.0 / med)   # the rate as measured
        gaps, span = _gaps(rec, ch, last_t, limit)
        sc.run_seconds += span
        sc.gap_starts.extend((gaps + ch.first).tolist())
        p = ch.planar if ch.planar is not None else twin.planar_of(ch.axes, ch.first)
        extra = None
        if extras:
            mag2 = np.einsum("ij,ij->i", ch.xyz, ch.xyz)
            extra = np.vstack([t - sc.t_first, ch.temp if ch.temp is not None else np.zeros(len(t)),
                               np.sqrt(mag2), mag2] + [ch.cols[c] for c in rec.columns])
        seg = stream.feed_planar(p, gaps, extra)
        local = seg.end - ch.first
        parts.append(seg)
        seg_t.append(t[local])
        if ch.temp is not None:
            seg_temp.append(ch.temp[local])
            lo, hi = float(ch.temp.min()), float(ch.temp.max())
            sc.temp_min = lo if sc.temp_min is None else min(sc.temp_min, lo)
            sc.temp_max = hi if sc.temp_max is None else max(sc.temp_max, hi)
        _count_clipping(sc, p)
        sc.n_samples += len(t)
        last_t = float(t[-1])
        if keep_samples:
            kept_t.append(t)
            kept_q.append(p.T.astype(np.int64))
            kept_temp.append(ch.temp)
        if progress:
            progress(sc.n_samples)
    if sc is None:
        raise InputError(f"{rec.path}: no samples")
    sc.t_last = last_t
    if stream.gauge is not None:
        sc.noise_threshold, sc.noise_level = stream.gauge.threshold, stream.gauge.level
    sc.segments = twin.Segments.concat(parts)
    sc.seg_t = np.concatenate(seg_t) if seg_t else np.zeros(0)
    sc.seg_temp = np.concatenate(seg_temp) if seg_temp and rec.has_temp else None
    if extras:
        sc.seg_means = sc.segments.extra / sc.length
        sc.seg_means[:, 0] += sc.t_first
    if keep_samples:
        whole = (np.concatenate(kept_t), np.concatenate(kept_q),
                 np.concatenate(kept_temp) if rec.has_temp else None)
        return sc, whole
    return sc
