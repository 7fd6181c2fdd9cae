# The logger app: acquisition -> rest detection -> bins -> calibration when the bins fill (and
# again later, so drift is tracked) -> applying the current calibration; logs on flash.
#
# Processor is everything after acquisition and is deterministic in the samples it is fed: the
# host's `accelcal replay` feeds it a pulled capture and must log the same records.
# App reads the LIS3DH (output registers by default; see lis3dh.py for why not the FIFO),
# retries bus errors, counts what is lost, and feeds the Processor in blocks of 41 samples
# (one capture record each).
import gc
import struct
from array import array

from acal import effects, log
from acal import profile as profiles
from acal.fixed import N_PARAMS, POINT_ONE_G
from acal.calibration import Calibration
from acal.model import in_bounds, effects_within
from acal.status import usable
from acal.pipeline import Pipeline

VERSION = 2  # 2: profiles (BOOT carries the fit)
BLOCK = log.SAMPLES_PER_RECORD
RETRIES = 3
# A rest mean is logged when the bins keep it, when it differs by more than this (max-norm,
# Q16 g: 8 mg) from the last one logged, or after REST_LOG_SECONDS; the rest segments in between
# are counted in the next record.  Rest records also get a daily byte allowance so that 14 days
# fit in the flash budget whatever the wearer does (docs/boards-and-logs.md "Flash budget").
REST_LOG_DIFFER = (8 * POINT_ONE_G) // 1000
REST_LOG_SECONDS = 600
REST_BUDGET_BYTES = 14 * 60000  # 60 kB a day for 14 days, cumulative: a quiet day saves
REST_BUDGET_DAYS = 14
REST_RESERVE_BYTES = 4000       # of each day's allowance, kept for points the bins keep
COUNTERS_SECONDS = 3600
CAPTURE_FLUSH_RECORDS = 32  # ~8 kB: a flush per record would cost more than the processing
FIT_STEPS_PER_FEED = 4      # fit slices per block fed (41 samples): the fit runs between FIFO reads


