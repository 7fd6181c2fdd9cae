# The calibration pipeline: samples -> rest detection -> bins -> optimiser.
# One object, allocated once; the app feeds it FIFO reads, the host feeds it recordings.
from acal.rest import RestDetector, DEFAULT_SECONDS, DEFAULT_THRESHOLD
from acal.bins import Bins, CENTRE, DEFAULT_DIFFER, N_SUBSETS, TEMP_DIFFER, TIME_DIFFER
from acal.optimiser import Optimiser, DEFAULT_ITERATIONS, COMPOSED_ITERATIONS
from acal.fixed import ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET
from acal import effects


class Pipeline:
    """rate_hz, seconds, threshold (Q10 g), axis: rest detection; min_count, max_count,
    differ (Q16 g), policy: bins; iterations and alphas (learning rates in tenths): optimiser.

    on_rest, if given, is called as on_rest(x, y, z, subset) for every rest mean (Q16 g), with
    the subset it was kept in or -1 (the app logs these; the host collects them).

    kinds: the effects of a composed model (acal.effects ids; () is the paper's model).  Their
    bins track temperature and time (bins.py), and the feeder keeps `temp` (int degC) and `time`
    (64 s units) current; a fit takes each point's dT and dt from the middle of the held points'
    ranges (ref_temp, ref_time), which the calibration keeps.  iterations None: 50 for the
    paper's model, 200 for a composed one (50 leave the effect terms under-converged).

    worn: the feeder's wear signal.  A rest segment that closes while it is False (a device off
    the wrist, on a table; imputed or idle-sleep stretches) is counted in `excluded` but not
    offered: it is still, but not what the wearer's data looks like.  The app leaves it True;
    the host sets it from its non-wear and quality masks."""

    def __init__(self, rate_hz=100, seconds=DEFAULT_SECONDS, threshold=DEFAULT_THRESHOLD, axis=0,
                 min_count=2, max_count=2, differ=DEFAULT_DIFFER, policy=CENTRE,
                 iterations=None, on_rest=None,
                 alphas=(ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET), kinds=()):
        self.kinds = tuple(kinds)
        self.rest = RestDetector(rate_hz, seconds, threshold, axis)
        temp_differ = 0
        time_differ = 0
        for k in self.kinds:
            if k == effects.TEMP_OFFSET or k == effects.TEMP_SCALE:
                temp_differ = TEMP_DIFFER
            elif k == effects.DRIFT:
                time_differ = TIME_DIFFER
        self.bins = Bins(min_count, max_count, differ, policy, temp_differ, time_differ)
        self.optimiser = Optimiser(N_SUBSETS * max_count, alphas, self.kinds)
        if iterations is None:
            iterations = COMPOSED_ITERATIONS if self.kinds else DEFAULT_ITERATIONS
        self.iterations = iterations
        self.points = [0] * (3 * N_SUBSETS * max_count)
        self.aux = [0] * (2 * N_SUBSETS * max_count)  # dT, dt per point (composed models)
        self.temp = 0
        self.time = 0
        self.ref_temp = 0
        self.ref_time = 0
        self.on_rest = on_rest
        self.rest_count = 0
        self.worn = True
        self.excluded = 0
        self.position = 0  # samples of the current add_samples call consumed so far

    def offer(self, x, y, z):
        """A rest mean (Q16 g), seen at self.temp and self.time -> bins; returns the subset it
        was kept in or -1."""
        self.rest_count += 1
        s = self.bins.offer(x, y, z, self.temp, self.time)
        if self.on_rest is not None:
            self.on_rest(x, y, z, s)
        return s

    def add_samples(self, buf, start, n):
        """Feed n interleaved samples (Q10 g) from sample index start."""
        rest = self.rest
        while n > 0:
            used = rest.add_samples(buf, start, n)
            start += used
            n -= used
            self.position = start
            if rest.ended:
                rest.ended = False
                if rest.still:
                    if self.worn:
                        self.offer(rest.mean_x, rest.mean_y, rest.mean_z)
                    else:
                        self.excluded += 1

    def ready(self):
        return self.bins.ready()

    def calibrate(self):
        """Run the optimiser on the held points; returns its status (optimiser.OK, ...).
        The parameters are in self.optimiser.p (Q24; 9, then 3 per effect)."""
        if not self.kinds:
            n = self.bins.gather(self.points)
            return self.optimiser.run(self.points, n, self.iterations)
        aux = self.aux
        n = self.bins.gather(self.points, aux)
        self.ref_temp = _middle(aux, 0, n)
        self.ref_time = _middle(aux, 1, n)
        for i in range(n):
            aux[2 * i] -= self.ref_temp
            aux[2 * i + 1] -= self.ref_time
        return self.optimiser.run(self.points, n, self.iterations, aux)


def _middle(cond, c, n):
    # Middle of the range of condition c over n points (floor): the fit's reference, so that
    # dT and dt are centred and the effect terms do not trade with the offsets.
    if n == 0:
        return 0
    lo = hi = cond[c]
    for i in range(1, n):
        v = cond[2 * i + c]
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
    return (lo + hi) >> 1
