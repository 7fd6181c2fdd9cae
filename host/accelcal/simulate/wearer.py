"""A wrist-worn day, simulated: what a wearable's LIS3DH sees, with the truth kept.

Two layers, so that physical effects can be added between them (issue "model discovery"):

* **Wearer** - the activity schedule and the true specific force at the wrist in the sensor frame
  (g), plus the temperature the chip sits at (degC).  Sensor axes on the wrist: x along the
  forearm toward the hand, y across the wrist, z out of the watch face; a still, face-up watch
  reads (0, 0, +1) g.
* **Sensor** - turns true specific force into what the chip measures: the 9 parameters of the
  paper's model (scale, cross-axis, offset; LIS3DH orders of magnitude), then any extra effects
  (objects with ``apply(a, temp_c, t_s)`` and ``truth()``), then white noise of the LIS3DH's
  220 ug/sqrt(Hz) over the ODR/2 bandwidth.  Quantisation and clipping belong to the chip: the
  simulated LIS3DH does them for the virtual board, ``quantise`` for recordings.

A day (from midnight): asleep until about 07:00 with a posture change every 10-90 min, each a
few seconds of movement; then a mix of standing, walking (arm swing and step impacts), sitting
with the hands on the lap, desk work (typing: small fast wrist motion, pauses in between) and
rest on a sofa; off the wrist for a shower (face up on a shelf, at room temperature); in bed
about 23:00.  Rest segments last from seconds (pauses in typing) to tens of minutes (sleep
postures).  Orientations cluster around the postures, so the sphere is unevenly covered, as in
the paper's figure 5.

Temperature: the chip follows a target (skin 32-33 degC awake, 35 degC under a blanket,
room 21-23 degC off the wrist) with a 15-minute time constant: not collinear with time.

Recording columns: when a hidden effect follows a column of the recording (a declared effect,
regressor "column:NAME"), the column is written after temp and holds the wearable's battery
voltage (battery_voltage): a LiPo charged for an hour each morning and discharged over the day;
in V, or in whole mV for the board's own supply column (supply_mv, supply_offset).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from accelcal import simulate
from accelcal.files.csvtext import fixed_rows
from accelcal.files.outputs import atomic, write_text
from accelcal.model.effects import SUPPLY_COLUMN
from accelcal.simulate.stimulus import StimulusWriter
from accelcal.vocabulary import documented

NOISE_DENSITY_G = 220e-6      # LIS3DH: 220 ug/sqrt(Hz)
TEMP_TAU_S = 900.0            # chip temperature follows its target with this time constant

# Posture clusters: mean gravity direction in the sensor frame (what a still sensor reads), the
# angular spread (deg) around it, and the roll freedom about the forearm (deg).
POSTURES = {
    # asleep
    "supine_palm_down": ((0.0, 0.0, 1.0), 12, 25),
    "supine_palm_in": ((0.0, 1.0, 0.1), 12, 25),
    "side_left": ((0.1, -0.9, 0.4), 15, 30),
    "side_right": ((-0.2, 0.5, -0.8), 15, 30),
    "prone": ((0.2, -0.1, -1.0), 12, 25),
    "hand_under_pillow": ((-0.7, 0.3, 0.6), 15, 20),
    # awake
    "desk_face_up": ((0.05, 0.0, 1.0), 8, 10),
    "lap_palm_in": ((-0.35, 0.85, 0.35), 12, 20),
    "sofa_armrest": ((0.2, 0.6, 0.75), 12, 20),
    "arm_hanging": ((-1.0, 0.15, 0.05), 12, 40),
    "hand_to_face": ((0.85, 0.3, 0.4), 12, 30),    # phone at the ear, chin on the hand
    "palm_up": ((0.1, 0.3, -0.95), 12, 20),         # hands open on the lap, arms crossed
    "hand_on_hip": ((-0.3, -0.85, 0.3), 12, 20),    # standing, hand on the hip or in a pocket
    "on_shelf": ((0.0, 0.0, 1.0), 1, 0),     # off the wrist, face up
}
SLEEP = ("supine_palm_down", "supine_palm_in", "side_left", "side_right", "prone",
         "hand_under_pillow")
SLEEP_WEIGHTS = (0.3, 0.2, 0.18, 0.14, 0.1, 0.08)

ACTIVITIES = ("sleep", "awake_rest", "typing", "walking", "standing", "fidget", "off_wrist")


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perturb(rng, d, spread_deg):
    """A direction within about spread_deg of d."""
    return _unit(d + rng.normal(scale=np.radians(spread_deg), size=3))


def _slerp(a, b, s):
    """Directions from a to b for s in [0, 1] (s: array)."""
    cos = np.clip(a @ b, -1.0, 1.0)
    ang = np.arccos(cos)
    if ang < 1e-6:
        return np.tile(a, (len(s), 1))
    sa = np.sin(ang)
    return (np.sin((1 - s) * ang)[:, None] * a + np.sin(s * ang)[:, None] * b) / sa


@dataclass
class Segment:
    start_s: float
    seconds: float
    activity: str
    posture: str | None = None


@dataclass
class Sensor:
    """The chip's errors (paper parameter order: kxx kyy kzz kxy kxz kyz ox oy oz) and effects."""
    params: np.ndarray
    noise_g: float
    effects: list = field(default_factory=list)

    @staticmethod
    def lis3dh(rng: np.random.Generator, rate_hz: int, effects=()) -> "Sensor":
        """LIS3DH orders of magnitude: zero-g offset +-40 mg typ. (per axis, here uniform in
        +-60 mg), sensitivity within a few % (+-3 %), cross-axis sensitivity about 1 %."""
        s = 1 + rng.uniform(-0.03, 0.03, 3)
        t = rng.uniform(-0.01, 0.01, 3)
        o = rng.uniform(-0.06, 0.06, 3)
        p = np.array([s[0], s[1], s[2], s[1] * t[0], s[2] * t[1], s[2] * t[2], *o])
        return Sensor(p, NOISE_DENSITY_G * np.sqrt(rate_hz / 2.0), list(effects))

    def measure(self, rng, a_true, temp_c, t_s, cols=None):
        """What the chip measures (g, before quantisation) for true specific force a_true;
        cols: the recording columns (by name) effects may follow."""
        v = simulate.uncorrect(self.params, a_true)
        for e in self.effects:
            v = e.apply(v, temp_c, t_s, cols)
        return v + rng.normal(scale=self.noise_g, size=v.shape)

    def truth(self) -> dict:
        from acal.core.fixed import PARAM_NAMES
        return {"params": dict(zip(PARAM_NAMES, map(float, self.params))),
                "noise_mg": float(self.noise_g * 1e3),
                "effects": [e.truth() for e in self.effects]}


