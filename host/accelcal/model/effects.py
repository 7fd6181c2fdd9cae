"""Physical effects beyond the paper's 9-parameter model, each declared once.

An effect adds to what the sensor measures, after the 9-parameter errors (v = measured, g):

    temp_offset  v += c (T - T0)             zero-g level moves with temperature (g/degC per axis)
    temp_offset2 v += e (T - T0)^2           ... and curves with it (g/degC^2 per axis)
    temp_scale   v *= 1 + s (T - T0)         sensitivity moves with temperature (1/degC per axis)
    drift        v += d (t - t0) / 1 day     offset moves with time (g/day per axis)
    step         v += j [t >= ts]            offset jumps once, at ts (a shock; g per axis)
    nonlinear    v += q v^2                  quadratic response per axis (1/g)

and shapes the device runs (its generic offsets) that diagnose does not try unless a user
declares an effect of that shape (model/declared.py) or names one in a model:
    time_offset2..4  v += p ((t - t0) / 1 day)^2..4      temp_offset3..4  v += p (T - T0)^3..4
and an effect of a recording column (model/declared.py), of which the board's own supply runs
on it too (diagnose tries it where a recording has the column):
    supply_offset    v += p (V - V0)          V: the supply_mv column (mV), V0 its reference

The same declaration serves the simulator (`measure`: add the effect with true values), the
fits (`correct`: remove it with fitted values, before the 9-parameter correction) and the reports
(names, units, bounds, the regressor to plot residuals against, the physics in a sentence).
T0 and t0 are references taken from the data a model is fitted on (mean temperature, first time),
stored with the fitted parameters; ts, a step's time, is found by a change-point search
(pipeline/composed_lsq.py) and stored beside them.  Effects without a device form (`kind` None)
are fitted and applied on the host only; every other effect runs on the board as the device
kind of its shape (device_kind).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from acal.core import effects as deff
from acal.core.fixed import C_TEMP, C_TIME, DIFFERS, PARAM_NAMES, TEMP_Q
from accelcal.fixedpoint import QUANTITIES, Quantity, hours, params_to_float, params_to_int
from accelcal.methods import correct as base_correct

AXES = "xyz"
# Recording columns an effect may follow (files/recordings.py reads them after t,x,y,z[,temp]):
# lower-case names, not the recording's own (`device` stays a points file's group column).
# supply_mv is the board's own supply in mV, the one column the device reads itself
# (acal.core.effects.SUPPLY_OFFSET, its third condition).
COLUMN_NAME = re.compile(r"[a-z][a-z0-9_]{0,23}")
RESERVED = ("t", "x", "y", "z", "temp", "device")
SUPPLY_COLUMN = "supply_mv"   # the board's supply (fixedpoint.QUANTITIES)
_QUANTITY_OF = {q.column: q for q in QUANTITIES}
SIM_BATTERY_V = 3.9     # the simulator's battery (simulate/wearer.py) is referred to this


@dataclass(frozen=True)
class Effect:
    """One physical effect: per axis, a parameter theta times a regressor x, entering the reading
    as an offset (v + theta x) or a gain (v (1 + theta x)).  Its float maths (measure, correct),
    its device integers (kind, int_scale: Q24 per normalised regressor, device/acal/core/effects.py)
    and its bound live here; tests/device/test_effects.py holds the bound equal to the device's."""
    name: str
    symbol: str             # parameter prefix: c -> cx cy cz
    unit: str               # of the parameters
    scale: float            # report unit per SI-ish unit (e.g. 1e3: g -> mg)
    report_unit: str
    bound: float            # |parameter| <= bound (fit bounds; the device's BOUNDS in Q24)
    true_range: tuple       # simulator: |true value| drawn uniformly in this range
    needs: str | None       # "temp", "t", "col" (a recording column) or None (the reading itself)
    regressor: str          # what residuals are plotted against
    explanation: str
    form: str = "offset"    # "offset": v + theta x;  "gain": v (1 + theta x)
    power: int = 1          # of the temperature regressor: (T - T0)^power
    change_point: bool = False   # the time regressor is a step at ts, found by the fit
    sim_reference: tuple = ()    # simulator: the truth's own reference, e.g. (("T0", 33.0),)
    declared_in: str | None = None   # a user's effects file (model/declared.py); None: built in
    candidate: bool = True  # diagnose tries it (the device's generic shapes: only when named)
    column: str | None = None    # needs "col": the recording column it follows (battery_v, ...)
    lis3dh: str = ""        # the LIS3DH datasheet's typical size: quoted only for its files

    def explain(self, sensor: str | None) -> str:
        """The explanation worded for the sensor a file came from: the LIS3DH's datasheet
        figure for an LIS3DH (accelcal's boards and simulator), none for another device, whose
        sensor's figures are not the LIS3DH's (an ActiGraph, an Axivity...)."""
        if self.lis3dh and sensor == "LIS3DH":
            return f"{self.explanation} Typical for the LIS3DH: {self.lis3dh}."
        return self.explanation

    @property
    def param_names(self) -> list[str]:
        return [f"{self.symbol}{a}" for a in AXES]

    def x(self, v, temp, t, ref, cols=None) -> np.ndarray:
        """The regressor, per axis (broadcast against v): degC from T0 (to the effect's power),
        days from t0, 1 from ts on (a step), a recording column from its reference (its mean,
        ref[column_ref(name)]), or the axis reading squared."""
        if self.needs == "col":
            return ((np.asarray(cols[self.column]) - ref[column_ref(self.column)])
                    ** self.power)[:, None]
        if self.needs == "temp":
            return ((temp - ref["T0"]) ** self.power)[:, None]
        if self.needs == "t":
            if self.change_point:
                return (t >= ref["ts"]).astype(np.float64)[:, None]
            return (((t - ref["t0"]) / 86400.0) ** self.power)[:, None]
        return v ** self.power

    def measure(self, v, theta, temp, t, ref, cols=None):
        """What the sensor reads with the effect added (simulator)."""
        dx = np.asarray(theta) * self.x(v, temp, t, ref, cols)
        return v * (1 + dx) if self.form == "gain" else v + dx

    def correct(self, v, theta, temp, t, ref, cols=None):
        """Remove the effect from measurements (fits, apply): first order, exactly the form the
        device applies in integers (device/acal/core/effects.py)."""
        dx = np.asarray(theta) * self.x(v, temp, t, ref, cols)
        return v - dx * v if self.form == "gain" else v - dx

    # Device integers (device/acal/core/effects.py): Q24 per normalised regressor.
    @property
    def kind(self) -> int | None:
        """The device's id for the effect's shape, None for an effect fitted and applied on the
        host only."""
        if self.needs == "col":   # an offset linear in a column the board reads
            q = self.quantity
            return q.kind if q and (self.power, self.form) == (1, "offset") else None
        return device_kind(self.needs, self.power, self.form, self.change_point)

    @property
    def int_scale(self) -> float:
        """The device's Q24 per normalised regressor (device/acal/core/effects.py): temperature per
        16 degC (temp_offset2: per 64 degC^2), time per 2048 units of 64 s (drift) or, for the
        generic powers, per 2**13 units; the board's supply per SUPPLY_MAX mV; a step, the
        reading and other columns per 1."""
        if self.needs == "col" and self.kind is not None:
            return float(self.quantity.per) * (1 << 24)
        if self.needs == "temp":
            per = {1: 16.0, 2: 64.0}.get(self.power, 16.0 ** self.power)
        elif self.needs == "t" and not self.change_point:
            unit = 2048 if self.power == 1 else 1 << deff.GENERIC_TIME_SHIFT
            per = (unit * deff.DT_UNIT_S / 86400.0) ** self.power
        else:
            per = 1.0
        return per * (1 << 24)

    @property
    def quantity(self) -> Quantity | None:
        """The quantity the board reads that the effect follows (fixedpoint.QUANTITIES: the
        device's bins require its spread), None for the reading itself or another column."""
        return _QUANTITY_OF.get({"temp": "temp", "t": "t", "col": self.column}.get(self.needs))

    def to_int(self, theta) -> list[int]:
        return [int(round(v * self.int_scale)) for v in theta]

    def from_int(self, p) -> np.ndarray:
        return np.asarray(p, dtype=np.float64) / self.int_scale

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        lo, hi = self.true_range
        return rng.uniform(lo, hi, 3) * rng.choice([-1.0, 1.0], 3)

    def draw_reference(self, rng: np.random.Generator, span_s: float) -> dict:
        """The simulator's reference for this effect beyond TrueEffect.REF: its own (a curve's
        T0), and a step's time, uniform in the middle half of the recording."""
        ref = dict(self.sim_reference)
        if self.needs == "col":   # the simulator's column is a battery (simulate/wearer.py)
            ref[column_ref(self.column)] = SIM_BATTERY_V * (1000 if self.column == SUPPLY_COLUMN
                                                            else 1)
        if self.change_point:
            ref["ts"] = float(rng.uniform(0.25, 0.75) * span_s)
        return ref


