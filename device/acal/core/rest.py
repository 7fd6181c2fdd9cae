# Rest detection (Farago 2024, section II-B-1): fixed segments of a duration in seconds; a segment
# is at rest when max - min of one chosen axis stays below a threshold.  Per-axis sums are
# accumulated during the segment and the mean is taken at its end.
#
# Beyond the paper (the default profile, acal/core/profile.py): axis ALL_AXES judges max - min on all
# three axes (the paper's one-axis test lets arm motion along y and z through), and threshold
# AUTO derives the threshold from the sensor's own noise, measured here (NoiseGauge).
#
# Formats (fixed.py): samples Q10 g, sums < 2**30, means Q16 g.  Nothing is allocated per sample:
# state lives in int attributes, and `add` returns a bool.
from array import array

from acal.core.emit import SIGN_SHIFT, viper, ptr32
from acal.core.fixed import SAMPLE_ONE_G, SEGMENT_MAX_SAMPLES, POINT_FROM_SAMPLE_SHIFT

# Default threshold 0.12 g in Q10 (122.88 -> 123) and segment length 5 s, as the paper.
DEFAULT_THRESHOLD = (12 * SAMPLE_ONE_G + 50) // 100
DEFAULT_SECONDS = 5
ALL_AXES = 3   # axis: max - min of every axis below the threshold
AUTO = 0       # threshold: from the measured noise (NoiseGauge)

# The noise gauge.  A segment's spread (the largest max - min of its axes, Q10 g) is at least the
# sensor's noise range; the quietest segments (a wrist asleep, a device on a table) show little
# more.  The gauge keeps a histogram of the spreads of the segments that could be rest (spread
# below NOISE_BINS LSB, 125 mg; a spread of 0 is imputed data, not a sensor, and is not counted),
# and every NOISE_EVERY such segments sets
#     threshold = clamp(NOISE_MUL * q + NOISE_ADD, THRESHOLD_MIN, THRESHOLD_MAX)
# where q is the spread below which the quietest 1/NOISE_QUANTILE of them lie.  A still segment's
# spread scatters little around its typical value (the range of n Gaussian samples), so twice the
# quiet level, plus two digits for quantisation, admits every still segment of the sensor and
# keeps out arm motion of more than a few mg.  Measured: LIS3DH at 12 bit, 220 ug/sqrt(Hz):
# ~4 LSB at 10 Hz -> 10 LSB, ~10 LSB at 100 Hz -> 22 LSB (docs/method-and-formats.md "Profiles"). 
# The counts
# halve when they pass NOISE_HALVE, so the gauge follows a sensor whose noise changes (a range
# or rate change; ageing) and its ints stay small.  Until the first NOISE_EVERY quiet segments
# (80 s) no segment is judged still.
NOISE_BINS = 128
NOISE_EVERY = 16
NOISE_QUANTILE = 8
NOISE_MUL = 2
NOISE_ADD = 2
NOISE_HALVE = 4096
THRESHOLD_MIN = 6     # 5.9 mg: quantisation alone spans 2 digits
THRESHOLD_MAX = DEFAULT_THRESHOLD  # never laxer than the paper


class NoiseGauge:
    """The histogram of quiet segments' spreads and the threshold it gives (see above).
    threshold is 0 (nothing is still) until the first update."""

    def __init__(self):
        self.hist = [0] * NOISE_BINS
        self.count = 0        # segments counted since the last halving
        self.seen = 0         # quiet segments ever counted (updates every NOISE_EVERY)
        self.threshold = 0
        self.level = 0        # q of the last update, Q10 g

    def add(self, spread):
        if spread <= 0 or spread >= NOISE_BINS:
            return
        self.hist[spread] += 1
        self.count += 1
        self.seen += 1
        if self.seen % NOISE_EVERY == 0:
            self._update()

    def _update(self):
        hist = self.hist
        need = (self.count + NOISE_QUANTILE - 1) // NOISE_QUANTILE
        acc = 0
        q = 0
        for b in range(NOISE_BINS):
            acc += hist[b]
            if acc >= need:
                q = b
                break
        self.level = q
        t = NOISE_MUL * q + NOISE_ADD
        self.threshold = THRESHOLD_MIN if t < THRESHOLD_MIN else (THRESHOLD_MAX if t > THRESHOLD_MAX else t)
        if self.count >= NOISE_HALVE:
            c = 0
            for b in range(NOISE_BINS):
                hist[b] >>= 1
                c += hist[b]
            self.count = c


