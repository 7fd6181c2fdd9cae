"""`accelcal apply`: saved parameters applied to every sample of a recording with the device's
per-sample code - its vectorised twin (bridge/twin.py, bit-exact with acal.core.calibration.Calibration) -
or, for a model with an effect the device has no form for, the fit's own float correction."""
from __future__ import annotations

import numpy as np

from acal.core import effects as deff
from acal.core import fixed
from acal.core.bins import conditions
from acal.core.calibration import Calibration
from accelcal.bridge import runtime, twin
from accelcal.errors import InputError
from accelcal.files.outputs import atomic
from accelcal.fixedpoint import COLUMN_QUANTITIES, board_columns, g_to_sample
from accelcal.model.effects import SUPPLY_COLUMN, ModelSpec, column_ref
from accelcal.pipeline.results import ApplyResult
from accelcal.vocabulary import documented


def apply_to_samples(p_int: list[int], xyz_g: np.ndarray, model: str = "base", temp=None, t=None,
                     ref: dict | None = None, source: str = "recording", range_g: int = 2,
                     cols: dict | None = None, first: int = 0) -> np.ndarray:
    """Calibrate samples with the vectorised twin of the device's per-sample code
    (calibration.Calibration, bit-exact with it: tests/bridge/test_vector.py).  A composed
    model needs each sample's temperature (degC) and time (s) and the fit's reference (T0, t0):
    the device sees them in Q2 degC (fixed.TEMP_Q) and 64 s units from t0.  cols: the recording's further
    columns by name, for a model whose effects follow one (the board's supply_mv for the
    device's supply_offset; any other on the host).  first: the first sample's index in its
    recording (the Q10 rounding's dither follows it: fixedpoint.g_to_sample)."""
    spec = ModelSpec.parse(model)
    if spec.host_only:
        return _apply_on_host(spec, p_int, xyz_g, temp, t, ref, source, cols)
    cal = Calibration(spec.kinds, range_g)
    ref_temp = int(round(ref["T0"] * (1 << fixed.TEMP_Q))) if spec.effects else 0   # Q2 degC
    refs = conditions(1)   # the device's references, its columns (bins.COND)
    refs[fixed.C_TEMP] = ref_temp
    try:
        cal.set(p_int, refs)
    except ValueError:
        raise InputError("parameters outside the device's calibration bounds (k 0.75..1.25, "
                         "|misalignment| <= 0.125, |offset| <= 0.25 g, effects within their "
                         "bounds)") from None
    q = g_to_sample(xyz_g, first)
    one_g = float(1 << cal.out_q)   # the calibrated samples' format, Q(13 - e) g (fixed.py)
    if not spec.effects:  # the twin of cal.apply_samples (tests/bridge/test_vector.py: bit-exact)
        return twin.apply_params(p_int, q, range_g=range_g, first=first) / one_g
    board = [c for c in spec.columns if c in {q.column for q in COLUMN_QUANTITIES}]
    _check_inputs(spec, temp, board, cols, source)
    cond = runtime.device_conditions(temp, t, ref["t0"], len(q),
                                     **board_columns({c: cols[c] for c in board}))
    follows_supply = SUPPLY_COLUMN in board
    # the board's supply from its reference (mV), as the device's supply - ref_supply
    dV = cond[:, 2] - int(round(ref[column_ref(SUPPLY_COLUMN)])) if follows_supply else None
    step_time = 0
    if spec.change_point:   # from ts on, as the device compares whole 64 s units
        if "ts" not in ref:
            raise InputError(f"model {spec}: the parameters' reference lacks ts, the step's time")
        step_time = int(np.ceil((ref["ts"] - ref["t0"]) / deff.DT_UNIT_S))
    return twin.apply_params(p_int, q, spec.kinds, cond[:, 0] - ref_temp, cond[:, 1], range_g,
                             step_time, dV) / one_g


def _check_inputs(spec: ModelSpec, temp, columns, cols: dict | None, source: str) -> None:
    """InputError for a model's input the file lacks: temperature, or one of columns."""
    if temp is None and any(e.needs == "temp" for e in spec.parts):
        raise InputError(f"model {spec} needs a temperature column; {source} has none")
    for c in columns:
        if c not in (cols or {}):
            raise InputError(f"model {spec} follows a column {c!r}; {source} has none")


def _apply_on_host(spec: ModelSpec, p_int, xyz_g, temp, t, ref: dict, source: str,
                   cols: dict | None = None) -> np.ndarray:
    """A model with an effect the device does not have, applied in float64 (the fit's own
    correction, spec.correct) to the samples as read."""
    cols = cols or {}
    _check_inputs(spec, temp, spec.columns, cols, source)
    temp = np.zeros(len(xyz_g)) if temp is None else np.asarray(temp, dtype=np.float64)
    return spec.correct(spec.from_int(p_int), np.asarray(xyz_g, dtype=np.float64), temp,
                        np.asarray(t, dtype=np.float64), ref, cols)


def apply_range(declared, given: int | None) -> int:
    """The full scale the device's apply takes for a file: given (apply --range), else the
    file's declared range (rounded up to 2, 4, 8 or 16 g), else 2 g."""
    if given:
        return given
    if declared:
        for r in (2, 4, 8, 16):
            if declared <= r:
                return r
    return 2