def kind_of(source: int, power: int, form: int) -> int:
    """The kind the device's table (acal.core.effects.EFFECTS) declares with this source, power
    and form (a step: SOURCE_STEP, 1), 0 when none."""
    for k, row in deff.EFFECTS.items():
        if row[1] == source and row[2] == power and row[3] == form:
            return k
    return 0


def column_ref(name: str) -> str:
    """The reference key (fitted model's `reference`) of a recording column: its mean, C0."""
    return f"{name}0"


_SOURCES = {"temp": deff.SOURCE_TEMP, "t": deff.SOURCE_TIME}
_FORMS = {"offset": deff.FORM_OFFSET, "gain": deff.FORM_SCALE}


def device_kind(needs: str | None, power: int, form: str, change_point: bool) -> int | None:
    """The device kind that computes an effect of this shape, from the device's table
    (acal.core.effects.EFFECTS: kind_of), None when it has none: offsets in a power of
    temperature or time (1..4) or a step in time, a gain linear in temperature, an offset in
    the squared reading.  Gains in time, higher gains in temperature and other powers of the
    reading run on the host only."""
    if form not in _FORMS:
        return None
    if needs is None:   # the reading itself: its own form
        return kind_of(deff.SOURCE_READING, power, deff.FORM_NONLINEAR) or None \
            if form == "offset" else None
    if needs not in _SOURCES:
        return None
    if needs == "t" and change_point:   # a step: its indicator, whatever the power
        return kind_of(deff.SOURCE_STEP, 1, _FORMS[form]) or None
    return kind_of(_SOURCES[needs], power, _FORMS[form]) or None