class RestDetector:
    """Splits a sample stream into segments and tells which are at rest.

    rate_hz: samples per second (int); seconds: segment length (int, s);
    threshold: max - min limit, in Q10 g (default 0.12 g), or AUTO (from the measured noise);
    axis: 0, 1 or 2 for x, y, z, or ALL_AXES.
    After `add` returns True a segment has ended: `still` says whether it was at rest, and if so
    mean_x/mean_y/mean_z hold its mean in Q16 g; `spread` holds its max - min (Q10 g; with
    ALL_AXES the largest of the three).  `threshold` is the one in force (AUTO: the gauge's).
    """

    def __init__(self, rate_hz, seconds=DEFAULT_SECONDS, threshold=DEFAULT_THRESHOLD, axis=0):
        n = rate_hz * seconds
        if n < 1 or n > SEGMENT_MAX_SAMPLES:
            raise ValueError("segment must hold 1..65535 samples")
        if axis not in (0, 1, 2, ALL_AXES):
            raise ValueError("axis must be 0, 1, 2 or ALL_AXES")
        if threshold < 0:
            raise ValueError("threshold must be > 0, or AUTO")
        self.length = n
        self.auto = threshold == AUTO
        self.gauge = NoiseGauge() if self.auto else None
        self.threshold = 0 if self.auto else threshold
        self.axis = axis
        self.segments = 0
        self.ended = False  # set when a segment closes; the reader clears it
        self.still = False
        self.spread = 0
        self.mean_x = 0
        self.mean_y = 0
        self.mean_z = 0
        self.st = array("i", bytearray(4 * STATE))   # the open segment (indices below)
        self.one = array("i", bytearray(12))         # add()'s sample
        self.st[LENGTH] = n
        self.st[AXIS] = axis
        self.reset()

    def reset(self):
        """Start a new segment (also after a gap in the stream)."""
        st = self.st
        for c in range(LO_X, SUM_X, 2):    # (a tuple of indices would allocate)
            st[c] = SAMPLE_ONE_G * 64    # above any sample
            st[c + 1] = -SAMPLE_ONE_G * 64
        for c in range(SUM_X, LENGTH):
            st[c] = 0

    @property
    def count(self):
        return self.st[COUNT]

    def add(self, x, y, z):
        """Take one sample (Q10 g ints); return True when it closes a segment."""
        b = self.one
        b[0] = x
        b[1] = y
        b[2] = z
        self.add_samples(b, 0, 1)
        return self.st[COUNT] == 0   # a segment closed (and a new one began)

    def add_samples(self, buf, start, n):
        """Take n interleaved samples x y z x y z ... of an int array (e.g. a FIFO read), from
        sample index `start`.  Returns how many it consumed: it stops right after a segment
        closes, so the caller reads the result and calls again for the rest.  (Indices, not
        slices: a slice would allocate.)  On a port with emitters buf must be an int array
        (array('i')): the scan reads it through a typed pointer."""
        if self.axis == ALL_AXES:
            i = _scan_all(buf, 3 * start, 3 * (start + n), self.st, SIGN_SHIFT)
        else:
            i = _scan_one(buf, 3 * start, 3 * (start + n), self.st, SIGN_SHIFT)
        if self.st[COUNT] >= self.length:
            self._close()
        return i // 3 - start

    def _close(self):
        st = self.st
        n = st[COUNT]
        spread = st[HI_X] - st[LO_X]
        if self.axis == ALL_AXES:
            if st[HI_Y] - st[LO_Y] > spread:
                spread = st[HI_Y] - st[LO_Y]
            if st[HI_Z] - st[LO_Z] > spread:
                spread = st[HI_Z] - st[LO_Z]
        self.spread = spread
        self.still = spread < self.threshold
        if self.auto:  # judged by the threshold in force, then counted for the next ones
            self.gauge.add(spread)
            self.threshold = self.gauge.threshold
        if self.still:
            self.mean_x = mean_q16(st[SUM_X], n)
            self.mean_y = mean_q16(st[SUM_Y], n)
            self.mean_z = mean_q16(st[SUM_Z], n)
        self.segments += 1
        self.ended = True
        self.reset()


