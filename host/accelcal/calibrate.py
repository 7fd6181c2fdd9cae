"""`accelcal calibrate` and `apply`: the device pipeline on files, with the host's reference
methods fitted on the very points the device's bins selected."""
from __future__ import annotations

import numpy as np

from acal import bins as dbins
from acal import fixed, optimiser
from acal.model import Calibration
from accelcal import methods, runtime
from accelcal.io import (InputError, Table, g_to_sample, params_record, params_to_float,
                         params_to_int, sample_rate, sample_to_g)


def groups_from_table(table: Table, by: str | None) -> list[runtime.Group]:
    """Split a points file or recording into device groups."""
    if table.kind == "recording":
        if by:
            raise InputError(f"{table.path}: --by applies to points files; this is a recording")
        t = table.columns["t"]
        rate = sample_rate(t, table.path)
        gaps = np.flatnonzero(np.diff(t) > 1.5 / rate) + 1
        return [runtime.Group("recording", samples=table.xyz, gaps=gaps)]
    if not by:
        return [runtime.Group("points", points=table.xyz)]
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
        groups.append(runtime.Group(k, points=table.xyz[sel]))
    return groups


def fill_report(r: runtime.DeviceResult, min_count: int) -> str:
    return " ".join(f"{n}={c}" for n, c in zip(dbins.SUBSET_NAMES, r.counts)) + f" (need >= {min_count} each)"


def calibrate_groups(table: Table, by: str | None, cfg: runtime.Config, method: str,
                     runtime_name: str) -> list[dict]:
    """One record per group; failed ones carry status 'failed' and a one-line reason."""
    groups = groups_from_table(table, by)
    if table.kind == "recording":
        cfg.rate_hz = sample_rate(table.columns["t"], table.path)
        if cfg.rate_hz * cfg.seconds > fixed.SEGMENT_MAX_SAMPLES:
            raise InputError(f"{table.path}: {cfg.seconds} s segments at {cfg.rate_hz} Hz exceed "
                             f"{fixed.SEGMENT_MAX_SAMPLES} samples")
    results = runtime.run(groups, cfg, runtime_name)
    out = []
    for g, r in zip(groups, results):
        rec: dict = {"model": "base", "method": method, "runtime": runtime_name}
        if by:
            rec[by] = g.name
        rest = r.rest_g
        rec["rest_points"] = int(len(rest))
        rec["bins"] = dict(zip(dbins.SUBSET_NAMES, r.counts))
        rec["points"] = len(r.selected_int)
        rec["error_before_mg"] = methods.calibration_error_mg(None, rest)
        if min(r.counts) < cfg.min_count:
            what = (f"{len(g.samples)} samples gave {len(rest)} rest segments"
                    if g.samples is not None else f"{len(g.points)} points")
            rec.update(status="failed", reason=f"bins did not fill: {fill_report(r, cfg.min_count)}; {what}")
            out.append(rec)
            continue
        if method == "device":
            if r.status != optimiser.OK:
                rec.update(status="failed", reason=f"device fit {r.status_name} after {r.iterations} "
                           "iterations; no parameters returned")
                out.append(rec)
                continue
            p_int = r.params_int
            rec["iterations"] = r.iterations
            rec["objective"] = r.objective / (1 << fixed.OBJ_Q) / max(1, len(r.selected_int))
        else:
            try:
                p_int = params_to_int(methods.METHODS[method](r.selected_g))
            except methods.FitError as e:
                rec.update(status="failed", reason=str(e))
                out.append(rec)
                continue
            rec["iterations"] = None
        p = params_to_float(p_int)
        rec.update(params_record(p_int, "base", method))
        rec["status"] = "calibrated"
        rec["error_after_mg"] = methods.calibration_error_mg(p, rest)
        out.append(rec)
    return out


def apply_to_samples(p_int: list[int], xyz_g: np.ndarray) -> np.ndarray:
    """Calibrate samples with the device's own per-sample code (model.Calibration)."""
    cal = Calibration()
    try:
        cal.set(p_int)
    except ValueError:
        raise InputError("parameters outside the device's calibration bounds (k 0.75..1.25, "
                         "|misalignment| <= 0.125, |offset| <= 0.25 g)") from None
    buf = g_to_sample(xyz_g).ravel().tolist()
    cal.apply_samples(buf, 0, len(buf) // 3)
    return sample_to_g(np.array(buf, dtype=np.int64).reshape(-1, 3))
