"""`accelcal calibrate`: the device pipeline on files, with the host's reference methods
fitted on the very points the device's bins selected (`apply`: pipeline/apply.py)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from acal.core import bins as dbins, effects as deff
from acal.core import fixed, hemisphere
from acal.paper import optimiser
from acal.core import profile as dprofile
from accelcal import methods
from accelcal.bridge import runtime
from accelcal.model.effects import ModelSpec, column_ref
from accelcal.errors import InputError, ModelUnsupported
from accelcal.files.table import Table
from accelcal.fixedpoint import (COLUMN_QUANTITIES, QUANTITIES, Conditions, board_columns,
                                 params_to_float, params_to_int, physical, seconds, span_reason)
from accelcal.files.params import COMPOSED_SCALE, params_record
from accelcal.pipeline.discovered import discovered_model, discovery_record
from accelcal.pipeline.results import CalibrationResult


def groups_from_table(table: Table, by: str | None) -> list[runtime.Group]:
    """Split a points file into device groups (recordings stream: calibrate_recording)."""
    if table.kind == "recording":
        raise InputError(f"{table.path}: a recording goes through calibrate_recording")
    temp = table.columns.get("temp")
    t = table.columns.get("t")
    cols = {k: v for k, v in table.columns.items() if k not in ("x", "y", "z", "t", "temp", by)}
    if not by:
        return [runtime.PointsGroup("points", points=table.xyz, temp=temp, t=t, cols=cols)]
    if by in table.text_columns:
        keys = table.text_columns[by]
    elif by in table.columns:
        keys = np.array([f"{v:g}" for v in table.columns[by]], dtype=object)
    else:
        raise InputError(f"{table.path}: no column {by!r} to group by")
    groups = []
    for k in dict.fromkeys(keys.tolist()):
        if not k or any(c.isspace() for c in k):
            raise InputError(f"{table.path}: {by} value {k!r} must be non-empty without spaces")
        sel = keys == k
        groups.append(runtime.PointsGroup(k, points=table.xyz[sel],
                                          temp=None if temp is None else temp[sel],
                                          t=None if t is None else t[sel],
                                          cols={c: v[sel] for c, v in cols.items()}))
    return groups


def fill_report(r: runtime.DeviceResult, min_count: int) -> str:
    return " ".join(f"{n}={c}" for n, c in zip(dbins.SUBSET_NAMES, r.counts)) + f" (need >= {min_count} each)"


# a subset (acal.core.bins.SUBSET_NAMES: axis, then n/0/p) as the orientation a person holds still:
# an axis pointing up reads +1 g at rest, level 0 g, down -1 g
_SIDE = {"n": "down", "0": "level", "p": "up"}


def missing_orientations(counts, cfg: runtime.Config) -> str:
    """The subsets short of min_count in words, with the rests each still needs, and how long a
    rest must be held: a still spell of twice cfg.seconds holds one whole rest segment wherever
    the segments fall, and a subset's points must differ by cfg.differ_g to count twice."""
    short = [f"{n[0]}-{_SIDE[n[1]]} {cfg.min_count - c}"
             for n, c in zip(dbins.SUBSET_NAMES, counts) if c < cfg.min_count]
    if not short:
        return ""
    return (f"; missing rests: {', '.join(short)} (up: the axis reads +1 g), each held still "
            f">= {2 * cfg.seconds} s, moved > {cfg.differ_g:g} g between repeats")