def apply_file(p_int: list[int], model: str, ref: dict, path: str, output: str,
               range_g: int | None = None) -> tuple[int, int, int]:
    """Calibrate a recording of any format and length chunk by chunk (accelcal.files.recordings) with
    the device's per-sample code at the full scale apply_range() picks (readings past it are
    clipped, as the device's); writes CSV t,x,y,z[,temp] (g to 1e-6: every step of the device's
    output format, >= 122 ug, kept distinct; degC to 1e-3), then the
    file's further columns as read.  Returns (samples, samples clipped, full scale in g)."""
    from accelcal.files.csvpieces import arrow
    from accelcal.files.recordings import open_recording
    pa, pacsv = arrow()
    rec = open_recording(path)
    rng = apply_range(rec.range_g, range_g)
    limit = (fixed.APPLY_IN_MAX << fixed.apply_range_shift(rng)) / fixed.SAMPLE_ONE_G
    clipped = 0
    names = ["t", "x", "y", "z"] + (["temp"] if rec.has_temp else []) + list(rec.columns)
    schema = pa.schema([(n, pa.float64()) for n in names])
    n = 0
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
    # written whole or not at all: a killed run leaves no partial file that looks like a recording
    with atomic(output, "wb") as sink, pacsv.CSVWriter(sink, schema, write_options=opts) as writer:
        sink.write((",".join(names) + "\n").encode())
        for ch in rec.chunks():
            clipped += int(np.count_nonzero((np.abs(ch.xyz) > limit + 0.5 / fixed.SAMPLE_ONE_G).any(axis=1)))
            a = np.round(apply_to_samples(p_int, ch.xyz, model, ch.temp, ch.t, ref, path, rng,
                                          ch.cols, ch.first), 6)
            cols = [ch.t, a[:, 0], a[:, 1], a[:, 2]] + ([np.round(ch.temp, 3)] if rec.has_temp else []) \
                + [ch.cols[c] for c in rec.columns]
            writer.write_batch(pa.RecordBatch.from_arrays([pa.array(c) for c in cols], schema=schema))
            n += len(ch.t)
    return n, clipped, rng


def params_of(params, device: str | None = None) -> tuple[str, list[int], dict]:
    """(model, Q24 parameters, reference) from a parameters file (files/params.load_params) or
    a CalibrationResult that calibrated."""
    from accelcal.files.params import load_params
    if isinstance(params, dict):
        if params.get("status") != "calibrated" or "params_int" not in params:
            raise InputError(f"{params.get('file', 'the result')}: not calibrated "
                             f"({params.get('status')}); no parameters to apply")
        return params["model"], [int(v) for v in params["params_int"].values()], \
            dict(params.get("reference") or {})
    return load_params(params, device)


@documented
def apply(params, path, output: str | None = None, *, device: str | None = None,
          range_g: int | None = None, force: bool = False, effects: str | None = None,
          rate: float | None = None, temp=None, time=None):
    """`accelcal apply`: the parameters saved at params (calibrate --save; device: which device
    of a --by file; or a CalibrationResult) applied to the recording at path, written to output
    (never one of the inputs; force: replace it): an ApplyResult.  Samples given in memory (a
    numpy array (n, 3) in g with rate (Hz) or time (s), temp (degC); a pandas or polars frame:
    files/arrays.py) come back calibrated as the same kind, in g (and are written to output
    too, if one is named).  range_g: the device's full scale, g (2, 4, 8, 16).  effects: a file
    of declared effects the model uses."""
    from accelcal.files.arguments import choice, paths
    from accelcal.files.arrays import as_input
    from accelcal.files.outputs import check_output
    from accelcal.files.readers import in_memory, is_recording, path_of
    from accelcal.model.declared import register
    path = as_input(path, rate, temp, time)
    paths(required=("path",), path=path, output=output, effects=effects)
    if not isinstance(params, dict):
        paths(required=("params",), params=params)
    if range_g is not None:
        choice("range", range_g)
    register(effects)
    model, p_int, ref = params_of(params, device)
    pfile = None if isinstance(params, dict) else path_of(params)
    if in_memory(path):
        if output is not None:
            check_output(output, [pfile, effects], force, "-o/--output")
            apply_file(p_int, model, ref, path, output, range_g)
        return path.like(apply_to_samples(p_int, path.xyz, model, path.temp, path.t, ref,
                                          str(path), apply_range(None, range_g), path.cols))
    if output is None:
        raise InputError("apply: name the output file (-o) for a recording read from a file")
    if not is_recording(path):
        raise InputError(f"{path}: apply needs a recording (header t,x,y,z[,temp][,NAME...], "
                         "or .cwa/.bin/.gt3x)")
    check_output(output, [pfile, path, effects], force, "-o/--output")
    n, clipped, rng = apply_file(p_int, model, ref, path, output, range_g)
    return ApplyResult(output=str(output), model=model, samples=n, clipped=clipped, range_g=rng,
                       host_only=list(ModelSpec.parse(model).host_only))
