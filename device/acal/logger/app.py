# The logger app: acquisition -> rest detection -> bins -> calibration when the bins fill (and
# again later, so drift is tracked) -> applying the current calibration; logs on flash.
#
# Processor (acal/logger/processor.py) is everything after acquisition and is deterministic in the
# samples it is fed: the host's `accelcal replay` feeds it a pulled capture and must log the same
# records.
# App reads the LIS3DH (by default its FIFO, drained past a watermark: the output registers,
# one bus transaction a sample, lose samples on a Pico from 100 Hz; see lis3dh.py), retries bus
# errors, counts what is lost, and feeds the Processor in blocks of 41 samples (one capture
# record each).
import gc
from array import array

from acal.core import effects
from acal.logger import log
from acal.core.fixed import C_TEMP, TEMP_Q, BOARD_READERS
# the Processor and its settings, here too for the app's callers (boards, host scripts)
from acal.logger.processor import (Processor, VERSION, BLOCK, RETRIES, REST_LOG_DIFFER,  # noqa: F401
                            REST_LOG_SECONDS, REST_BUDGET_BYTES, REST_BUDGET_DAYS,
                            REST_RESERVE_BYTES, COUNTERS_SECONDS, CAPTURE_FLUSH_RECORDS,
                            FIT_STEPS_PER_FEED)
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

# FIFO drains: DRAIN samples after the last, with the watermark FTH = DRAIN - 1 (WTM: at least
# DRAIN wait); 7 of the FIFO's 32 levels are the slack for a late drain (a fit slice, a flash
# write): 17.5 ms at 400 Hz, 70 ms at 100 Hz.
DRAIN = 25


class RealClock:
    """A board's own time: time.ticks_us and friends (they wrap; only differences are used)."""

    def __init__(self):
        import time
        self.time = time

    def ticks_us(self):
        return self.time.ticks_us()

    def ticks_diff(self, a, b):
        return self.time.ticks_diff(a, b)

    def sleep_us(self, us):
        self.time.sleep_us(us)

    def sleep_ms(self, ms):
        self.time.sleep_ms(ms)


_TICKS_HALF = const(1 << 29)   # time.ticks_us wraps at 2^30 (MicroPython's small ints)


class MsTicksClock:
    """A board's time from a millisecond counter that wraps at 2^bits, with a sleep (both from
    the board file; CircuitPython: supervisor.ticks_ms(), which wraps at 2^29 ms, 6.2 days).
    ticks_us() is kept from the counter's differences and wraps at 2^30 as time.ticks_us does,
    so the app's rules stay as they are, in whole milliseconds.  Only small ints (< 2^30),
    nothing allocated: it must be read at least every 2^29 us (8.9 min; the app reads it at
    every sample or FIFO drain)."""

    def __init__(self, ticks_ms, sleep_us, bits=29):
        self._ms = ticks_ms
        self.sleep_us = sleep_us
        self._mask = (1 << bits) - 1
        self._last = ticks_ms()
        self._us = 0

    def ticks_us(self):
        ms = self._ms()
        d = ((ms - self._last) & self._mask) * 1000
        self._last = ms
        w = self._us - _TICKS_HALF + d - _TICKS_HALF   # (us + d) mod 2^30, below 2^30 throughout
        self._us = w + _TICKS_HALF + _TICKS_HALF if w < 0 else w
        return self._us

    def ticks_diff(self, a, b):
        d = a - b
        if d >= _TICKS_HALF:
            return d - _TICKS_HALF - _TICKS_HALF
        return d + _TICKS_HALF + _TICKS_HALF if d < -_TICKS_HALF else d