def fill_reason(r: runtime.DeviceResult, cfg: runtime.Config) -> str | None:
    """Why the bins are not ready by their counts (the wear profile: nor by coverage, and never
    on one hemisphere's points: the coverage rule every fit shares), or None."""
    newton = cfg.fit == dprofile.NEWTON
    held = [c for p in r.selected_int for c in p[:3]]
    one_sided = newton and hemisphere.one_sided(held, [len(r.selected_int)],
                                                len(r.selected_int), len(r.selected_int))
    if min(r.counts) >= cfg.min_count or (newton and r.covered):
        return f"the {len(r.selected_int)} held points {methods.ONE_HEMISPHERE}" \
            if one_sided else None
    rest = r.rest_g
    if len(rest) >= 9 and methods.one_side_margin(rest) > 1e-9:   # the reason a user can act on
        return (f"the {len(rest)} rest points {methods.ONE_HEMISPHERE} (bins: "
                f"{fill_report(r, cfg.min_count)})")
    cover = (f" and the held points do not cover every axis (>= {dbins.COVER_SIDE} beyond "
             f"+-0.3 g on each side, >= {dbins.COVER_POINTS} points)"
             + (" or lie on one side of a plane through 0 g" if one_sided and
                len(r.selected_int) >= dbins.COVER_POINTS else "") if newton else "")
    missing = missing_orientations(r.counts, cfg)
    return f"bins did not fill: {fill_report(r, cfg.min_count)}{missing}" \
        f"{';' if missing and cover else ''}{cover}"


def spread_report(spec: ModelSpec, r: runtime.DeviceResult) -> str | None:
    """Why the bins, full in counts, are not ready for a composed model (their spread rule,
    decided on the device), or None."""
    if r.ready:
        return None
    for e in spec.parts:
        q = e.quantity
        why = q and span_reason(q, r.span[QUANTITIES.index(q)])
        if why:
            return f"{e.name}: {why}"
    return "the bins are not ready"


def calibrate_groups(table: Table, by: str | None, cfg: runtime.Config, method: str,
                     runtime_name: str, spec: ModelSpec | None = None,
                     points: str = "bins") -> list[CalibrationResult]:
    """A points file: one record per group (Fit.record: status and a one-line reason).
    spec: a composed model (fitted by the device method or lsq); None is the paper's.
    points: what a float method is fitted on (Fit)."""
    spec, cfg = _device_spec(spec, method, cfg, points)
    groups = groups_from_table(table, by)
    for g in groups:
        try:
            spec.check_data(g.temp, g.t, table.path if not by else f"{table.path} ({by} {g.name})",
                            g.cols)
        except ValueError as e:
            raise ModelUnsupported(str(e)) from None
    results = runtime.run(groups, cfg, runtime_name)
    out = []
    for g, r in zip(groups, results):
        rec = CalibrationResult(model=str(spec), method=method, runtime=runtime_name)
        if by:
            rec[by] = g.name
        out.append(Fit(g, r, cfg, spec, method, points).record(rec))
    return out


def _device_spec(spec: ModelSpec | None, method: str, cfg: runtime.Config,
                 points: str = "bins") -> tuple[ModelSpec, runtime.Config]:
    """The model for the device pipeline (None: the paper's), and the settings with its effects.
    A model with an effect the device does not have is fitted by lsq on every rest point, the
    device handing over each point's conditions."""
    spec = spec or ModelSpec(())
    if cfg.discover:   # the board's own discovery: from its base model, with its fit
        if spec.effects or method != "device" or cfg.fit != dprofile.NEWTON:
            raise InputError("--discover runs the board's own discovery: model base, --method "
                             "device, --profile wear")
        return spec, replace(cfg, kinds=(), conditions=True)
    if spec.effects and method not in ("device", "lsq"):
        raise InputError(f"model {spec}: composed models are fitted by --method device or lsq")
    if spec.host_only:
        if method != "lsq" or points != "all":
            raise InputError(f"model {spec}: {', '.join(spec.host_only)} has no device form yet; "
                             "fit it on the host with --method lsq --points all")
        return spec, replace(cfg, kinds=(), conditions=True)
    if method == "device" and deff.STEP in spec.kinds and cfg.fit != dprofile.NEWTON:
        raise InputError(f"model {spec}: a step's time is found by the wear profile's fit "
                         f"(--profile wear); the {cfg.profile} profile has no search for it")
    return spec, replace(cfg, kinds=spec.kinds)


