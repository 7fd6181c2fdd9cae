# Drives the device pipeline.  The same file runs inside CPython (imported: the host calls a
# Runner's methods with ints and gets ints back, no text in between) and inside the real
# MicroPython interpreter (as a script reading the line protocol below), so both runtimes execute
# the very same device code on the very same integers.  MicroPython-compatible: no f-strings with
# expressions beyond str(), no host imports.
#
# Input lines (integers, space separated):
#   C rate seconds threshold axis min_count max_count differ policy iterations fit discover
#     a_s a_m a_o [kind ...]   the settings, in SETTINGS order; threshold 0: from the noise
#                          (acal.core.rest.AUTO); axis 3: all axes; fit: acal.core.profile.GRADIENT or
#                          NEWTON; discover 1: the board's own discovery after the fit
#                          (acal/discover/search.py); the effects of a composed model (acal.core.effects
#                          ids), if any
#   G name                 start a group (a device): a fresh pipeline
#   T temp time supply     conditions of what follows: Q2 degC, 64 s units, mV (composed models)
#   P x y z                a rest point, Q16 g, offered to the bins
#   B n x0 y0 z0 x1 ...    n samples, Q10 g, fed to the rest detector
#   X                      a gap in the samples: the open segment is dropped
#   W worn                 1/0: rest segments closing in what follows are offered / excluded
#   E                      end of group: calibrate and report
# Output lines (a Runner's emit(tag, values) calls, printed as "tag v0 v1 ..."):
#   G name
#   R x y z subset temp time supply   every rest mean (Q16 g), the subset that kept it (-1: not
#                              kept) and the conditions it was seen at
#   K c0 ... c8                points per subset
#   S x y z temp time supply   every point the bins hold at the end (Q16 g)
#   Y ready covered span...    the bins' verdict (1/0), whether the held points cover every
#                              axis (bins.covered()), and their range of each condition (COND)
#   Z step_time ref...         a step's time and the fit's references, a condition each (COND;
#                              composed models)
#   F status iterations objective_start objective p0 ... p8 [3 per effect]
#   D n k0 ... k(n-1)          NEWTON: the points the fit was given (in S order) kept (1) or
#                              rejected as outliers (0)
#   N threshold level          the rest threshold in force at the end and the noise level it
#                              came from (Q10 g; AUTO only)
#   V adopted closest before after betters blocks held weight step_time p0 .. p14 fitted_time
#     step_unplaced placed_insample gap_n   discover: the DISCOVERY record's fields (acal/logger/log.py),
#                              the held-out points and the rest means they stand for (their
#                              weights' sum), a step's time (placed), the closest candidate's 15
#                              parameters, and the step's fitted time, held-out error at it
#                              and placed in-sample (-1: not placed; after: leave-one-out), gap points
#   H x y z temp time supply weight   discover: each held-out point (acal/discover/heldout.py)
#   W kind err betters         discover: each candidate (err -1: not testable)
#                              After an adoption with room for another effect (discover.more)
#                              the discovery runs again from the adopted model on the same fit
#                              points: a V and its W records per round (H once, after the first)
import sys
from array import array

from acal.core.bins import COND

from acal.core.pipeline import Pipeline
from acal.core.profile import NEWTON

# The C line's fields, in order: the one place the settings' order is written (the host's
# Config.line() builds the line from it).  The learning rates (a_*) and the effect ids follow.
SETTINGS = ("rate_hz", "seconds", "threshold", "axis", "min_count", "max_count", "differ", "policy",
            "iterations", "fit", "discover")