class Wearer:
    """Schedules and synthesises wrist days.  All randomness comes from rng."""

    def __init__(self, rng: np.random.Generator, rate_hz: int):
        self.rng = rng
        self.rate = rate_hz
        self.temp = 30.0
        self.direction = np.array([0.0, 0.0, 1.0])

    # --- schedule ----------------------------------------------------------------------------
    def schedule(self, day: int) -> list[Segment]:
        rng = self.rng
        t0 = day * 86400.0
        segs: list[Segment] = []
        t = t0

        def add(seconds, activity, posture=None):
            nonlocal t
            seconds = max(1.0, float(seconds))
            segs.append(Segment(t, seconds, activity, posture))
            t += seconds

        wake = t0 + 3600 * rng.normal(7.0, 0.4)
        bed = t0 + 3600 * rng.normal(23.0, 0.4)
        shower = t0 + 3600 * rng.uniform(7.5, 21.5)
        showered = False
        while t < wake:  # night: postures, each held 10-90 min, a few seconds of turning between
            add(rng.uniform(2, 8), "fidget")
            add(min(rng.uniform(600, 5400), max(wake - t, 1)), "sleep",
                rng.choice(SLEEP, p=SLEEP_WEIGHTS))
        while t < bed:
            if not showered and t >= shower:
                add(rng.uniform(3, 10), "fidget")
                add(rng.uniform(1200, 2400), "off_wrist", "on_shelf")
                showered = True
                continue
            u = rng.random()
            if u < 0.30:       # desk work: typing bursts with still pauses
                end = t + rng.uniform(600, 3600)
                while t < end:
                    add(rng.exponential(40) + 3, "typing", "desk_face_up")
                    add(rng.exponential(25) + 2, "awake_rest", "desk_face_up")
            elif u < 0.50:
                add(rng.uniform(60, 1500), "walking", "arm_hanging")
            elif u < 0.56:
                add(rng.uniform(30, 600), "standing", "arm_hanging")
            elif u < 0.62:
                add(rng.uniform(10, 400), "awake_rest", "hand_on_hip")
            elif u < 0.68:
                add(rng.uniform(20, 1200), "awake_rest", "lap_palm_in")
            elif u < 0.78:
                add(rng.uniform(5, 180), "awake_rest", "hand_to_face")
            elif u < 0.84:
                add(rng.uniform(10, 600), "awake_rest", "palm_up")
            else:
                add(rng.uniform(60, 2400), "awake_rest", "sofa_armrest")
            add(rng.uniform(1, 6), "fidget")
        while t < t0 + 86400:  # asleep again until midnight
            add(rng.uniform(2, 8), "fidget")
            add(min(rng.uniform(600, 5400), t0 + 86400 - t), "sleep",
                rng.choice(SLEEP, p=SLEEP_WEIGHTS))
        # Clip the last segment to the day's end.
        last = segs[-1]
        last.seconds = t0 + 86400 - last.start_s
        return [s for s in segs if s.seconds > 0]

    # --- signals -----------------------------------------------------------------------------
    def _posture_direction(self, name):
        mean, spread, roll = POSTURES[name]
        d = _perturb(self.rng, _unit(mean), spread)
        if roll:  # roll about the forearm (x)
            a = np.radians(self.rng.uniform(-roll, roll))
            c, s = np.cos(a), np.sin(a)
            d = np.array([d[0], c * d[1] - s * d[2], s * d[1] + c * d[2]])
        return d

    def _target_temp(self, activity, posture):
        if activity == "off_wrist":
            return 21.0 + 2.0 * self.rng.random()
        if activity == "sleep":
            return 34.5 + self.rng.random()
        if activity in ("walking", "standing"):
            return 31.0 + self.rng.random()
        return 32.0 + self.rng.random()

    def signals(self, segs: list[Segment], n_total: int, first_sample: int):
        """True specific force (n, 3) g and chip temperature (n,) degC for samples
        first_sample .. first_sample + n_total - 1 covered by segs."""
        rng = self.rng
        r = self.rate
        a = np.full((n_total, 3), np.nan)
        temp = np.full(n_total, np.nan)
        for sg in segs:
            i0 = int(round(sg.start_s * r)) - first_sample
            i1 = int(round((sg.start_s + sg.seconds) * r)) - first_sample
            i0, i1 = max(i0, 0), min(i1, n_total)
            n = i1 - i0
            if n <= 0:
                continue
            tt = np.arange(n) / r
            if sg.activity == "fidget":  # move from the last direction to a new random-ish one
                new = _perturb(rng, self.direction, 60)
                d = _slerp(self.direction, new, 0.5 - 0.5 * np.cos(np.pi * np.linspace(0, 1, n)))
                a[i0:i1] = d + rng.normal(scale=0.15, size=(n, 3)) * np.hanning(n)[:, None]
                self.direction = new
            elif sg.activity == "walking":
                base = self._posture_direction("arm_hanging")
                f_step = rng.uniform(1.7, 2.1)            # steps per second
                swing = np.radians(rng.uniform(15, 35)) * np.sin(np.pi * f_step * tt)
                # Arm swing: rotate the hanging direction about y (forward-back pendulum).
                c, s = np.cos(swing), np.sin(swing)
                d = np.column_stack([c * base[0] + s * base[2], np.full(n, base[1]),
                                     -s * base[0] + c * base[2]])
                impact = rng.uniform(0.15, 0.4) * np.maximum(np.sin(2 * np.pi * f_step * tt), 0) ** 4
                a[i0:i1] = d * (1 + impact)[:, None] + rng.normal(scale=0.03, size=(n, 3))
                self.direction = base
            elif sg.activity == "typing":
                base = self._posture_direction("desk_face_up")
                wobble = np.cumsum(rng.normal(scale=0.004, size=(n, 3)), axis=0)
                wobble -= np.linspace(0, 1, n)[:, None] * wobble[-1]  # returns to base
                a[i0:i1] = _unit(base + wobble) + rng.normal(scale=0.02, size=(n, 3))
                self.direction = base
            elif sg.activity == "standing":  # small sway: not quite still
                base = self._posture_direction("arm_hanging")
                sway = np.radians(2) * np.sin(2 * np.pi * rng.uniform(0.1, 0.3) * tt + rng.uniform(0, 6))
                a[i0:i1] = _unit(base + np.outer(sway, [0, 0, 1])) + rng.normal(scale=0.004, size=(n, 3))
                self.direction = base
            else:  # sleep, awake_rest, off_wrist: still
                d = self._posture_direction(sg.posture)
                a[i0:i1] = d
                self.direction = d
            # Temperature: first-order approach to the target, exact per sample.
            target = self._target_temp(sg.activity, sg.posture)
            decay = np.exp(-tt / TEMP_TAU_S)
            temp[i0:i1] = target + (self.temp - target) * decay
            self.temp = float(temp[i1 - 1])
        if np.isnan(temp).any():
            raise AssertionError("wearer: segments leave samples uncovered")
        return a, temp