@dataclass
class Fit:
    """One group's fit: the data the device was handed (group), what it returned (result), the
    settings it ran with, the model and the method fitted (a float method on points "bins", the
    points the device's bins selected and its fit kept, or "all", every usable rest point: |v|
    within 0.5-1.5 g, the bins' own gate; the bins' readiness does not matter then)."""
    group: runtime.Group
    result: runtime.DeviceResult
    cfg: runtime.Config
    spec: ModelSpec
    method: str
    points: str = "bins"

    @cached_property
    def rest(self) -> Conditions:
        """The rest points' conditions as the device saw them, in physical units."""
        return physical(self.result.rest_conditions, self.group.t_first)

    def record(self, rec: dict) -> dict:
        """Fill rec with the group's outcome: status calibrated, not_enough_data (bins not
        filled, or a composed model's spread not reached) or failed (the fit), with a one-line
        reason."""
        g, r, cfg = self.group, self.result, self.cfg
        rest = r.rest_g
        rec["profile"] = cfg.profile
        rec["rest_points"] = int(len(rest))
        if r.threshold is not None:
            rec["rest_threshold_g"] = r.threshold / fixed.SAMPLE_ONE_G
            rec["noise_level_g"] = r.noise_level / fixed.SAMPLE_ONE_G
        rec["bins"] = dict(zip(dbins.SUBSET_NAMES, r.counts))
        rec["bins_filled"] = int(sum(c >= cfg.min_count for c in r.counts))
        rec["points"] = len(r.selected_int)
        # no rest points: no figure (null in JSON, never NaN)
        rec["error_before_mg"] = methods.calibration_error_mg(None, rest) if len(rest) else None
        if self.method != "device":
            rec["points_from"] = self.points
            if self.points == "all":
                return self._float_record(rec, rest, r.rest_conditions, self.rest_columns())
        why = fill_reason(r, cfg)
        if why:
            n_samples = g.n_samples
            what = (f"{n_samples} samples gave {len(rest)} rest segments"
                    if n_samples is not None else f"{len(g)} points")
            rec.update(status="not_enough_data", reason=f"{why}; {what}")
            return rec
        why = spread_report(self.spec, r)
        if why:
            rec.update(status="not_enough_data", reason=f"bins filled but {why}")
            return rec
        if r.kept is not None:
            rec["points"] = int(sum(r.kept))
            rec["outliers"] = len(r.kept) - rec["points"]
        if self.method != "device":
            sel = np.array(r.selected_int, dtype=np.int64).reshape(-1, 3 + dbins.COND)
            if r.kept is not None:
                sel = sel[np.asarray(r.kept, bool)]
            return self._float_record(rec, sel[:, :3] / fixed.POINT_ONE_G, sel[:, 3:])
        if not optimiser.usable(r.status):
            rec.update(status="failed", reason=f"device fit {r.status_name} after {r.iterations} "
                       "iterations; no parameters returned")
            return rec
        if r.status != optimiser.OK:  # a composed fit refused, the base fit kept
            rec["note"] = r.status_name
        rec["iterations"] = r.iterations
        rec["objective"] = r.objective / (1 << fixed.OBJ_Q) / max(1, rec["points"])
        rec = self._params_record(rec, r.params_int)
        if cfg.discover:
            rec["discovery"] = discovery_record(r, self.group.t_first)
            found = discovered_model(rec["discovery"])
            if found:
                rec = self._discovered_record(rec, *found)
        return rec

    def _discovered_record(self, rec, model: str, p_int: list[int], step_time_s) -> dict:
        """What is found is what is saved: the record's model, parameters, reference and error
        after are the model the discovery ended with (relative to the device fit's references,
        as the board scored it); the base fit's beside them (`base_fit`), and model_from says
        so.  `--save`, `apply` and `--json` then carry the discovered model."""
        base = {k: rec[k] for k in ("model", "scale", "params_int", "params", "error_after_mg")}
        fit = replace(self, spec=ModelSpec.parse(model))
        ref = fit._reference(list(self.result.ref))
        if step_time_s is not None:
            ref["ts"] = float(step_time_s)
        rec = fit._params_record(rec, p_int, ref)
        rec["model_from"] = "discovery"
        rec["base_fit"] = base
        return rec

    def rest_columns(self) -> dict:
        """The recording columns the model's effects follow, one value per rest point the device
        reported: the board's supply as the device saw it (its third condition), others from the
        group's points, which are its rest points (a points file, or a recording's segments as
        the twin found them), each offered once, in order."""
        spec, g = self.spec, self.group
        out = self._board_columns(self.rest)
        if all(c in out for c in spec.columns):
            return out
        if len(self.result.rest_int) != len(g):
            raise InputError(f"model {spec}: its column effects need the rest points as the host "
                             "found them (engine vector)")
        return {c: out[c] if c in out else np.asarray(g.cols[c], dtype=np.float64)
                for c in spec.columns}

    def _float_record(self, rec, v, cond, cols=None):
        """A float method fitted on points v seen at cond (the device's conditions) with further
        columns cols (by name, per point): the paper's model by any method, a composed one by
        lsq (diagnose.fit) with the device's references."""
        spec = self.spec
        mag = np.linalg.norm(v, axis=1)
        ok = (mag > 0.5) & (mag < 1.5)
        v, seen = v[ok], physical(cond[ok], self.group.t_first)
        cols = {c: x[ok] for c, x in (cols or {}).items()}
        cols.update(self._board_columns(seen))   # the board's supply, as the device saw it
        rec["points"] = int(len(v))
        rec["iterations"] = None
        ref = None
        try:
            if not spec.effects:
                p_int = params_to_int(methods.METHODS[self.method](v))
            else:
                from accelcal.pipeline.restpoints import RestPoints
                from accelcal.pipeline.composed_lsq import fit_with_reference, refs
                methods.check_points(v, 9 + 3 * len(spec.effects), "lsq")
                pts = RestPoints(v, seen.time, seen.temp, np.zeros(len(v)), "points", cols)
                if spec.host_only:   # the host's references, as diagnose takes them
                    ref = refs(pts, spec)
                else:   # the device's references (acal.core.reference.references)
                    from acal.core.reference import references
                    c = cond[ok]
                    ref = self._reference(references([int(x) for x in c.ravel()], len(c),
                                                     spec.kinds))
                theta, ref = fit_with_reference(spec, pts, ref)
                p_int = spec.to_int(theta)
        except methods.FitError as e:
            rec.update(status="failed", reason=str(e))
            return rec
        return self._params_record(rec, p_int, ref)

    def _reference(self, device_ref) -> dict:
        """The device's integer references (Q2 degC, 64 s units, mV) as a model's reference: T0, t0
        and, for an effect of the board's supply, its column's."""
        at = physical(device_ref, self.group.t_first)
        ref = {q.ref: float(getattr(at, q.name)) for q in QUANTITIES if q.ref}
        ref.update({column_ref(c): float(x) for c, x in self._board_columns(at).items()})
        return ref

    def _board_columns(self, seen: Conditions) -> dict:
        """The columns the model follows that the board reads itself, as the device saw them."""
        return {q.column: getattr(seen, q.name) for q in COLUMN_QUANTITIES
                if q.column in self.spec.columns}

    def _params_record(self, rec, p_int, ref=None):
        """rec with the parameters (decoded and Q24) and the error after; ref: a composed
        model's references (None: the device fit's)."""
        spec, r = self.spec, self.result
        if spec.effects:
            if ref is None:   # the device fit's references, and a step's time it found
                ref = self._reference(list(r.ref))
                if spec.change_point:
                    ref["ts"] = ref["t0"] + seconds(r.step_time)
            rec.update(model=str(spec), method=self.method,
                       scale=COMPOSED_SCALE,
                       params_int=dict(zip(spec.param_names, map(int, p_int))),
                       params=dict(zip(spec.param_names, spec.from_int(p_int).tolist())),
                       reference=ref)
        else:
            rec.update(params_record(p_int, "base", self.method))
        rec["status"] = "calibrated"
        rec["error_after_mg"] = self.error_after_mg(p_int, rec.get("reference"))
        return rec

    def error_after_mg(self, p_int, ref: dict | None) -> float:
        """The calibration error (mean | |a| - 1 g |, mg) of parameters over the group's rest
        points, composed models at each point's conditions as the device saw them."""
        rest = self.result.rest_g
        if not self.spec.effects:
            return methods.calibration_error_mg(params_to_float(p_int), rest)
        a = self.spec.correct(self.spec.from_int(p_int), rest, self.rest.temp, self.rest.time, ref,
                              self.rest_columns())
        return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)) * 1e3)


