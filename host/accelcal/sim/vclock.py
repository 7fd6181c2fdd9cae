# Virtual time for the virtual board, MicroPython-compatible.  Time advances only when the app
# sleeps, so a simulated day runs as fast as the interpreter can process it; `speed` > 0 also
# sleeps for real, 1/speed of the virtual duration (speed=1: real time).
#
# ticks_us() wraps as time.ticks_us() does on a board: modulo TICKS_PERIOD (2**30, MicroPython's
# small-int range), so an app that forgets ticks_diff() breaks here as it would there; start_us
# puts the first wrap wherever a test wants it.  now_us() is the simulator's own unwrapped time.
import time

TICKS_PERIOD = 1 << 30
_TICKS_MAX = TICKS_PERIOD - 1
_TICKS_HALF = TICKS_PERIOD >> 1


class Clock:
    def __init__(self, speed=0, start_us=0):
        self.us = start_us
        self.speed = speed

    def now_us(self):
        return self.us

    def ticks_ms(self):
        return (self.us // 1000) & _TICKS_MAX

    def ticks_us(self):
        return self.us & _TICKS_MAX

    def sleep_us(self, us):
        if us > 0:
            self.us += us
            if self.speed:
                time.sleep_us(us // self.speed) if hasattr(time, "sleep_us") else time.sleep(us / 1e6 / self.speed)

    def sleep_ms(self, ms):
        self.sleep_us(ms * 1000)

    def ticks_diff(self, a, b):
        """a - b for ticks that wrap, as time.ticks_diff: in [-2**29, 2**29)."""
        return ((a - b + _TICKS_HALF) & _TICKS_MAX) - _TICKS_HALF