class Processor:
    """profile: acal.profile.WEAR (the default) or PAPER, whose settings (profile.settings) any of
    seconds, threshold, axis, min_count, max_count, differ, policy, iterations, fit given here
    override (as Pipeline); range_g: the sensor's full scale (the apply's format, fixed.py; a
    composed model applies at 2 g); recal_seconds: least time between calibrations; logger: a log.Log;
    capture: a log.Log for the raw samples or None; store: a log.CalStore or None; model: 'base'
    (the paper's) or a composed model, e.g. 'base+temp_offset' (effects.py).

    The fit runs in slices, FIT_STEPS_PER_FEED per block fed, so acquisition never waits for it
    (docs/method-and-formats.md "Sliced fit"); the calibration in use changes when it ends.

    With the paper's fit a composed model's bins hold profile.COMPOSED_MAX_COUNT points per
    subset (unless max_count is given).  A composed model's bins are kept across calibrations, so
    their temperature and time spread keeps growing (the paper's model starts afresh after
    each; the wear profile keeps its bins too, its CENTRE rule keeps improving them).  Its time is the board's running time since
    boot in 64 s units (no clock survives a power cut): a stored composed calibration is resumed
    at boot as if the board had not been off."""

    def __init__(self, logger, rate_hz=100, recal_seconds=6 * 3600, capture=None, store=None,
                 model="base", profile=profiles.DEFAULT, range_g=2, **pipeline_settings):
        self.log = logger
        self.capture = capture
        self.store = store
        self.rate_hz = rate_hz
        self.kinds = effects.parse_model(model)
        settings = profiles.settings(profile, bool(self.kinds))
        for k in pipeline_settings:
            settings[k] = pipeline_settings[k]
        self.pipe = Pipeline(rate_hz, on_rest=self._on_rest, kinds=self.kinds, **settings)
        self.fitting = False
        self.recal_samples = recal_seconds * rate_hz
        self.rest_log_samples = REST_LOG_SECONDS * rate_hz
        self.day_samples = 86400 * rate_hz
        self.time_unit_samples = effects.DT_UNIT_S * rate_hz
        self.calibration = Calibration(self.kinds, range_g)
        # The calibrated samples of each block go to on_samples(buf, n) (Q10 g, interleaved),
        # once a calibration exists: the wearable's own use of the data hooks in there.
        self.on_samples = None
        self.calibrated = array("i", bytearray(12 * log.SAMPLES_PER_RECORD))
        self.params = [0] * self.calibration.n_params
        self.index = 0              # samples fed so far (lost ones included)
        self.batch_start = 0
        self.temp = 0               # relative degC, set by the feeder
        self.supply = 0             # the board's supply, mV, set by the feeder (supply_offset)
        self.uses_supply = effects.uses_source(self.kinds, effects.SOURCE_SUPPLY)
        self._cap_supply = -1       # the supply the capture last recorded
        self.calibrations = 0
        self.last_cal_index = -1
        self.last_logged = [0, 0, 0]
        self.last_logged_index = -(1 << 29)
        self.merged = 0
        self.rest_bytes = 0
        self.rest_logged = 0
        self.rest_skipped = 0
        self.capture_full = False
        self._rest_size = struct.calcsize(log.FORMATS[log.REST]) + log.OVERHEAD
        self._cap_mv = None
        if store is not None:
            self._resume(store)

    def _resume(self, store):
        # The stored calibration, if it is of this model.  A board flashed with another model
        # starts uncalibrated but numbers on from the stored calibration, so that its first
        # calibration is the store's newest (the other model's stays in the other slot).
        slot, rec = store.load()
        if rec is None:
            return
        self.calibrations = rec[1]
        if len(store.effects) != len(self.kinds):
            return
        for j in range(len(self.kinds)):
            if store.effects[j][1] != self.kinds[j]:
                return
        p = [0] * self.calibration.n_params   # the stored parameters, checked before any is taken
        for i in range(N_PARAMS):
            p[i] = rec[7 + i]
        for j in range(len(self.kinds)):
            for i in range(3):
                p[N_PARAMS + 3 * j + i] = store.effects[j][4 + i]
        if not in_bounds(p) or (self.kinds and not effects_within(p, self.kinds, 1)):
            return   # a record the checksum passed but no fit could have made: not applied
        ref_temp = 0
        ref_time = 0
        ref_supply = 0
        step_at = 0
        for j in range(len(self.kinds)):
            e = store.effects[j]
            ref_temp = e[2]
            at = e[3] - rec[0] // self.time_unit_samples  # resumed where it was saved
            if self.kinds[j] == effects.STEP:
                step_at = at     # a step's record holds its time, not the reference
            elif self.kinds[j] == effects.SUPPLY_OFFSET:
                ref_supply = e[3]   # a supply's record holds its reference (mV)
            else:
                ref_time = at
            for i in range(3):
                self.params[N_PARAMS + 3 * j + i] = e[4 + i]
        for i in range(N_PARAMS):
            self.params[i] = rec[7 + i]
        step_time = step_at - ref_time if effects.STEP in self.kinds else 0
        self.calibration.set(self.params, ref_temp, ref_time, step_time, ref_supply)

    def _on_rest(self, x, y, z, subset):
        index = self.batch_start + self.pipe.position
        last = self.last_logged
        d = REST_LOG_DIFFER
        near = -d < x - last[0] < d and -d < y - last[1] < d and -d < z - last[2] < d
        if subset < 0 and near and index - self.last_logged_index < self.rest_log_samples:
            self.merged += 1
            return
        allowance = (REST_BUDGET_BYTES // REST_BUDGET_DAYS) * (1 + index // self.day_samples)
        if subset < 0:
            allowance -= REST_RESERVE_BYTES
        if self.rest_bytes + self._rest_size > allowance:
            self.rest_skipped += 1
            self.merged += 1
            return
        if self.log.write(log.REST, index, x, y, z, self.temp, subset, self.merged):
            self.rest_bytes += self._rest_size
            self.rest_logged += 1
        self.merged = 0
        last[0] = x
        last[1] = y
        last[2] = z
        self.last_logged_index = index

    def feed(self, buf, n):
        """n samples (Q10 g, interleaved) that follow the previous ones without a gap."""
        if self.capture is not None and not self.capture_full:
            self._capture(buf, n)
        self.batch_start = self.index
        pipe = self.pipe
        if self.kinds:  # the block's conditions, for the bins and for applying the calibration
            pipe.temp = self.temp
            pipe.time = self.index // self.time_unit_samples
            pipe.supply = self.supply
            self.calibration.temp = pipe.temp
            self.calibration.time = pipe.time
            self.calibration.supply = self.supply
        pipe.add_samples(buf, 0, n)
        self.index += n
        if self.on_samples is not None and self.calibrations:
            out = self.calibrated
            self.calibration.apply_samples(out, 0, n, buf)   # copied and applied in one pass
            self.on_samples(out, n)
        if self.fitting:
            for _ in range(FIT_STEPS_PER_FEED):
                if pipe.fit_step():
                    self._fitted()
                    break
        elif pipe.ready() and (self.last_cal_index < 0 or
                               self.index - self.last_cal_index >= self.recal_samples):
            pipe.begin_fit()
            self.fitting = True
            self.last_cal_index = self.index  # calibrations start recal_samples apart

    def gap(self, lost):
        """lost samples were never read: the open segment is dropped."""
        if lost <= 0:
            return
        if self.capture is not None and not self.capture_full:
            if not self.capture.write(log.GAP, self.index, lost):
                self.capture_full = True
        self.pipe.rest.reset()
        self.index += lost

    def _capture(self, buf, n):
        c = self.capture
        if self.uses_supply and self.supply != self._cap_supply:   # replays need it too
            if not c.write(log.SUPPLY, self.index, self.supply):
                self.capture_full = True
                return
            self._cap_supply = self.supply
        b = c.buf
        struct.pack_into("<IBb", b, 3, self.index, n, self.temp)
        log.pack_int16(buf, 3 * n, b, 9)
        if not c.write_payload(log.SAMPLES, 6 + 6 * n):
            self.capture_full = True

    def calibrate(self):
        """Calibrate now, in one go (the app itself slices the fit: feed())."""
        self.last_cal_index = self.index
        self.pipe.begin_fit()
        while not self.pipe.fit_step():
            pass
        return self._fitted()

    def _fitted(self):
        # The fit has ended: log it, take its parameters if it is good, start the bins afresh
        # (the paper's model).
        self.fitting = False
        pipe = self.pipe
        o = pipe.optimiser
        status = o.status
        number = self.calibrations + 1
        values = (self.index, number, status, o.iterations,
                  o.n if pipe.fit == profiles.NEWTON else pipe.bins.total(),
                  _sat32(o.objective_start >> (o.OBJ_Q - 24)),
                  _sat32(o.objective >> (o.OBJ_Q - 24))) + tuple(o.p[:N_PARAMS])
        self.log.write(log.CAL, *values)
        extra = []
        for j in range(len(self.kinds)):
            e = N_PARAMS + 3 * j
            at = pipe.ref_time   # a step's record holds the step's time instead
            if self.kinds[j] == effects.STEP:
                at += pipe.step_time
            elif self.kinds[j] == effects.SUPPLY_OFFSET:
                at = pipe.ref_supply   # and a supply's its reference (mV)
            extra.append((self.index, self.kinds[j], pipe.ref_temp, at,
                          o.p[e], o.p[e + 1], o.p[e + 2]))
            self.log.write(log.EFFECT, *extra[j])
        if usable(status):
            self.calibrations = number
            for i in range(len(self.params)):
                self.params[i] = o.p[i]
            self.calibration.set(self.params, pipe.ref_temp, pipe.ref_time, pipe.step_time,
                                 pipe.ref_supply)
            if self.store is not None:
                self.store.save(values, extra)
        if not self.kinds and pipe.fit == profiles.GRADIENT:
            pipe.bins.clear()
        return status


def _sat32(v):
    return v if v < 0xFFFFFFFF else 0xFFFFFFFF


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


_TICKS_HALF = 1 << 29   # time.ticks_us wraps at 2^30 (MicroPython's small ints)


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
    """board: a module from boards/ (i2c(), I2C_ADDRESS, optional clock); settings: rate_hz,
    range_g, fifo, capture_bytes, log_budget, plus Processor settings."""

    def __init__(self, board, rate_hz=100, range_g=2, fifo=False, capture_bytes=0,
                 log_budget=1 << 20, prefix="", **processor_settings):
        from acal.lis3dh import LIS3DH, LIS3DHError
        self.board = board
        self.clock = getattr(board, "clock", None) or RealClock()
        self.rate_hz = rate_hz
        self.period_us = 1000000 // rate_hz
        self.fifo = fifo
        self.samples = 0
        self.lost = 0
        self.fifo_overruns = 0
        self.bus_errors = 0
        self.bus_retries = 0
        # int arrays: the hot loops read them through typed pointers (acal/emit.py)
        self.buf = array("i", bytearray(12 * (32 if fifo else BLOCK)))
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
        self.sensor = None
        for attempt in range(RETRIES):  # a bus fault while probing is retried like any other
            try:
                self.sensor = LIS3DH(board.i2c(), board.I2C_ADDRESS, rate_hz, range_g, True, fifo)
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
        # the board's supply in mV (an optional supply_mv() in its board file), read once per
        # block: what a supply_offset model follows
        self.supply_mv = getattr(board, "supply_mv", None)
        if self.proc.uses_supply and self.supply_mv is None:
            raise ValueError("model follows the board's supply: its board file needs supply_mv()")
        p = self.proc.pipe
        self.log.write(log.BOOT, self.log.size, VERSION, rate_hz, p.rest.length // rate_hz,
                       p.rest.threshold, p.rest.axis, range_g, 1 if fifo else 0, p.bins.min_count,
                       p.bins.max_count, p.bins.differ, p.iterations,
                       self.proc.recal_samples // rate_hz, -128 if ref is None else ref,
                       effects.model_code(self.proc.kinds), p.fit)

    def _retry(self, fn):
        for attempt in range(RETRIES):
            try:
                return fn()
            except OSError:
                self.bus_errors += 1
                if attempt + 1 < RETRIES:
                    self.bus_retries += 1
        return None

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

    def _flush(self):
        if self.fill:
            try:  # one try: a failed temperature read keeps the last value
                self.proc.temp = self.sensor.temperature() + self.temp_ref
            except OSError:
                self.bus_errors += 1
            if self.supply_mv is not None:
                try:  # as the temperature: a failed read keeps the last value
                    mv = self.supply_mv()
                    self.proc.supply = 0 if mv < 0 else (65535 if mv > 65535 else mv)
                except OSError:
                    self.bus_errors += 1
            self.proc.feed(self.block, self.fill)
            self.fill = 0

    def _account(self, got):
        # got samples were just read; anything the chip produced before them and we never saw
        # is lost, and lies before them in the stream.
        self._elapsed()
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

    # Both readers retry inline and hold no closures: a lambda here would make its captured
    # variables heap cells, allocated on every call.
    def _step_register(self):
        s = self.sensor
        self.clock.sleep_us(self.period_us)
        for attempt in range(RETRIES):
            try:
                s.read_sample()
                break
            except OSError:
                self.bus_errors += 1
                if attempt + 1 == RETRIES:
                    return 0  # lost; _account finds it on the next read
                self.bus_retries += 1
        self._account(1)
        self._push(s.x, s.y, s.z)
        self.samples += 1
        return 1

    def _step_fifo(self):
        s = self.sensor
        buf = self.buf
        self.clock.sleep_us(self.period_us * 25)  # 25 of the FIFO's 32 levels
        n = 0
        over = False
        for attempt in range(RETRIES):
            try:
                n = s.fifo_level()
                over = s.overrun  # counted once, however many retries
                if n:
                    s.read_fifo(buf, 0, n)
                break
            except OSError:
                self.bus_errors += 1
                if attempt + 1 == RETRIES:
                    return 0
                self.bus_retries += 1
        if over:
            self.fifo_overruns += 1
        if not n:
            return 0
        self._account(n)
        for i in range(n):
            self._push(buf[3 * i], buf[3 * i + 1], buf[3 * i + 2])
        self.samples += n
        return n

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
    """Entry point on a board: `import acal.app; acal.app.main(...)` (deploy writes it into
    main.py).  seconds=None runs for ever.  The board file (boards/NAME.py) is deployed as
    acal_board.py: CircuitPython's built-in `board` module owns that name."""
    import acal_board
    app = App(acal_board, **settings)
    if verbose:
        app.progress = report
    app.run(seconds)
    return app
