# The calibration pipeline: samples -> rest detection -> bins -> optimiser.
# One object, allocated once; the app feeds it FIFO reads, the host feeds it recordings.
from acal.rest import RestDetector, DEFAULT_SECONDS, DEFAULT_THRESHOLD
from acal.bins import Bins, CENTRE, DEFAULT_DIFFER, N_SUBSETS
from acal.optimiser import Optimiser, DEFAULT_ITERATIONS
from acal.fixed import N_PARAMS, ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET


class Pipeline:
    """rate_hz, seconds, threshold (Q10 g), axis: rest detection; min_count, max_count,
    differ (Q16 g), policy: bins; iterations and alphas (learning rates in tenths): optimiser.

    on_rest, if given, is called as on_rest(x, y, z, subset) for every rest mean (Q16 g), with
    the subset it was kept in or -1 (the app logs these; the host collects them)."""

    def __init__(self, rate_hz=100, seconds=DEFAULT_SECONDS, threshold=DEFAULT_THRESHOLD, axis=0,
                 min_count=2, max_count=2, differ=DEFAULT_DIFFER, policy=CENTRE,
                 iterations=DEFAULT_ITERATIONS, on_rest=None,
                 alphas=(ALPHA_SCALE, ALPHA_MISALIGN, ALPHA_OFFSET)):
        self.rest = RestDetector(rate_hz, seconds, threshold, axis)
        self.bins = Bins(min_count, max_count, differ, policy)
        self.optimiser = Optimiser(N_SUBSETS * max_count, alphas)
        self.iterations = iterations
        self.points = [0] * (3 * N_SUBSETS * max_count)
        self.on_rest = on_rest
        self.rest_count = 0
        self.position = 0  # samples of the current add_samples call consumed so far

    def offer(self, x, y, z):
        """A rest mean (Q16 g) -> bins; returns the subset it was kept in or -1."""
        self.rest_count += 1
        s = self.bins.offer(x, y, z)
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
                    self.offer(rest.mean_x, rest.mean_y, rest.mean_z)

    def ready(self):
        return self.bins.ready()

    def calibrate(self):
        """Run the optimiser on the held points; returns its status (optimiser.OK, ...).
        The parameters are in self.optimiser.p (Q24)."""
        n = self.bins.gather(self.points)
        return self.optimiser.run(self.points, n, self.iterations)

    def params(self, out):
        for i in range(N_PARAMS):
            out[i] = self.optimiser.p[i]
