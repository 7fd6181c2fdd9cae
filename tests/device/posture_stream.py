"""The script the board-discovery tests (test_discover.py) and the install-unit tests
(test_install_units.py) run under CPython and the real MicroPython: a Processor with the settings
given as argv[2] (default: a discovering board), fed rest postures REST (x y z temp, Q10 g, from
test_discover.postures) of 6 s each with +-2 LSB noise, then 2 s of motion and a gap of GAP
samples; it prints the calibrations, the model's kinds and the acal modules it loaded.
STREAM % (REST, GAP) is the script; run it as `SCRIPT LOG [SETTINGS]`."""

STREAM = r'''
import sys
from array import array
from acal.logger import log
from acal.logger.processor import Processor
from acal.core.fixed import C_TEMP, TEMP_Q

REST = %s
GAP = %d


def run(path, settings):
    lg = log.Log(path)
    p = Processor(lg, 10, store=log.CalStore(path + ".a", path + ".b"), **settings)
    buf = array("i", bytearray(12 * 40))
    seed = 12345
    for s in range(len(REST) // 4):
        p.now[C_TEMP] = REST[4 * s + 3] << TEMP_Q   # whole degC, as the app reads it
        for part in range(3):            # 6 s of rest: noise of +-2 LSB (2 mg)
            for i in range(20):
                for c in range(3):
                    seed = (seed * 1103515245 + 12345) & 0x7FFFFFFF
                    buf[3 * i + c] = REST[4 * s + c] + (seed >> 16) %% 5 - 2
            p.feed(buf, 20)
        for i in range(20):              # 2 s of motion
            for c in range(3):
                buf[3 * i + c] = REST[4 * s + c] + (300 if (i + c) & 1 else -300)
        p.feed(buf, 20)
        p.gap(GAP)
    while p.pipe.plug is not None and p.pipe.plug.running:   # its last slices: the gaps, most of the stream's time, feed nothing
        p.feed(buf, 20)
    lg.close()
    print("CALIBRATIONS", p.calibrations)
    print("KINDS", p.kinds)
    print("MODULES", " ".join(sorted(m for m in sys.modules if m.startswith("acal"))))


run(sys.argv[1], eval(sys.argv[2]) if len(sys.argv) > 2 else {"discover": True})
'''