_GENERIC_DAYS = (1 << deff.GENERIC_TIME_SHIFT) * deff.DT_UNIT_S / 86400.0   # 6.07 days
_GENERIC_BOUND = deff.GENERIC_BOUND / float(1 << 24)                        # 0.05 g


def _board_column(q: Quantity) -> Effect:
    # A board column's built-in effect from its QUANTITIES row (q.effect): the offset linear in
    # the column that the device kind q.kind runs, named as the device names it, its bound the
    # device's 0.05 g per q.per units (the regressor's normalisation).
    symbol, scale, report_unit, explanation = q.effect
    return Effect(deff.NAMES[q.kind], symbol, f"g/{q.unit}", scale, report_unit,
                  _GENERIC_BOUND / q.per, (0.05 / q.per / 10, 0.05 / q.per / 4), "col", q.column,
                  explanation, column=q.column)


def _shape(name: str, needs: str, power: int, unit: str, report_unit: str, bound: float,
           what: str) -> Effect:
    # One of the device's generic offsets as a built-in effect (not a diagnose candidate).
    reg = "temperature" if needs == "temp" else "time"
    return Effect(name, f"{name}_", unit, 1e3, report_unit, bound,
                  (bound / 10, bound / 4), needs, reg,
                  f"The offset follows {what}: a shape the device computes (its generic offsets), "
                  "for an effect a user declares with it.", power=power, candidate=False)


CATALOGUE: dict[str, Effect] = {e.name: e for e in (
    Effect("temp_offset", "c", "g/degC", 1e3, "mg/degC", 0.005, (0.0004, 0.001), "temp", "temperature",
           "The zero-g level moves with temperature: thermal stress in the package bends the MEMS "
           "proof mass's suspension, so rest readings shift with the chip's temperature whatever "
           "the orientation.", lis3dh="+-0.5 mg/degC"),
    Effect("temp_offset2", "e", "g/degC^2", 1e3, "mg/degC^2", 0.001, (0.00008, 0.0002), "temp",
           "temperature",
           "The zero-g level curves with temperature: the package's thermal stress is not linear "
           "in temperature (a bimetal-like bending of the die on its substrate), so rest readings "
           "bow away from a straight line as the chip warms and cools - a curvature a linear "
           "temperature offset leaves behind.", power=2),
    Effect("temp_scale", "s", "1/degC", 1e2, "%/degC", 0.002, (0.0003, 0.0006), "temp", "temperature",
           "Sensitivity changes with temperature: the spring constant and the capacitive readout's "
           "gain drift, so the error grows with the size of the reading along each axis and with "
           "the temperature change.", "gain", lis3dh="0.01 %/degC, more on some parts"),
    Effect("drift", "d", "g/day", 1e3, "mg/day", 0.02, (0.0015, 0.004), "t", "time",
           "The offset moves with time (ageing of the package and its solder stress, supply "
           "changes): rest readings shift steadily over days whatever the temperature."),
    Effect("step", "j", "g", 1e3, "mg", 0.05, (0.003, 0.008), "t", "time",
           "The offset jumps once and stays: a shock (a knock or a drop) shifts the proof mass's "
           "rest position or cracks a solder joint's stress, so rest readings before and after "
           "one moment differ by a constant whatever the orientation - a step, not a trend.",
           change_point=True),
    Effect("nonlinear", "q", "1/g", 1e2, "%/g", 0.05, (0.004, 0.01), None, "axis reading",
           "The response is not linear: each axis reads a little more (or less) than "
           "proportionally at larger accelerations, so the error depends on the squared reading "
           "of that axis, and on which side of zero it is.", power=2,
           lis3dh="+-0.5 % of full scale"),
    # bounds: the device's 0.05 g per unit of its normalised regressor
    _shape("time_offset2", "t", 2, "g/day^2", "mg/day^2", _GENERIC_BOUND / _GENERIC_DAYS ** 2,
           "the square of time"),
    _shape("time_offset3", "t", 3, "g/day^3", "mg/day^3", _GENERIC_BOUND / _GENERIC_DAYS ** 3,
           "the cube of time"),
    _shape("time_offset4", "t", 4, "g/day^4", "mg/day^4", _GENERIC_BOUND / _GENERIC_DAYS ** 4,
           "the fourth power of time"),
    _shape("temp_offset3", "temp", 3, "g/degC^3", "mg/degC^3", _GENERIC_BOUND / 16 ** 3,
           "the cube of temperature"),
    _shape("temp_offset4", "temp", 4, "g/degC^4", "mg/degC^4", _GENERIC_BOUND / 16 ** 4,
           "the fourth power of temperature"),
    # the board's own columns (the supply: supply_offset), each from its QUANTITIES row
    *(_board_column(q) for q in QUANTITIES if q.effect),
)}


