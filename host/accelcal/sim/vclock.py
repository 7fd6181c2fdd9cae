# Virtual time for the virtual board, MicroPython-compatible.  Time advances only when the app
# sleeps, so a simulated day runs as fast as the interpreter can process it; `speed` > 0 also
# sleeps for real, 1/speed of the virtual duration (speed=1: real time).
import time


class Clock:
    def __init__(self, speed=0):
        self.us = 0
        self.speed = speed

    def now_us(self):
        return self.us

    def ticks_ms(self):
        return self.us // 1000

    def ticks_us(self):
        return self.us

    def sleep_us(self, us):
        if us > 0:
            self.us += us
            if self.speed:
                time.sleep_us(us // self.speed) if hasattr(time, "sleep_us") else time.sleep(us / 1e6 / self.speed)

    def sleep_ms(self, ms):
        self.sleep_us(ms * 1000)

    def ticks_diff(self, a, b):
        return a - b  # virtual ticks never wrap
