# Everything the logger app does after acquisition (acal/logger/app.py reads the sensor): rest
# detection -> bins -> calibration when the bins fill (and again later, so drift is tracked) ->
# applying the current calibration; the log's records.  Deterministic in the samples it is fed:
# the host's `accelcal replay` feeds it a pulled capture and must log the same records.
import struct
from array import array

from acal.core import effects
from acal.logger import log
from acal.core import profile as profiles
from acal.core.fixed import N_PARAMS, POINT_ONE_G, TEMP_Q, C_TEMP, C_TIME, C_SUPPLY
from acal.core.calibration import Calibration
from acal.core.model import in_bounds, effects_within
from acal.core.status import OK, usable
from acal.core.pipeline import Pipeline
from acal.core.bins import conditions

VERSION = 4  # 2: profiles (BOOT carries the fit); 3: EFFECT's reference temperature in Q2 degC;
#   4: DISCOVERY carries the effect its parameters are of
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
_REST_SIZE = struct.calcsize(log.FORMATS[log.REST]) + log.OVERHEAD   # a REST record's bytes


class Processor:
    """profile: acal.core.profile.WEAR (the default) or PAPER, whose settings (profile.settings) any of
    seconds, threshold, axis, min_count, max_count, differ, policy, iterations, fit given here
    override (as Pipeline); range_g: the sensor's full scale (the apply's format, fixed.py);
    recal_seconds: least time between calibrations; logger: a log.Log;
    capture: a log.Log for the raw samples or None; store: a log.CalStore or None; model: 'base'
    (the paper's) or a composed model, e.g. 'base+temp_offset' (effects.py).

    The fit runs in slices, FIT_STEPS_PER_FEED per block fed, so acquisition never waits for it
    (docs/method-and-formats.md "Sliced fit"); the calibration in use changes when it ends.

    With the paper's fit a composed model's bins hold profile.COMPOSED_MAX_COUNT points per
    subset (unless max_count is given).  A composed model's bins are kept across calibrations, so
    their temperature and time spread keeps growing (the paper's model starts afresh after
    each; the wear profile keeps its bins too, its CENTRE rule keeps improving them).  Its time is the board's running time since
    boot in 64 s units (no clock survives a power cut): a stored composed calibration is resumed
    at boot as if the board had not been off.

    discover (model 'base', the wear profile; any full scale): after a usable calibration the board
    looks for its own missing effect (the pipeline's plug, acal/discover/plug.py, sliced as the
    fit; docs/model-discovery.md "Discovery on the board"), and logs a DISCOVERY record; when an
    effect is adopted, the calibration (and the store) switch to the composed model at once, logged as a CAL and
    its EFFECT record.  Powered up again with a stored calibration of a model the discovery
    adopts, the board goes on with that model, not discovering (as if flashed with it)."""

    def __init__(self, logger, rate_hz=100, recal_seconds=6 * 3600, capture=None, store=None,
                 model="base", profile=profiles.DEFAULT, range_g=2, discover=False,
                 **pipeline_settings):
        self.log = logger
        self.capture = capture
        self.store = store
        self.kinds = effects.parse_model(model)
        if discover and store is not None and not self.kinds:
            adopted = _adopted_before(store)
            if adopted:   # resumed as a board flashed with the adopted model (its BOOT says so)
                self.kinds = adopted
                discover = False
        settings = profiles.settings(profile, bool(self.kinds))
        for k in pipeline_settings:
            settings[k] = pipeline_settings[k]
        # The board's conditions now (bins.conditions(1)): C_TEMP Q2 degC and C_SUPPLY mV written
        # by the feeder where it reads them (app.py), C_TIME by feed(); one array, which the
        # pipeline, its bins and the calibration hold too: nothing copied per block.
        self.now = conditions(1)
        self.tracks = bool(self.kinds) or discover   # the feeder's conditions reach the bins
        self.pipe = Pipeline(rate_hz, on_rest=self._on_rest, kinds=self.kinds,
                             plug=_plug() if discover else None,
                             now=self.now if self.tracks else None, **settings)
        self.fitting = False
        self.recal_samples = recal_seconds * rate_hz
        self.rest_log_samples = REST_LOG_SECONDS * rate_hz
        self.day_samples = 86400 * rate_hz
        self.time_unit_samples = effects.DT_UNIT_S * rate_hz
        self.calibration = Calibration(self.kinds, range_g, self.pipe.now)
        # The calibrated samples of each block go to on_samples(buf, n) (interleaved, in
        # Q(calibration.out_q) g: Q13 at 2 g, fixed.py "apply"), once a calibration exists: the
        # wearable's own use of the data hooks in there.
        self.on_samples = None
        self.calibrated = array("i", bytearray(12 * log.SAMPLES_PER_RECORD))
        self.params = [0] * len(self.calibration.k)
        self.index = 0              # samples fed so far (lost ones included)
        self.batch_start = 0
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
        p = [0] * len(self.calibration.k)   # the stored parameters, checked before any is taken
        for i in range(N_PARAMS):
            p[i] = rec[7 + i]
        for j in range(len(self.kinds)):
            for i in range(3):
                p[N_PARAMS + 3 * j + i] = store.effects[j][4 + i]
        if not in_bounds(p) or (self.kinds and not effects_within(p, self.kinds, 1)):
            return   # a record the checksum passed but no fit could have made: not applied
        ref = conditions(1)   # the references, now's columns (once, at a restore)
        step_at = 0
        for j in range(len(self.kinds)):
            e = store.effects[j]
            ref[C_TEMP] = e[2]
            at = e[3] - rec[0] // self.time_unit_samples  # resumed where it was saved
            c = effects.condition_of(self.kinds[j])
            if self.kinds[j] == effects.STEP:
                step_at = at     # a step's record holds its time, not the reference
            elif c > C_TIME:
                ref[c] = e[3]    # a board column's record holds its reference (_log_calibration)
            else:
                ref[C_TIME] = at
            for i in range(3):
                self.params[N_PARAMS + 3 * j + i] = e[4 + i]
        for i in range(N_PARAMS):
            self.params[i] = rec[7 + i]
        step_time = step_at - ref[C_TIME] if effects.STEP in self.kinds else 0
        self.calibration.set(self.params, ref, step_time)

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
        if self.rest_bytes + _REST_SIZE > allowance:
            self.rest_skipped += 1
            self.merged += 1
            return
        if self.log.write(log.REST, index, x, y, z, self.now[C_TEMP] >> TEMP_Q, subset,
                          self.merged):
            self.rest_bytes += _REST_SIZE
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
        if self.tracks:  # the block's time (its temperature and supply: the feeder's)
            self.now[C_TIME] = self.index // self.time_unit_samples
        self.pipe.add_samples(buf, 0, n)
        self.index += n
        if self.on_samples is not None and self.calibrations:
            # copied and applied in one pass
            self.calibration.apply_samples(self.calibrated, 0, n, buf)
            self.on_samples(self.calibrated, n)
        self._fit_steps()

    def _fit_steps(self):
        # feed's fit slices, a method apart: in feed they made its frame pass 11 words, which
        # MicroPython takes from the heap on every call (docs/method-and-formats.md "Frames")
        pipe = self.pipe
        if self.fitting:
            for _ in range(FIT_STEPS_PER_FEED):
                if pipe.fit_step():
                    self._fitted()
                    break
        elif pipe.plug is not None and pipe.plug.running:
            for _ in range(FIT_STEPS_PER_FEED):
                if pipe.plug.step():
                    self._discovered()
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
        now = self.now
        if self.uses_supply and now[C_SUPPLY] != self._cap_supply:   # replays need it too
            if not c.write(log.SUPPLY, self.index, now[C_SUPPLY]):
                self.capture_full = True
                return
            self._cap_supply = now[C_SUPPLY]
        b = c.buf
        struct.pack_into("<IBb", b, 3, self.index, n, now[C_TEMP] >> TEMP_Q)
        log.pack_int16(buf, 3 * n, b, 9)
        if not c.write_payload(log.SAMPLES, 6 + 6 * n):
            self.capture_full = True

    def calibrate(self):
        """Calibrate now, in one go (the app itself slices the fit: feed())."""
        self.last_cal_index = self.index
        self.pipe.begin_fit()
        while not self.pipe.fit_step():
            pass
        status = self._fitted()
        plug = self.pipe.plug
        if plug is not None and plug.running:
            while not plug.step():
                pass
            self._discovered()
        return status

    def _fitted(self):
        # The fit has ended: log it, take its parameters if it is good, start the bins afresh
        # (the paper's model); a discovering board starts its discovery.
        self.fitting = False
        pipe = self.pipe
        o = pipe.optimiser
        status = o.status
        values, extra = self._log_calibration(status, o.iterations,
                                              o.n if pipe.fit == profiles.NEWTON
                                              else pipe.bins.total(),
                                              o.objective_start, o.objective)
        if usable(status):
            self._take(values, extra)
            if pipe.plug is not None:
                pipe.plug.fitted(pipe)   # the discovery's start (the first fit's: from the next)
        if not self.kinds and pipe.fit == profiles.GRADIENT:
            pipe.bins.clear()
        return status

    def _log_calibration(self, status, iterations, points, objective_start, objective):
        # CAL and a composed model's EFFECT records of the optimiser's parameters
        pipe = self.pipe
        p = pipe.optimiser.p
        values = (self.index, self.calibrations + 1, status, iterations, points,
                  _sat32(objective_start >> (pipe.optimiser.OBJ_Q - 24)),
                  _sat32(objective >> (pipe.optimiser.OBJ_Q - 24))) + tuple(p[:N_PARAMS])
        self.log.write(log.CAL, *values)
        extra = []
        for j in range(len(self.kinds)):
            e = N_PARAMS + 3 * j
            ref = pipe.ref
            at = ref[C_TIME]   # a step's record holds the step's time instead
            c = effects.condition_of(self.kinds[j])
            if self.kinds[j] == effects.STEP:
                at += pipe.step_time
            elif c > C_TIME:
                at = ref[c]    # and an effect of a board column (the supply) its reference
            extra.append((self.index, self.kinds[j], ref[C_TEMP], at, p[e], p[e + 1], p[e + 2]))
            self.log.write(log.EFFECT, *extra[j])
        return values, extra

    def _take(self, values, extra):
        # a usable calibration: applied from now on, and stored
        pipe = self.pipe
        self.calibrations = values[1]
        for i in range(len(self.params)):
            self.params[i] = pipe.optimiser.p[i]
        self.calibration.set(self.params, pipe.ref, pipe.step_time)
        if self.store is not None:
            self.store.save(values, extra)

    def _discovered(self):
        # The discovery has chosen: logged; an adopted effect becomes the model at once.
        pipe = self.pipe
        plug = pipe.plug
        d = plug.discovery
        i = d.chosen
        # the effect this round added and its parameters (a second round's follow the first's)
        a = d.new_at
        self.log.write(log.DISCOVERY, self.index, d.kind, d.kind_ids[i] if i >= 0 else 0,
                       d.before, d.errs[i] if i >= 0 else 0, d.betters[i] if i >= 0 else 0,
                       d.blocks, d.new_ids[i] if i >= 0 else 0, d.params[a], d.params[a + 1],
                       d.params[a + 2])
        if not d.adopted:
            return
        f = d.fits
        plug.adopt(pipe)
        self.kinds = pipe.kinds
        self.uses_supply = effects.uses_source(self.kinds, effects.SOURCE_SUPPLY)
        # at the full scale the first was made for (2 * 2**e g: fixed.apply_range_shift)
        self.calibration = Calibration(self.kinds, 2 << self.calibration.e, self.now)
        self.params = [0] * len(self.calibration.k)
        values, extra = self._log_calibration(OK, f[4 * i], f[4 * i + 1], f[4 * i + 2],
                                              f[4 * i + 3])
        self._take(values, extra)


def _plug():
    # a discovering board's plug, early: calibrated as early as without discovery (Plug.early)
    from acal.discover.plug import Plug   # only a discovering board loads the discovery
    return Plug(early=True)


def _adopted_before(store):
    # The stored calibration's effects when they are a model the discovery adopts (a board that
    # discovered an effect and was then powered off goes on with it), else None.
    store.load()
    kinds = tuple(e[1] for e in store.effects)
    if not kinds:
        return None
    from acal.discover.search import adoptable   # only a discovering board loads the discovery
    return kinds if adoptable(kinds) else None


def _sat32(v):
    return v if v < 0xFFFFFFFF else 0xFFFFFFFF