def calibrate_recording(path: str, cfg: runtime.Config, method: str, runtime_name: str,
                        spec: ModelSpec | None = None, engine: str = "vector",
                        progress=None, fallback: str | None = None,
                        points: str = "bins") -> CalibrationResult:
    """A recording of any size or format (accelcal.files.recordings) through the device pipeline, with
    its quality report (docs/real-recordings.md "False rest kept out").  engine "vector": one
    streaming pass of the numpy twin, constant memory; "device": every sample through the
    device modules (the whole recording in memory).  The same record either way."""
    from accelcal.files.recordings import open_recording
    from accelcal.pipeline.scan import scan
    spec, cfg = _device_spec(spec, method, cfg, points)
    if spec.columns and engine != "vector":
        raise InputError(f"model {spec}: its column effects ({', '.join(spec.columns)}) are "
                         "fitted on the rest points the host finds: --engine vector")
    rec_in = open_recording(path)
    # a discovering board reads its own columns (its supply) for the candidates that follow them
    wanted = set(spec.columns) | ({q.column for q in COLUMN_QUANTITIES} if cfg.discover else set())
    out = scan(rec_in, cfg.seconds, cfg.threshold_int, cfg.axis, keep_samples=engine == "device",
               progress=progress, extras=bool(wanted))
    sc, whole = out if engine == "device" else (out, None)
    cfg = replace(cfg, rate_hz=sc.rate_hz)
    m = sc.masks()
    kept = m["kept"]
    temp = None if sc.seg_temp is None else sc.seg_temp[kept]
    cols = {c: sc.seg_column(c)[kept] for c in sc.columns if c in wanted}
    try:
        spec.check_data(temp, sc.seg_t[kept], path, cols)
    except ValueError as e:
        raise ModelUnsupported(str(e)) from None
    if engine == "vector":
        cond = runtime.device_conditions(temp, sc.seg_t[kept], sc.t_first, int(kept.sum()),
                                         **board_columns(cols))
        g = runtime.RestMeans("recording", points_q16=sc.segments.mean[kept],
                              temp=temp, t=sc.seg_t[kept], cond=cond, t_origin=sc.t_first,
                              n_samples=sc.n_samples, cols=cols)
    else:
        t, q, temp_s = whole
        g = runtime.SamplesGroup("recording", samples=q / fixed.SAMPLE_ONE_G,
                                 gaps=np.asarray(sc.gap_starts, dtype=np.int64), temp=temp_s,
                                 t=t, unworn=sc.excluded_runs(kept))
    r = runtime.run([g], cfg, runtime_name)[0]
    if r.threshold is None and sc.noise_threshold is not None:  # the twin's gauge
        r.threshold, r.noise_level = sc.noise_threshold, sc.noise_level
    rec = CalibrationResult(file=str(path), format=sc.format, model=str(spec), method=method,
                            runtime=runtime_name)
    rec.update(quality(sc, m))
    if rec_in.overlapping_pages is not None:   # files/pagetimes.py
        rec["overlapping_pages"] = rec_in.overlapping_pages
    if rec_in.pages_missing or rec_in.pages_cut:   # a truncated file (files/binpages.py)
        rec.update(pages_missing=rec_in.pages_missing, pages_cut=rec_in.pages_cut)
    if rec_in.warnings:
        rec["reader_warnings"] = rec_in.warnings
    rec = Fit(g, r, cfg, spec, method, points).record(rec)
    rec["calibration"] = "new" if rec["status"] == "calibrated" else "none"
    if rec["status"] != "calibrated" and fallback:
        use_fallback(rec, fallback, r.rest_g, (sc.segments.mean[kept] / float(fixed.POINT_ONE_G),
                                               temp, sc.seg_t[kept], cols))
    return rec


