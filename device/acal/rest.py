# Rest detection (Farago 2024, section II-B-1): fixed segments of a duration in seconds; a segment
# is at rest when max - min of one chosen axis stays below a threshold.  Per-axis sums are
# accumulated during the segment and the mean is taken at its end.
#
# Formats (fixed.py): samples Q10 g, sums < 2**30, means Q16 g.  Nothing is allocated per sample:
# state lives in int attributes, and `add` returns a bool.
from acal.fixed import SAMPLE_ONE_G, SEGMENT_MAX_SAMPLES, POINT_FROM_SAMPLE_SHIFT

# Default threshold 0.12 g in Q10 (122.88 -> 123) and segment length 5 s, as the paper.
DEFAULT_THRESHOLD = (12 * SAMPLE_ONE_G + 50) // 100
DEFAULT_SECONDS = 5


class RestDetector:
    """Splits a sample stream into segments and tells which are at rest.

    rate_hz: samples per second (int); seconds: segment length (int, s);
    threshold: max - min limit of the rest axis, in Q10 g (default 0.12 g);
    axis: 0, 1 or 2 for x, y, z.
    After `add` returns True a segment has ended: `still` says whether it was at rest, and if so
    mean_x/mean_y/mean_z hold its mean in Q16 g; `spread` holds its max - min (Q10 g).
    """

    def __init__(self, rate_hz, seconds=DEFAULT_SECONDS, threshold=DEFAULT_THRESHOLD, axis=0):
        n = rate_hz * seconds
        if n < 1 or n > SEGMENT_MAX_SAMPLES:
            raise ValueError("segment must hold 1..65535 samples")
        if axis not in (0, 1, 2):
            raise ValueError("axis must be 0, 1 or 2")
        self.length = n
        self.threshold = threshold
        self.axis = axis
        self.segments = 0
        self.ended = False  # set when a segment closes; the reader clears it
        self.still = False
        self.spread = 0
        self.mean_x = 0
        self.mean_y = 0
        self.mean_z = 0
        self.reset()

    def reset(self):
        """Start a new segment (also after a gap in the stream)."""
        self.count = 0
        self.sum_x = 0
        self.sum_y = 0
        self.sum_z = 0
        self.lo = SAMPLE_ONE_G * 64  # above any sample
        self.hi = -SAMPLE_ONE_G * 64

    def add(self, x, y, z):
        """Take one sample (Q10 g ints); return True when it closes a segment."""
        s = x if self.axis == 0 else (y if self.axis == 1 else z)
        if s < self.lo:
            self.lo = s
        if s > self.hi:
            self.hi = s
        self.sum_x += x
        self.sum_y += y
        self.sum_z += z
        self.count += 1
        if self.count < self.length:
            return False
        self._close()
        return True

    def add_samples(self, buf, start, n):
        """Take n interleaved samples x y z x y z ... of an int array (e.g. a FIFO read), from
        sample index `start`.  Returns how many it consumed: it stops right after a segment
        closes, so the caller reads the result and calls again for the rest.  (Indices, not
        slices: a slice would allocate.)"""
        axis = self.axis
        lo = self.lo
        hi = self.hi
        sx = self.sum_x
        sy = self.sum_y
        sz = self.sum_z
        count = self.count
        length = self.length
        i = 3 * start
        end = 3 * (start + n)
        closed = False
        while i < end:
            x = buf[i]
            y = buf[i + 1]
            z = buf[i + 2]
            s = buf[i + axis]
            if s < lo:
                lo = s
            if s > hi:
                hi = s
            sx += x
            sy += y
            sz += z
            count += 1
            i += 3
            if count >= length:
                closed = True
                break
        self.lo = lo
        self.hi = hi
        self.sum_x = sx
        self.sum_y = sy
        self.sum_z = sz
        self.count = count
        if closed:
            self._close()
        return i // 3 - start

    def _close(self):
        n = self.count
        self.spread = self.hi - self.lo
        self.still = self.spread < self.threshold
        if self.still:
            self.mean_x = mean_q16(self.sum_x, n)
            self.mean_y = mean_q16(self.sum_y, n)
            self.mean_z = mean_q16(self.sum_z, n)
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