def quantise(v_g: np.ndarray, range_g: int = 2, bits: int = 12) -> np.ndarray:
    """The LIS3DH output registers: round to the digit (1 mg at +-2 g, 12 bits), clip."""
    step = {2: 1e-3, 4: 2e-3, 8: 4e-3, 16: 12e-3}[range_g] * 2 ** (12 - bits)
    lim = 2 ** (bits - 1)
    d = np.clip(np.rint(v_g / step), -lim, lim - 1)
    return d * step


BATTERY_FULL_V = 4.18        # LiPo at the end of its charge
BATTERY_EMPTY_DROP_V = 0.42  # the drop over a day's discharge, with a knee at the end


def battery_voltage(t_s: np.ndarray, charge_hour: float, rng: np.random.Generator) -> np.ndarray:
    """A wearable's LiPo voltage (V) at times t_s: charged for an hour from charge_hour each day
    (rising linearly back to full), then discharged over the day: a slow linear fall and a knee
    near empty; 3 mV of ADC noise.  Not collinear with time (it repeats daily) or temperature."""
    t_s = np.asarray(t_s, dtype=np.float64)
    day_s = 86400.0
    since = np.mod(t_s - charge_hour * 3600.0, day_s)      # s since this day's charge began
    f = np.clip((since - 3600.0) / (day_s - 3600.0), 0.0, 1.0)   # discharge fraction
    v = BATTERY_FULL_V - BATTERY_EMPTY_DROP_V * (0.75 * f + 0.25 * f ** 6)
    low = BATTERY_FULL_V - BATTERY_EMPTY_DROP_V
    charging = since < 3600.0
    v = np.where(charging, low + (BATTERY_FULL_V - low) * since / 3600.0, v)
    return v + rng.normal(scale=0.003, size=len(t_s))


