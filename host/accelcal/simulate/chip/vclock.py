# Virtual time for the virtual board, MicroPython-compatible.  Time advances only when the app
# sleeps, so a simulated day runs as fast as the interpreter can process it; `speed` > 0 also
# sleeps for real, 1/speed of the virtual duration (speed=1: real time).
#
# ticks_us() wraps as time.ticks_us() does on a board: modulo TICKS_PERIOD (2**30, MicroPython's
# small-int range), so an app that forgets ticks_diff() breaks here as it would there; start_us
# puts the first wrap wherever a test wants it.
#
# 32-bit faithful: every int stays below 2**30, so the clock allocates nothing on a 32-bit port.
# The simulator's own unwrapped time is kept as whole seconds `s` (a board runs 34 years before
# it reaches 2**30) and microseconds `us` in [0, 10**6); the wrapped tick counters are kept
# beside it.  now_us() gives the unwrapped time as one int, for host code (a long past 17.9 min
# on a 32-bit port).
import time

TICKS_PERIOD = 1 << 30
_TICKS_MAX = TICKS_PERIOD - 1
_TICKS_HALF = TICKS_PERIOD >> 1
_US_PER_S = 1000000


class Clock:
    def __init__(self, speed=0, start_us=0):
        self.speed = speed
        self.s = 0
        self.us = 0
        self.t_us = 0      # ticks_us, wrapped
        self.t_ms = 0      # ticks_ms, wrapped
        self.ms_part = 0   # microseconds not yet a whole millisecond of ticks_ms
        self.set_us(start_us)

    def set_us(self, start_us):
        """Put the clock at start_us (host code: any int)."""
        self.s = start_us // _US_PER_S
        self.us = start_us % _US_PER_S
        self.t_us = start_us & _TICKS_MAX
        self.t_ms = (start_us // 1000) & _TICKS_MAX
        self.ms_part = start_us % 1000

    def now_us(self):
        return self.s * _US_PER_S + self.us

    def ticks_ms(self):
        return self.t_ms

    def ticks_us(self):
        return self.t_us

    def sleep_us(self, us):
        if us > 0:
            self._advance(us)
            if self.speed:
                time.sleep_us(us // self.speed) if hasattr(time, "sleep_us") else time.sleep(us / 1e6 / self.speed)

    def _advance(self, us):
        # us < 2**29 a call (a board's sleep is far shorter)
        v = self.us + us
        if v >= _US_PER_S:
            self.s += v // _US_PER_S
            v %= _US_PER_S
        self.us = v
        self.t_us = _wrap_add(self.t_us, us)
        m = self.ms_part + us
        self.t_ms = _wrap_add(self.t_ms, m // 1000)
        self.ms_part = m % 1000

    def sleep_ms(self, ms):
        self.sleep_us(ms * 1000)

    def ticks_diff(self, a, b):
        """a - b for ticks that wrap, as time.ticks_diff: in [-2**29, 2**29)."""
        d = a - b
        if d >= _TICKS_HALF:
            return d - _TICKS_HALF - _TICKS_HALF
        if d < -_TICKS_HALF:
            return d + _TICKS_HALF + _TICKS_HALF
        return d


def _wrap_add(t, d):
    # (t + d) mod 2**30 for t in [0, 2**30), d in [0, 2**29), with no int past 2**30 on the way
    w = t - _TICKS_HALF + d - _TICKS_HALF
    return w + _TICKS_HALF + _TICKS_HALF if w < 0 else w
