# Drives the device pipeline from a line protocol.  The same file runs inside CPython (imported)
# and inside the real MicroPython interpreter (as a script), so both runtimes execute the very
# same device code on the very same integers.  MicroPython-compatible: no f-strings with
# expressions beyond str(), no host imports.
#
# Input lines (integers, space separated):
#   C rate seconds threshold axis min_count max_count differ policy iterations fit a_s a_m a_o
#     [kind ...]           threshold 0: from the noise (acal.rest.AUTO); axis 3: all axes;
#                          fit: acal.profile.GRADIENT or NEWTON; the effects of a composed
#                          model (acal.effects ids), if any
#   G name                 start a group (a device): a fresh pipeline
#   T temp time            conditions of what follows: degC, 64 s units (composed models)
#   P x y z                a rest point, Q16 g, offered to the bins
#   B n x0 y0 z0 x1 ...    n samples, Q10 g, fed to the rest detector
#   X                      a gap in the samples: the open segment is dropped
#   W worn                 1/0: rest segments closing in what follows are offered / excluded
#   E                      end of group: calibrate and report
# Output lines:
#   G name
#   R x y z subset temp time   every rest mean (Q16 g), the subset that kept it (-1: not kept)
#                              and the conditions it was seen at
#   K c0 ... c8                points per subset
#   S x y z temp time          every point the bins hold at the end (Q16 g)
#   Y ready temp_span time_span covered   the bins' verdict (1/0), the held points' spread,
#                              and whether they cover every axis (bins.covered(), 1/0)
#   Z ref_temp ref_time        the fit's reference conditions (composed models)
#   F status iterations objective_start objective p0 ... p8 [3 per effect]
#   D n k0 ... k(n-1)          NEWTON: the points the fit was given (in S order) kept (1) or
#                              rejected as outliers (0)
#   N threshold level          the rest threshold in force at the end and the noise level it
#                              came from (Q10 g; AUTO only)
import sys

from acal.pipeline import Pipeline
from acal.profile import NEWTON


def run(lines, emit):
    cfg = None
    pipe = None
    buf = None
    for line in lines:
        f = line.split()
        if not f:
            continue
        tag = f[0]
        if tag == "B":
            n = int(f[1])
            if buf is None or len(buf) < 3 * n:
                buf = [0] * (3 * n)
            for i in range(3 * n):
                buf[i] = int(f[2 + i])
            pipe.add_samples(buf, 0, n)
        elif tag == "X":
            pipe.rest.reset()
        elif tag == "W":
            pipe.worn = f[1] == "1"
        elif tag == "T":
            pipe.temp = int(f[1])
            pipe.time = int(f[2])
        elif tag == "P":
            pipe.offer(int(f[1]), int(f[2]), int(f[3]))
        elif tag == "G":
            emit("G " + f[1])

            def on_rest(x, y, z, s):
                emit("R %d %d %d %d %d %d" % (x, y, z, s, pipe.temp, pipe.time))

            pipe = Pipeline(cfg[0], cfg[1], cfg[2], cfg[3], cfg[4], cfg[5], cfg[6], cfg[7],
                            cfg[8], on_rest, (cfg[10], cfg[11], cfg[12]), cfg[13:], cfg[9])
        elif tag == "E":
            emit("K " + " ".join([str(c) for c in pipe.bins.counts]))
            for s in range(9):
                for k in range(pipe.bins.counts[s]):
                    x, y, z = pipe.bins.point(s, k)
                    temp, time = pipe.bins.condition(s, k)
                    emit("S %d %d %d %d %d" % (x, y, z, temp, time))
            b = pipe.bins
            emit("Y %d %d %d %d" % (1 if b.ready() else 0, b.temp_span(), b.time_span(),
                                    1 if b.covered() else 0))
            status = pipe.calibrate()
            o = pipe.optimiser
            emit("Z %d %d" % (pipe.ref_temp, pipe.ref_time))
            q = 40 - o.OBJ_Q   # the host reads Q40 g^4 (fixed.OBJ_Q) from either fit
            emit("F %d %d %d %d " % (status, o.iterations, o.objective_start << q,
                                     o.objective << q)
                 + " ".join([str(v) for v in o.p]))
            if pipe.fit == NEWTON:
                emit("D %d " % o.n_given + " ".join([str(o.keep[i]) for i in range(o.n_given)]))
            if pipe.rest.auto and pipe.rest.segments:
                emit("N %d %d" % (pipe.rest.threshold, pipe.rest.gauge.level))
        elif tag == "C":
            cfg = [int(v) for v in f[1:]]
        else:
            raise ValueError("unknown line: " + tag)


def main():
    with open(sys.argv[1]) as fh:
        run(fh, print)


if __name__ == "__main__":
    main()