def _write_days(out_csv, stim, wearer, sensor, rng, n_days, total, rate_hz, range_g, progress,
                columns=(), crng=None, charge_hour=7.5):
    # The recording day by day (written whole or not at all) and the stimulus beside it; the
    # further columns (battery voltage) from their own stream crng.
    segs_all: list[Segment] = []
    hours: dict[str, float] = {}
    clipped = 0
    with atomic(out_csv, "wb") as fh:
        fh.write((",".join(["t", "x", "y", "z", "temp", *columns]) + "\n").encode())
        done = 0
        for day in range(n_days):
            segs = wearer.schedule(day)
            n = min(86400 * rate_hz, total - done)
            if n <= 0:
                break
            a, temp = wearer.signals(segs, n, done)
            t = (done + np.arange(n)) / rate_hz
            volts = battery_voltage(t, charge_hour, crng) if columns else None
            # the board's supply column in whole mV (its ADC), any other in V
            cols = {c: np.rint(volts * 1000) if c == SUPPLY_COLUMN else volts for c in columns}
            v = sensor.measure(rng, a, temp, t, cols)
            q = quantise(v, range_g)
            clipped += int((np.abs(q) >= range_g - 0.0015).any(axis=1).sum())
            # np.savetxt's bytes with fmt %.4f,%.3f,%.3f,%.3f,%.2f then %.0f (mV) or %.4f
            fh.write(fixed_rows([t, q[:, 0], q[:, 1], q[:, 2], temp, *cols.values()],
                                [4, 3, 3, 3, 2] + [0 if c == SUPPLY_COLUMN else 4 for c in columns]))
            if stim is not None:
                stim.write(v, temp, cols.get(SUPPLY_COLUMN))
            end_s = (done + n) / rate_hz
            for s in segs:
                if s.start_s < end_s:
                    segs_all.append(s)
                    hours[s.activity] = hours.get(s.activity, 0.0) + \
                        (min(s.start_s + s.seconds, end_s) - s.start_s) / 3600
            done += n
            if progress:
                progress(done, total)
    return hours, segs_all, clipped