class App:
    """board: a module from boards/ (sensor_bus(bus) or i2c(), I2C_ADDRESS, optional clock and
    FIFO_TABLES: True where the FIFO's codes convert faster through tables, LIS3DH(tables=));
    settings: rate_hz, range_g, fifo (default: the FIFO; False: the output registers, 12 bits,
    one read a sample), bus (None: the board file's BUS; "i2c", "spi", "auto": the LIS3DH's bus,
    where the board file offers sensor_bus), capture_bytes, log_budget, plus Processor settings."""

    def __init__(self, board, rate_hz=100, range_g=2, fifo=True, capture_bytes=0,
                 log_budget=1 << 20, prefix="", bus=None, **processor_settings):
        from acal.logger.lis3dh import LIS3DH, LIS3DHError
        self.board = board
        self.clock = getattr(board, "clock", None) or RealClock()
        self.rate_hz = rate_hz
        self.period_us = 1000000 // rate_hz
        # FIFO waits in whole milliseconds where the clock offers them: MicroPython's rp2
        # time.sleep_us(us) waits us // 1000 ms in WFE and busy-waits the rest (mphalport.c
        # mp_hal_delay_us), up to 1 ms awake a drain; sleep_ms is all WFE (mp_hal_delay_ms).
        self._sleep_ms = getattr(self.clock, "sleep_ms", None)
        self.fifo = fifo
        self.samples = 0
        self.lost = 0
        self.fifo_overruns = 0
        self._owed = 0      # samples a full FIFO drain may have lost that the clock has not shown
        self.bus_errors = 0
        self.bus_retries = 0
        # int arrays: the hot loops read them through typed pointers (acal/core/emit.py)
        self.block = array("i", bytearray(12 * BLOCK))
        self.fill = 0
        self.log = log.Log(prefix + "log.bin", log_budget)
        cap = None
        if capture_bytes:  # a capture is one session's samples: it starts afresh at each boot
            open(prefix + "capture.bin", "wb").close()
            cap = log.Log(prefix + "capture.bin", capture_bytes, CAPTURE_FLUSH_RECORDS)
        store = log.CalStore(prefix + "cal_a.bin", prefix + "cal_b.bin")
        self.proc = Processor(self.log, rate_hz, capture=cap, store=store, range_g=range_g,
                              **processor_settings)
        self.now = self.proc.now   # the conditions the block is read at: written in _flush
        self.sensor = None
        if not hasattr(board, "sensor_bus") and bus not in (None, "i2c"):
            raise ValueError("bus %r: this board file has the LIS3DH on I2C only" % (bus,))
        for attempt in range(RETRIES):  # a bus fault while probing is retried like any other
            try:
                regs = board.sensor_bus(bus) if hasattr(board, "sensor_bus") else board.i2c()
                self.sensor = LIS3DH(regs, board.I2C_ADDRESS, rate_hz, range_g, True, fifo,
                                     DRAIN - 1, fifo and getattr(board, "FIFO_TABLES", False))
                break
            except (OSError, LIS3DHError) as e:
                self.bus_errors += 1
                if attempt + 1 == RETRIES:
                    raise LIS3DHError("LIS3DH setup failed %d times: %s" % (RETRIES, e))
                self.bus_retries += 1
        self.progress = None        # called after each counters record (main: report)
        self.t_last = self.clock.ticks_us()
        self.acc_us = 0
        self.expected = 0
        self.next_counters = COUNTERS_SECONDS * rate_hz
        # OUT_ADC3 is relative to a reference that differs from chip to chip: with the board
        # file's TEMP_REF_C (an int, from one thermometer reading) temperatures are absolute.
        ref = getattr(board, "TEMP_REF_C", None)
        self.temp_ref = 0 if ref is None else ref
        # the columns the board file reads (fixed.BOARD_READERS: the supply's supply_mv()...):
        # (column, function, low, high) for each function it defines, read once a block
        # (_read_conditions); a model following a column whose function it lacks is refused
        readers = []
        for column, name, lo, hi in BOARD_READERS:
            read = getattr(board, name, None)
            if read is not None:
                readers.append((column, read, lo, hi))
            for k in self.proc.kinds:
                if read is None and effects.condition_of(k) == column:
                    raise ValueError("model's %s follows a column the board reads: its board "
                                     "file needs %s()" % (effects.NAMES[k], name))
        self.readers = tuple(readers)
        p = self.proc.pipe
        self.log.write(log.BOOT, self.log.size, VERSION, rate_hz, p.rest.length // rate_hz,
                       p.rest.threshold, p.rest.axis, range_g, 1 if fifo else 0, p.bins.min_count,
                       p.bins.max_count, p.bins.differ, p.iterations,
                       self.proc.recal_samples // rate_hz, -128 if ref is None else ref,
                       effects.model_code(self.proc.kinds), p.fit,
                       0 if p.plug is None else 1)

    def _elapsed(self):
        # Samples the chip has produced since it was configured (exact while both clocks agree).
        now = self.clock.ticks_us()
        self.acc_us += self.clock.ticks_diff(now, self.t_last)
        self.t_last = now
        k = self.acc_us // self.period_us
        self.acc_us -= k * self.period_us
        self.expected += k

    def _push(self, x, y, z):
        b = self.block
        i = 3 * self.fill
        b[i] = x
        b[i + 1] = y
        b[i + 2] = z
        self.fill += 1
        if self.fill == BLOCK:
            self._flush()

    def _read_conditions(self):
        # the block's conditions: the chip's temperature and the board file's columns, each
        # clamped; a failed read (OSError) keeps the last value.  Allocates nothing.  (A try
        # block takes three words of a frame: each read has its own, see _step_fifo.)
        self._read_temperature()
        for reader in self.readers:     # (column, function, low, high)
            v = self._read_column(reader)
            if v is not None:   # clamped before it is stored: the int array takes no wider
                if v < reader[2]:
                    v = reader[2]
                elif v > reader[3]:
                    v = reader[3]
                self.now[reader[0]] = v

    def _read_temperature(self):
        try:
            self.now[C_TEMP] = (self.sensor.temperature() + self.temp_ref) << TEMP_Q
        except OSError:
            self.bus_errors += 1

    def _read_column(self, reader):
        try:
            return reader[1]()
        except OSError:
            self.bus_errors += 1
            return None

    def _flush(self):
        if self.fill:
            self._read_conditions()
            self.proc.feed(self.block, self.fill)
            self.fill = 0

    def _account(self, got):
        # got samples were just read; anything the chip produced before them (by the clock
        # read just before, _elapsed) and we never saw is lost, and lies before them in the
        # stream.
        missing = self.expected - (self.samples + self.lost + got)
        if missing > 0:
            self._flush()
            self.proc.gap(missing)
            self.lost += missing

    def step(self):
        """Sleep until data is due, read it, feed it. Returns samples read."""
        n = self._step_fifo() if self.fifo else self._step_register()
        if self.samples + self.lost >= self.next_counters:
            self.write_counters()
            self.next_counters += COUNTERS_SECONDS * self.rate_hz
        return n

    def _step_register(self):
        self.clock.sleep_us(self.period_us)
        if not self._read(0):
            return 0  # lost; _account finds it on the next read
        self._elapsed()
        self._account(1)
        s = self.sensor
        self._push(s.x, s.y, s.z)
        self.samples += 1
        return 1

    def _step_fifo(self):
        # A drain in steps whose frames stay within 11 words, a try block's three included:
        # MicroPython takes a larger call's frame from the heap on every call
        # (docs/method-and-formats.md "Frames", tests/device/test_frames.py).
        # DRAIN samples after the last drain's clock reading, not after this drain's work: the
        # fit's slices (up to ~100 ms a block on CircuitPython) would otherwise push the next
        # read past the 32 the FIFO holds
        c = self.clock
        wait = self.period_us * DRAIN - c.ticks_diff(c.ticks_us(), self.t_last)
        if wait > 0:
            self._wait(wait)
        n = self._fifo_level()
        if 0 <= n < DRAIN and not (self.sensor.wtm or self.sensor.overrun):
            # WTM clear: the chip has converted fewer than DRAIN (its clock and ours differ, or
            # the drain came a hair early): wait for the rest rather than drain a few
            self._wait(self.period_us * (DRAIN - n))
            n = self._fifo_level()
        if n <= 0 or not self._read(n):
            return 0
        self._settle(n)
        self._account(n)
        self._convert(n)
        self.samples += n
        return n

    # Both readers retry inline and hold no closures: a lambda here would make its captured
    # variables heap cells, allocated on every call.
    def _read(self, n):
        # The chip read, retried: n samples' codes from the FIFO, or (n = 0) one sample from
        # the output registers.  False: the bus failed RETRIES times (the FIFO keeps its
        # samples for the next drain; a register sample is lost, _account finds it).
        attempt = 1
        while not self._read_once(n):
            if self._failed(attempt):
                return False
            attempt += 1
        return True

    def _read_once(self, n):
        try:
            if n:
                self.sensor.read_fifo_raw(n)
            else:
                self.sensor.read_sample()
        except OSError:
            return False
        return True

    def _failed(self, attempt):
        # a bus error at the attempt-th try: True when it was the last of RETRIES
        self.bus_errors += 1
        if attempt == RETRIES:
            return True
        self.bus_retries += 1
        return False

    def _settle(self, n):
        # What a drain of n says of the samples lost before it.
        if self.sensor.overrun:
            # full: a sample converted between the level's read and the FIFO's overwrites one
            # more, lost but found by the clock only at a later drain
            self._owed = 1
            return
        # Not full: the FIFO held every conversion since the last drain's read, so nothing
        # is lost but what a full drain still owes.  A clock that says more are due is off
        # -- a millisecond clock's resolution (CircuitPython's ticks_ms: 1 of 4 008 counted
        # lost at 200 Hz on the emulated Feather), or a chip converting slower than its
        # nominal ODR -- and is set back.
        ahead = self.expected - (self.samples + self.lost + n)
        if ahead > self._owed:
            self.expected -= ahead - self._owed
            ahead = self._owed
        if ahead > 0:
            self._owed -= ahead

    def _convert(self, n):
        # The drain's n samples converted straight into the block a run at a time (a _push
        # call a sample cost 73 us on the emulated Pico; converting into a buffer and copying
        # from it, 0.9 ms a drain of 25 on the emulated Feather, where the copy is bytecode)
        i = 0
        while i < n:
            m = BLOCK - self.fill
            if m > n - i:
                m = n - i
            self.sensor.fifo_convert(self.block, self.fill, i, m)
            self.fill += m
            i += m
            if self.fill == BLOCK:
                self._flush()

    def _wait(self, us):
        # Between drains: rounded up to whole ms where the clock sleeps in ms (<= 1 ms late, of
        # the FIFO's 7 levels of slack: 17.5 ms at 400 Hz)
        if self._sleep_ms is not None:
            self._sleep_ms((us + 999) // 1000)
        else:
            self.clock.sleep_us(us)

    def _fifo_level(self):
        # The FIFO's level (FSS, or 32 with OVRN_FIFO), -1 if the bus failed RETRIES times.  The
        # clock is read first: every sample it says is due is then in the FIFO or overwritten.
        # Read after, it would count as lost the samples converted during the FIFO read (3.4 ms
        # at 400 kHz, 18 ms on CircuitPython's 100 kHz), though they wait in the FIFO
        # (docs/boards-and-logs.md "Lost samples").  An overrun is counted once a drain.
        attempt = 1
        n = self._level_once()
        while n < 0:
            if self._failed(attempt):
                return -1
            attempt += 1
            n = self._level_once()
        if self.sensor.overrun:
            self.fifo_overruns += 1
        return n

    def _level_once(self):
        # the clock, then the level; -1: the bus failed
        try:
            self._elapsed()
            return self.sensor.fifo_level()
        except OSError:
            return -1

    def write_counters(self):
        p = self.proc
        self.log.write(log.COUNTERS, p.index, self.samples, self.lost, self.fifo_overruns,
                       self.bus_errors, self.bus_retries, p.pipe.rest.segments, p.rest_logged,
                       p.rest_skipped)
        if self.progress is not None:
            self.progress(self)
        # Hourly, at a quiet moment: a collection now keeps the heap from filling with the
        # few records' garbage (unix port: a day at 10 Hz took 95 s without it, 19 s with it).
        gc.collect()

    def run(self, seconds=None):
        """Acquire for `seconds` of the board's time (None: for ever), then write counters and
        flush."""
        end = -1 if seconds is None else self.samples + self.lost + seconds * self.rate_hz
        done = getattr(self.board, "exhausted", None)  # the virtual board's stimulus can end
        # The set-up's garbage (imports, ~60 kB on a Pico) collected before acquiring: left in
        # the heap, it cost the emulated Pico 0.7-1.8 % of its core at 100 Hz, by the heap's
        # layout, in one small region of the firmware's code (an allocator's scan past the
        # holes, we think: no symbols to confirm it); docs/boards-and-logs.md
        gc.collect()
        while end < 0 or self.samples + self.lost < end:
            self.step()
            if done is not None and done():
                break
        self._flush()
        if self.proc.capture is not None:
            self.proc.capture.flush()
        self.write_counters()


def report(app):
    """One console line per counters record (hourly), for whoever watches the board's REPL."""
    p = app.proc
    print("acal: %d s, %d samples, %d lost, %d bus errors, %d rest logged, %d calibrations" % (
        (app.samples + app.lost) // app.rate_hz, app.samples, app.lost, app.bus_errors,
        p.rest_logged, p.calibrations))


def main(seconds=None, verbose=True, **settings):
    """Entry point on a board: `import acal.logger.app; acal.logger.app.main(...)` (deploy writes it into
    main.py).  seconds=None runs for ever.  The board file (boards/NAME.py) is deployed as
    acal_board.py: CircuitPython's built-in `board` module owns that name."""
    import acal_board
    app = App(acal_board, **settings)
    if verbose:
        app.progress = report
    app.run(seconds)
    return app