def quality(sc, m: dict) -> dict:
    """The per-file figures researchers' tools report (GGIR, actipy, scikit-digital-health)."""
    rate = sc.measured_rate_hz
    seg_h = sc.length / rate / 3600.0
    nonwear_h = float(m["nonwear"].sum() * seg_h)
    return {
        "rate_hz": round(rate, 4),   # as measured (a float); the device's segments: rate_hz_device
        "rate_hz_device": sc.rate_hz,
        "hours": round(sc.hours, 4),
        "hours_used": round(sc.hours - nonwear_h, 4),
        "gaps": len(sc.gap_starts),
        "still_windows": int(m["kept"].sum()),
        "excluded": {k: int(m[k].sum()) for k in ("nonwear", "imputed", "clipped")},
        "nonwear_hours": round(nonwear_h, 4),
        "temp_range_c": None if sc.temp_min is None else [round(sc.temp_min, 3), round(sc.temp_max, 3)],
        "full_scale_g": sc.full_scale_g,
        "clipped_pct": round(100.0 * sc.clipped_samples / max(1, sc.n_samples), 4),
    }


def use_fallback(rec: dict, params_path: str, rest_g: np.ndarray, kept=None) -> dict:
    """A file that did not calibrate takes a device's last good calibration, said so in the
    record: calibration "fallback", the file it came from, its model, its error on this file's
    rest points (rest_g; a composed model's on kept: (every kept rest mean g, their temp degC,
    t s, further columns), bad input where the file lacks what it needs: a temperature column,
    say).  The record's own status (why it did not calibrate) stays."""
    from accelcal.files.params import load_params
    model, p_int, ref = load_params(params_path)
    spec = ModelSpec.parse(model)
    if spec.effects:
        rest_g, temp, t, cols = kept if kept is not None else (np.zeros((0, 3)), None, None, {})
    if spec.effects and len(rest_g):   # applied to them: they carry what it needs, as apply's
        from accelcal.pipeline.apply import _check_inputs
        _check_inputs(spec, temp, spec.columns, cols, f"{rec.get('file')} (--fallback {params_path})")
    rec["calibration"] = "fallback"
    rec["fallback"] = params_path
    rec["model"] = model
    if spec.effects:   # as Fit._params_record writes a composed model's
        rec.update(scale=COMPOSED_SCALE, params_int=dict(zip(spec.param_names, map(int, p_int))),
                   params=dict(zip(spec.param_names, spec.from_int(p_int).tolist())),
                   reference=ref)
    else:
        rec.update({k: v for k, v in params_record(p_int, model, "fallback").items()
                    if k in ("scale", "params_int", "params")})
    if len(rest_g):
        rec["error_after_mg"] = methods.calibration_error_mg(params_to_float(p_int), rest_g) \
            if not spec.effects else 1e3 * float(np.mean(np.abs(np.linalg.norm(spec.correct(
                spec.from_int(p_int), rest_g, temp, t, ref, cols), axis=1) - 1.0)))
    return rec