@documented
def simulate_wrist(output: str | Path, days: float, rate: int, seed: int,
                   effect=(), stimulus: str | Path | None = None, range_g: int = 2,
                   progress=None, events_within_days: float | None = None) -> dict:
    """Write a recording CSV (t,x,y,z,temp, then any column a hidden effect follows: battery
    voltage) and its truth beside it (NAME.truth.json); with stimulus, also the stimulus file
    for the virtual board.  effects: catalogue names (accelcal.model.effects), drawn with
    realistic magnitudes; a step's shock falls in the middle half of the recording, or of its
    first events_within_days (a held-out study's fit days: a shock in the scored days is one no
    fit of the days before can know).  Returns the truth."""
    from accelcal.model.effects import CATALOGUE, TrueEffect
    out_csv, rate_hz, effects = output, rate, effect
    rng = np.random.default_rng(seed)
    sensor = Sensor.lis3dh(rng, rate_hz)
    # Effects draw from their own stream: the same seed gives the same day with or without them.
    erng = np.random.default_rng([seed, 1])
    span_s = (days if events_within_days is None else min(days, events_within_days)) * 86400
    sensor.effects = [TrueEffect(n, CATALOGUE[n].draw(erng), CATALOGUE[n].draw_reference(erng, span_s))
                      for n in effects]
    columns = tuple(dict.fromkeys(CATALOGUE[n].column for n in effects
                                  if CATALOGUE[n].needs == "col"))
    crng = np.random.default_rng([seed, 2])    # the columns' own stream, as the effects'
    charge_hour = float(crng.uniform(6.5, 9.0))
    wearer = Wearer(rng, rate_hz)
    out_csv = Path(out_csv)
    n_days = int(np.ceil(days))
    total = int(round(days * 86400 * rate_hz))
    stim = StimulusWriter(stimulus, rate_hz, total, SUPPLY_COLUMN in columns) \
        if stimulus is not None else None
    try:
        hours, segs_all, clipped = _write_days(out_csv, stim, wearer, sensor, rng, n_days, total,
                                               rate_hz, range_g, progress, columns, crng,
                                               charge_hour)
    except BaseException:
        if stim is not None:
            stim.abort()
        raise
    if stim is not None:
        stim.close()
    rest = [s.seconds for s in segs_all if s.activity in ("sleep", "awake_rest", "off_wrist")]
    truth = {"kind": "wrist", "seed": seed, "days": days, "rate_hz": rate_hz, "range_g": range_g,
             "samples": total, **sensor.truth(),
             "hours": {k: round(v, 3) for k, v in sorted(hours.items())},
             "still_segments": {"count": len(rest), "min_s": min(rest), "median_s": float(np.median(rest)),
                                "max_s": max(rest)},
             "clipped_samples": clipped,
             **({"columns": {c: f"battery voltage (V): charged 1 h from {charge_hour:.2f} h each "
                                "day, discharged over the day" for c in columns}} if columns else {}),
             "segments": [[round(s.start_s, 2), round(s.seconds, 2), s.activity, s.posture]
                          for s in segs_all]}
    write_text(out_csv.with_suffix(".truth.json"), json.dumps(truth, indent=1))
    return truth