class Runner:
    """One pipeline per group.  emit(tag, values): values a list of ints (G: [name])."""

    def __init__(self, emit):
        self.emit = emit
        self.settings = None
        self.pipe = None

    def configure(self, values):
        self.settings = values

    def group(self, name):
        self.emit("G", [name])
        v = self.settings
        n = len(SETTINGS)
        emit = self.emit

        def on_rest(x, y, z, s):
            emit("R", [x, y, z, s] + [pipe.now[c] for c in range(COND)])

        pipe = Pipeline(rate_hz=v[0], seconds=v[1], threshold=v[2], axis=v[3], min_count=v[4],
                        max_count=v[5], differ=v[6], policy=v[7], iterations=v[8], fit=v[9],
                        on_rest=on_rest, alphas=(v[n], v[n + 1], v[n + 2]), kinds=v[n + 3:],
                        plug=_plug() if v[10] == 1 else None)
        self.pipe = pipe

    def conditions(self, *cond):
        """The conditions now, a value a column (COND: fixed.C_TEMP ...)."""
        for c in range(COND):
            self.pipe.now[c] = cond[c]

    def point(self, x, y, z):
        self.pipe.offer(x, y, z)

    def samples(self, buf, n):
        self.pipe.add_samples(buf, 0, n)

    def gap(self):
        self.pipe.rest.reset()

    def worn(self, flag):
        self.pipe.worn = flag

    def end(self):
        pipe = self.pipe
        emit = self.emit
        b = pipe.bins
        emit("K", list(b.counts))
        for s in range(9):
            for k in range(b.counts[s]):
                emit("S", list(b.point(s, k)) + list(b.condition(s, k)))
        emit("Y", [1 if b.ready() else 0, 1 if b.covered() else 0] +
             [b.span(c) for c in range(COND)])
        status = pipe.calibrate()
        o = pipe.optimiser
        emit("Z", [pipe.step_time] + [pipe.ref[c] for c in range(COND)])
        q = 40 - o.OBJ_Q   # the host reads Q40 g^4 (fixed.OBJ_Q) from either fit
        emit("F", [status, o.iterations, o.objective_start << q, o.objective << q] + list(o.p))
        if pipe.fit == NEWTON:
            emit("D", [o.n_given] + [o.keep[i] for i in range(o.n_given)])
        d = None if pipe.plug is None else pipe.plug.discovery
        first = True
        if d is not None:
            from acal.discover.search import more   # a discovering runner's module only
        while d is not None and status == 0:   # acal.core.status.OK: a base fit to start from
            d.run(pipe)
            i = d.chosen
            emit("V", [d.kind, d.kind_ids[i] if i >= 0 else 0, d.before,
                       d.errs[i] if i >= 0 else 0, d.betters[i] if i >= 0 else 0, d.blocks,
                       d.held.count, d.held.total_weight(), d.step_time] + list(d.params) +
                 [d.fitted_time, d.step_unplaced, d.placed_insample, d.gap_n])
            h = d.held
            for j in range(h.count if first else 0):
                emit("H", [h.xyz[3 * j], h.xyz[3 * j + 1], h.xyz[3 * j + 2]] +
                     [h.cond[COND * j + c] for c in range(COND)] + [h.weight[j]])
            for j in range(len(d.errs)):
                if d.kind_ids[j]:   # (a second round has no curve pair)
                    emit("W", [d.kind_ids[j], d.errs[j], d.betters[j]])
            first = False
            if not (d.adopted and more(d.kinds[i])):
                break
            pipe.plug.adopt(pipe)
        if pipe.rest.auto and pipe.rest.segments:
            emit("N", [pipe.rest.threshold, pipe.rest.gauge.level])


def _plug():
    from acal.discover.plug import Plug   # a discovering runner's module only
    return Plug()


def run(lines, emit):
    """The line protocol (above) through a Runner; emit(tag, values) for each output record."""
    r = Runner(emit)
    buf = None
    for line in lines:
        f = line.split()
        if not f:
            continue
        tag = f[0]
        if tag == "B":
            n = int(f[1])
            if buf is None or len(buf) < 3 * n:
                buf = array("i", bytearray(12 * n))   # viper scans read int arrays
            for i in range(3 * n):
                buf[i] = int(f[2 + i])
            r.samples(buf, n)
        elif tag == "X":
            r.gap()
        elif tag == "W":
            r.worn(f[1] == "1")
        elif tag == "T":
            r.conditions(*[int(f[1 + c]) for c in range(COND)])
        elif tag == "P":
            r.point(int(f[1]), int(f[2]), int(f[3]))
        elif tag == "G":
            r.group(f[1])
        elif tag == "E":
            r.end()
        elif tag == "C":
            r.configure([int(v) for v in f[1:]])
        else:
            raise ValueError("unknown line: " + tag)


def print_record(tag, values):
    print(tag + " " + " ".join([str(v) for v in values]))


def main():
    with open(sys.argv[1]) as fh:
        run(fh, print_record)


if __name__ == "__main__":
    main()