def mean_q16(total, n):
    """floor(total * 2**6 / n): a Q10 sum of n samples -> Q16 mean, never past 2**30.

    total = q*n + r with 0 <= r < n, so floor(total*64/n) = q*64 + floor(r*64/n); |q| <= 2**14
    and r < 2**16 keep both products small."""
    q = total // n
    r = total - q * n
    return (q << POINT_FROM_SAMPLE_SHIFT) + ((r << POINT_FROM_SAMPLE_SHIFT) // n)


# The open segment's state, an int32 array: min and max of x, y, z (one-axis: the chosen axis's
# in LO_X, HI_X), the three sums, the samples so far; then the segment's length and the judged
# axis, which the scans read from it too: a call with them as arguments took a frame of over 11
# words, which MicroPython takes from the heap on every call (docs/method-and-formats.md
# "Frames").  The scans below are the hot loop (acal/core/emit.py: viper on ports with emitters;
# the literal indices are these: a viper function reads no module constant, whose every load
# is a call).  Every value is a sample (|v| <= SAMPLE_MAX), a sum of at most
# SEGMENT_MAX_SAMPLES of them (< 2**30) or an index below 3 * 65535 (tests/device/test_ranges.py).
LO_X = 0
HI_X = 1
LO_Y = 2
HI_Y = 3
LO_Z = 4
HI_Z = 5
SUM_X = 6
SUM_Y = 7
SUM_Z = 8
COUNT = 9
LENGTH = 10    # the segment's length in samples, set once
AXIS = 11      # the judged axis (one-axis scans)
STATE = 12


@viper
def _scan_one(buf, i: int, end: int, state, w: int) -> int:
    # Samples buf[i:end] (flat x y z) into the state, judging one axis; stops after the sample
    # that fills the segment.  Returns the flat index it stopped at.  w: emit.SIGN_SHIFT (a
    # 32-bit word read into a 64-bit one is sign-extended by << w >> w; 0 on a 32-bit port).
    b = ptr32(buf)
    st = ptr32(state)
    length = int(st[10])
    axis = int(st[11])
    lo = int(st[0]) << w >> w
    hi = int(st[1]) << w >> w
    sx = int(st[6]) << w >> w
    sy = int(st[7]) << w >> w
    sz = int(st[8]) << w >> w
    count = int(st[9]) << w >> w
    while i < end:
        s = int(b[i + axis]) << w >> w
        if s < lo:
            lo = s
        if s > hi:
            hi = s
        sx += int(b[i]) << w >> w
        sy += int(b[i + 1]) << w >> w
        sz += int(b[i + 2]) << w >> w
        count += 1
        i += 3
        if count >= length:
            break
    st[0] = lo
    st[1] = hi
    st[6] = sx
    st[7] = sy
    st[8] = sz
    st[9] = count
    return i


@viper
def _scan_all(buf, i: int, end: int, state, w: int) -> int:
    # _scan_one with every axis's min and max tracked.
    b = ptr32(buf)
    st = ptr32(state)
    length = int(st[10])
    lx = int(st[0]) << w >> w
    hx = int(st[1]) << w >> w
    ly = int(st[2]) << w >> w
    hy = int(st[3]) << w >> w
    lz = int(st[4]) << w >> w
    hz = int(st[5]) << w >> w
    sx = int(st[6]) << w >> w
    sy = int(st[7]) << w >> w
    sz = int(st[8]) << w >> w
    count = int(st[9]) << w >> w
    while i < end:
        x = int(b[i]) << w >> w
        y = int(b[i + 1]) << w >> w
        z = int(b[i + 2]) << w >> w
        if x < lx:
            lx = x
        if x > hx:
            hx = x
        if y < ly:
            ly = y
        if y > hy:
            hy = y
        if z < lz:
            lz = z
        if z > hz:
            hz = z
        sx += x
        sy += y
        sz += z
        count += 1
        i += 3
        if count >= length:
            break
    st[0] = lx
    st[1] = hx
    st[2] = ly
    st[3] = hy
    st[4] = lz
    st[5] = hz
    st[6] = sx
    st[7] = sy
    st[8] = sz
    st[9] = count
    return i