def device_effects() -> list[str]:
    """The catalogue's effects the device has a form for (acal.core.effects), in catalogue order."""
    return [n for n, e in CATALOGUE.items() if e.kind is not None]


def _known(name: str, catalogue: dict, where: str = "") -> Effect:
    if name not in catalogue:
        raise ValueError(f"unknown effect {name!r}{where}: known effects are "
                         f"{', '.join(catalogue)} (one you declared? pass its --effects FILE)")
    return catalogue[name]


class ModelSpec:
    """'base' or 'base+NAME+NAME...': the paper's model and its effects, held as the Effect
    objects themselves.  Names are resolved once, when the spec is made, in a catalogue
    (CATALOGUE: the built-in effects and those register() declared in this process): a spec
    keeps meaning what it meant when it was made, whatever is declared later."""

    def __init__(self, effects=(), catalogue: dict | None = None):
        cat = CATALOGUE if catalogue is None else catalogue
        self.parts: tuple[Effect, ...] = tuple(e if isinstance(e, Effect) else _known(e, cat)
                                               for e in effects)

    @staticmethod
    def parse(spec: str, catalogue: dict | None = None) -> "ModelSpec":
        cat = CATALOGUE if catalogue is None else catalogue
        parts = [p.strip() for p in spec.split("+")]
        if not parts or parts[0] != "base":
            raise ValueError(f"model spec {spec!r} must start with 'base' (e.g. base+temp_offset)")
        names = parts[1:]
        for n in names:
            _known(n, cat, f" in model spec {spec!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"model spec {spec!r} names an effect twice")
        if sum(cat[n].change_point for n in names) > 1:
            raise ValueError(f"model spec {spec!r} has two steps; a model holds one")
        return ModelSpec(names, cat)

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects' names, in order."""
        return tuple(e.name for e in self.parts)

    def __str__(self):
        return "+".join(("base",) + self.effects)

    def __repr__(self):
        return f"ModelSpec({self.effects!r})"

    def __eq__(self, other):
        return isinstance(other, ModelSpec) and self.parts == other.parts

    def __hash__(self):
        return hash(self.parts)

    def effect(self, name: str) -> Effect:
        """One of the model's effects by name."""
        return next(e for e in self.parts if e.name == name)

    def with_effect(self, effect: "str | Effect") -> "ModelSpec":
        return ModelSpec(self.parts + (effect,))

    @property
    def param_names(self) -> list[str]:
        return list(PARAM_NAMES) + [p for e in self.parts for p in e.param_names]

    @property
    def host_only(self) -> tuple[str, ...]:
        """The effects with no device form: fitted (lsq) and applied on the host."""
        return tuple(e.name for e in self.parts if e.kind is None)

    @property
    def kinds(self) -> tuple[int, ...]:
        """The device's effect ids (acal.core.effects), in order; ValueError for a model with an
        effect the device does not have."""
        if self.host_only:
            raise ValueError(f"model {self}: {', '.join(self.host_only)} has no device form yet; "
                             "it is fitted and applied on the host (calibrate --method lsq "
                             "--points all)")
        return tuple(e.kind for e in self.parts)

    @property
    def device_model(self) -> str:
        """The model as the device names it (acal.core.effects.NAMES): a declared effect by the
        device kind of its shape."""
        return "+".join(("base",) + tuple(deff.NAMES[k] for k in self.kinds))

    @property
    def columns(self) -> tuple[str, ...]:
        """The recording columns the model's effects follow (battery_v, ...), in order."""
        return tuple(dict.fromkeys(e.column for e in self.parts if e.needs == "col"))

    @property
    def change_point(self) -> str | None:
        """The effect whose time (ts) the fit finds, if any (one per model)."""
        return next((e.name for e in self.parts if e.change_point), None)

    def without(self, name: str) -> "ModelSpec":
        return ModelSpec(tuple(e for e in self.parts if e.name != name))

    def to_int(self, theta) -> list[int]:
        """Float parameters (9 + 3 per effect) -> the device's Q24 integers."""
        out = params_to_int(theta[:9])
        for k, e in enumerate(self.parts):
            out += e.to_int(theta[9 + 3 * k: 12 + 3 * k])
        return out

    def from_int(self, p_int) -> np.ndarray:
        """The device's integers -> float parameters (g, 1/degC, g/day, 1/g)."""
        parts = [params_to_float(p_int[:9])]
        for k, e in enumerate(self.parts):
            parts.append(e.from_int(p_int[9 + 3 * k: 12 + 3 * k]))
        return np.concatenate(parts)

    def check_data(self, temp, t, source: str, cols=None) -> None:
        """ValueError, one line, when the data cannot support the model: a temperature effect
        without temperatures or with too little spread, a drift over too short a span, a column
        effect without its column or with a column that does not vary.  The thresholds are the
        device bins' (acal.core.fixed.DIFFERS: 3 degC (12 in Q2), 12 h)."""
        need_temp = DIFFERS[C_TEMP] / (1 << TEMP_Q)   # the device bins' Q2 degC in degC
        need_h = hours(DIFFERS[C_TIME])
        cols = cols or {}
        for e in self.parts:
            n = e.name
            if e.needs == "col":
                if e.column not in cols:
                    have = ", ".join(cols) or "none"
                    raise ValueError(f"{n} follows a column {e.column!r}; {source} has none "
                                     f"(its further columns: {have})")
                c = np.asarray(cols[e.column])
                if len(c) and float(np.ptp(c)) <= 1e-9 * max(1.0, float(np.max(np.abs(c)))):
                    raise ValueError(f"{n} follows column {e.column!r}, which does not vary "
                                     f"across {source}'s rest points")
            if e.needs == "temp":
                if temp is None:
                    raise ValueError(f"{n} needs a temperature column; {source} has none")
                spread = float(np.ptp(temp)) if len(temp) else 0.0
                if spread < need_temp:
                    raise ValueError(f"{n} needs >= {need_temp:g} degC of temperature spread across "
                                     f"rest points; {source} has {spread:.1f} degC")
            if e.needs == "t":
                span = float(np.ptp(t)) / 3600 if t is not None and len(t) else 0.0
                if span < need_h:
                    raise ValueError(f"{n} needs rest points spanning >= {need_h:g} h; "
                                     f"{source} spans {span:.1f} h")

    def correct(self, theta, v, temp, t, ref, cols=None):
        """Corrected acceleration for measurements v with parameters theta (9 + 3 per effect);
        cols: the recording columns column effects follow, by name."""
        w = v
        for k in reversed(range(len(self.parts))):  # undo in the reverse order of measure
            w = self.parts[k].correct(w, theta[9 + 3 * k: 12 + 3 * k], temp, t, ref, cols)
        return base_correct(theta[:9], w)


class TrueEffect:
    """An effect with true values, as the simulated sensor has it (wearer.Sensor.effects)."""
    REF = {"T0": 25.0, "t0": 0.0}

    def __init__(self, name: str, theta, reference: dict | None = None):
        self.effect = CATALOGUE[name]
        self.theta = np.asarray(theta, dtype=np.float64)
        self.ref = {**self.REF, **(reference or {})}

    def apply(self, v, temp_c, t_s, cols=None):
        return self.effect.measure(v, self.theta, temp_c, t_s, self.ref, cols)

    def truth(self) -> dict:
        e = self.effect
        return {"effect": e.name, "unit": e.unit, "reference": self.ref,
                "params": dict(zip(e.param_names, map(float, self.theta)))}
