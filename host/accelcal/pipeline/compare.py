"""`accelcal compare`: every calibration method on the same data, scored the same way.

Rest points come from the device's own rest detector (as `diagnose`); they are split into a
training part and a held-out part (recordings and timed points files: 2-hour blocks, even
train, odd held out, as `diagnose`; points files without a time column: alternate points; or,
with split="first-half" or "second-half", the two halves of the rest points' time span, one
training: pipeline/restpoints.py).  The device's bins and
integer optimiser run on the training part in stream order; by default every float method is
fitted on the very points those bins selected (Farago 2024: "we used our method to collect and
select the calibration points for each of the compared calibration algorithms"), or with
--train all on every training rest point.  All are scored on the held-out part with the Table 3
metric, mean | |a| - 1 g | in mg, before and after, and the improvement R (eq. 21).  Fit times
are measured in this run, one fit each.

With a composed model (--model base+EFFECT..., effects of the catalogue or declared with
--effects), two more rows fit it on the same training part: the device's integer pipeline (where
the device has every effect's form) and float least squares on every training rest point; both
are scored on the same held-out points, each at its conditions.  The base rows are the same with
or without a composed model (the composed device row takes the profile's composed settings:
composed_config).  A method whose held-out error is above no calibration's is not "calibrated"
but worse_than_none (WORSE), its figures kept.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from acal.core import fixed
from acal.paper import optimiser
from accelcal import methods
from accelcal.bridge import runtime
from accelcal.bridge.runtime import Config
from accelcal.pipeline.results import CompareResult
from accelcal.pipeline.restpoints import (RestPoints, check_coverage, check_rule, rest_points,
                                          split, usable)
from accelcal.errors import InputError
from accelcal.vocabulary import documented
from accelcal.fixedpoint import params_to_float
from accelcal.files.table import read_table
from accelcal.files.outputs import check_output_dir, save_figure
from accelcal.files.readers import is_recording

ALL = ["device"] + methods.ORDER
CURVE_MAX = 1000   # training vectors: Gietzelt's figure 3 goes to ~300; de costs O(n) per step


def parse_methods(text: str | None) -> list[str]:
    if not text:
        return list(ALL)
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in ALL]
    if bad or not names:
        raise InputError(f"unknown method {','.join(bad) or repr(text)}; choose from {','.join(ALL)}")
    return list(dict.fromkeys(names))


@dataclass
class Split:
    train: RestPoints
    test: RestPoints
    how: str


def split_points(path: str, cfg: runtime.Config | None = None, rule: str = "blocks") -> Split:
    """The rest points (by cfg's rest test; None: the paper's) split into train and held out by
    rule (restpoints.SPLIT_RULES; "blocks" on a points file without t: alternate points)."""
    seconds, thr, axis = (5, 123, 0) if cfg is None else (cfg.seconds, cfg.threshold_int, cfg.axis)
    if is_recording(path):
        p, timed = usable(rest_points(path, seconds, thr, axis)), True
    else:
        table = read_table(path)
        p, timed = usable(rest_points(table)), "t" in table.columns
    if not timed and rule != "blocks":
        raise InputError(f"{path}: --split {rule} cuts the rest points by time and this points "
                         "file has no t column (without one it is split into alternate points, "
                         "--split blocks)")
    check_coverage(p)
    if timed:
        halves = split(p, rule)   # both halves pass the coverage rule every fit shares
        train, test, _ = halves
        how = halves.how
    else:
        idx = np.arange(len(p))
        train, test = p.take(idx % 2 == 0), p.take(idx % 2 == 1)
        how = "alternate points: even train, odd held out"
    if len(test) == 0 or len(train) == 0:
        raise InputError(f"{path}: {len(train)} training and {len(test)} held-out rest points; "
                         "both parts need points (a longer recording)")
    return Split(train, test, how)


def device_fit(v: np.ndarray, cfg: runtime.Config, runtime_name: str = "cpython"):
    """The device's bins and optimiser on points in stream order: (params or None, selected
    points, reason or None)."""
    from accelcal.pipeline.calibrate import fill_reason
    r = runtime.run([runtime.PointsGroup("train", points=v)], cfg, runtime_name)[0]
    sel = r.fit_points_g
    why = fill_reason(r, cfg)
    if why:
        return None, sel, why
    if r.status != optimiser.OK:
        return None, sel, f"device fit {r.status_name} after {r.iterations} iterations"
    return params_to_float(r.params_int), sel, None


def fit_method(name: str, v: np.ndarray, cfg: runtime.Config, runtime_name: str, say=None):
    """(params or None, seconds, reason or None).  say(message): a slow method's progress and
    estimate (de)."""
    t0 = time.perf_counter()
    if name == "device":
        p, _, why = device_fit(v, cfg, runtime_name)
        return p, time.perf_counter() - t0, why
    try:
        p = methods.METHODS[name](v, progress=say) if say and name == "de" else \
            methods.METHODS[name](v)
    except methods.FitError as e:
        return None, time.perf_counter() - t0, str(e)
    return p, time.perf_counter() - t0, None


WORSE = "worse_than_none"   # a row's status: fitted, but its held-out error is above no calibration's


def scored(row: dict, after: float, before: float) -> dict:
    """row with its held-out error after: status calibrated, or worse_than_none when the
    method leaves the held-out points worse than no calibration (the reason says how much)."""
    worse = after > before
    row.update(status=WORSE if worse else "calibrated",
               reason=f"{after / before:.2f}x the error with no calibration ({before:.2f} mg)"
               if worse else None, error_after_mg=after,
               improvement_pct=100 * before / after if after > 0 else None)
    return row


def composed_config(cfg: runtime.Config) -> runtime.Config:
    """The settings a composed model's device row runs with: the profile's composed defaults
    (more points a subset; the paper profile's longer fit) where cfg holds the base model's
    defaults, and every setting the user gave as given.  The base rows keep cfg, so `--model`
    adds rows and changes none."""
    base = runtime.Config.for_profile(cfg.profile, False)
    comp = runtime.Config.for_profile(cfg.profile, True)
    return replace(cfg, **{k: getattr(comp, k) for k in ("min_count", "max_count", "iterations")
                           if getattr(cfg, k) == getattr(base, k)})


def composed_rows(spec, sp: Split, cfg: runtime.Config, runtime_name: str, before: float) -> list:
    """The composed model's rows: the device pipeline on the training points (in stream order,
    with their conditions) and lsq on every training point, scored on the held-out points."""
    from accelcal.pipeline.calibrate import Fit
    from accelcal.pipeline.composed_lsq import fit_with_reference, refs
    rows = []
    for name in ("device", "lsq"):
        t0 = time.perf_counter()
        row = {"method": name, "model": str(spec), "error_before_mg": before,
               "role": "the device's integer pipeline" if name == "device"
               else "float least squares on every training rest point"}
        try:
            if name == "device":
                if spec.host_only:
                    raise methods.FitError(f"{', '.join(spec.host_only)} has no device form")
                g = runtime.PointsGroup("train", points=sp.train.v, temp=sp.train.temp,
                                        t=sp.train.t, cols=sp.train.cols)
                c = replace(composed_config(cfg), kinds=spec.kinds)
                r = runtime.run([g], c, runtime_name)[0]
                rec = Fit(g, r, c, spec, "device").record({})
                if rec.get("status") != "calibrated":
                    raise methods.FitError(rec.get("reason") or rec.get("status", "failed"))
                theta, ref = spec.from_int(list(rec["params_int"].values())), rec["reference"]
                row["points"] = rec["points"]
                if rec.get("note"):
                    row["note"] = rec["note"]
            else:
                methods.check_points(sp.train.v, 9 + 3 * len(spec.effects), "lsq")
                theta, ref = fit_with_reference(spec, sp.train, refs(sp.train, spec))
                row["points"] = len(sp.train)
        except (methods.FitError, InputError) as e:
            row.update(status="failed", reason=str(e), error_after_mg=None, improvement_pct=None,
                       params=None, points=row.get("points", 0),
                       fit_ms=(time.perf_counter() - t0) * 1e3)
            rows.append(row)
            continue
        row["fit_ms"] = (time.perf_counter() - t0) * 1e3
        test = sp.test
        temp = test.temp if test.temp is not None else np.zeros(len(test))
        a = spec.correct(theta, test.v, temp, test.t, ref, test.cols)
        after = float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1)) * 1e3)
        scored(row, after, before)
        row.update(params=dict(zip(spec.param_names, np.round(theta, 9).tolist())),
                   reference=ref)
        rows.append(row)
    return rows


def compare_split(path: str, names: list[str], cfg: runtime.Config, train: str = "selected",
                  runtime_name: str = "cpython", say=lambda m: None,
                  spec=None, rule: str = "blocks") -> tuple[CompareResult, Split]:
    """The comparison (JSON-ready) and the split (by rule, restpoints.SPLIT_RULES) it was made
    on."""
    say(f"{path}: rest detection (the device's detector, {cfg.profile} profile)")
    sp = split_points(path, cfg, rule)
    before = methods.calibration_error_mg(None, sp.test.v)
    _, selected, dev_why = device_fit(sp.train.v, cfg, runtime_name)
    if train == "selected" and dev_why is None:
        fit_on, training = selected, "the points the device's bins selected from the training part"
    elif train == "all":
        fit_on, training = sp.train.v, "every training rest point"
    else:
        fit_on = sp.train.v[thin_by_direction(sp.train.v)]
        training = "the training rest points, at most 10 per direction (Gietzelt 2.4)" + (
            f"; the device's bins could not select: {dev_why}" if train == "selected" else "")
    rows = []
    for name in names:
        say(f"  fitting {name}")
        v = sp.train.v if name == "device" else fit_on
        p, secs, why = fit_method(name, v, cfg, runtime_name, say)
        row = {"method": name,
               "role": "the integer device method (Farago 2024)" if name == "device"
               else methods.METHODS[name].role,
               "points": int(len(selected) if name == "device" else len(v)),
               "fit_ms": secs * 1e3, "error_before_mg": before}
        if p is None:
            row.update(status="failed", reason=why, error_after_mg=None, improvement_pct=None,
                       params=None)
        else:
            after = methods.calibration_error_mg(p, sp.test.v)
            scored(row, after, before)
            row["params"] = dict(zip(fixed.PARAM_NAMES, np.round(p, 7).tolist()))
        rows.append(row)
    if spec is not None and spec.effects:
        say(f"  fitting {spec} (device, lsq)")
        try:
            spec.check_data(sp.train.temp, sp.train.t, path, sp.train.cols)
        except ValueError as e:
            raise InputError(str(e)) from None
        rows += composed_rows(spec, sp, cfg, runtime_name, before)
    return CompareResult(input=str(path), profile=cfg.profile, split=sp.how, training=training,
                         rest_points={"train": len(sp.train), "heldout": len(sp.test)},
                         heldout="every held-out rest point",
                         metric="mean | |a| - 1 g |, mg (Farago Table 3)", rows=rows), sp


def thin_by_direction(v: np.ndarray, per_direction: int = 10, near_g: float = 0.1) -> np.ndarray:
    """Indices of the points kept, in order, when at most `per_direction` points may lie within
    near_g (max-norm) of each other: Gietzelt 2.4, "only up to ten measurements of a certain
    direction were included", so a night in one posture does not outweigh the rest."""
    kept: list[int] = []
    for i, p in enumerate(v):
        if not kept or np.sum(np.abs(v[kept] - p).max(axis=1) < near_g) < per_direction:
            kept.append(i)
    return np.array(kept, dtype=int)


def training_curve(sp: Split, names: list[str], cfg: runtime.Config, runtime_name: str,
                   sizes=None) -> dict:
    """Held-out error against the number of training vectors, each method fed the first n of
    the training rest points in time order, at most ten per direction (Gietzelt 2013 figure 3
    and section 2.4).  NaN where a method fails."""
    train = sp.train.v[thin_by_direction(sp.train.v)][:CURVE_MAX]
    if sizes is None:
        sizes = np.unique(np.geomspace(6, len(train), 14).astype(int))
    curve = {n: [] for n in names}
    for k in sizes:
        v = train[:k]
        for n in names:
            p, _, _ = fit_method(n, v, cfg, runtime_name)
            curve[n].append(methods.calibration_error_mg(p, sp.test.v) if p is not None else np.nan)
    return {"sizes": [int(s) for s in sizes], "error_mg": curve,
            "training": "first n training rest points in time order, at most 10 per direction"}


def plot_curve(curve: dict, path: Path, title: str) -> None:
    from accelcal.report.figures import pyplot
    plt = pyplot()
    names = list(curve["error_mg"])
    cols = 4
    rows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), sharex=True, sharey=True,
                             squeeze=False)
    for ax, n in zip(axes.ravel(), names):
        y = np.array(curve["error_mg"][n], dtype=float)
        ax.set_title(n, fontsize=10)
        ax.set_xscale("log")
        if np.isfinite(y).any():
            ax.plot(curve["sizes"], y, "o-", ms=3)
            ax.set_yscale("log")
        else:
            ax.text(0.5, 0.5, "no fit at any size", ha="center", va="center", transform=ax.transAxes)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("training vectors")
    for ax in axes[:, 0]:
        ax.set_ylabel("held-out error, mg")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=110)
    plt.close(fig)


@documented
def compare(path, *, methods: str | list[str] | None = None, model: str = "base",
            cfg: runtime.Config | None = None, profile: str = "wear", train: str = "selected",
            runtime: str = "cpython", plots: str | None = None, effects: str | None = None,
            split: str = "blocks", progress=None, rate: float | None = None, temp=None,
            time=None) -> CompareResult:
    """`accelcal compare`: every method (or those named: a list, or "lsq,device") fitted on the
    same training points and scored on the same held-out ones; with a composed model two more
    rows.  cfg: the pipeline settings (None: the profile's).  plots: a folder for the training
    curve (Gietzelt figure 3).  effects: a file of declared effects (registered).  split: how
    the rest points are split (restpoints.SPLIT_RULES: "blocks", the default, or "first-half" /
    "second-half", the half of their time span that trains).  progress(message): what is
    being done, with an estimate for the slow methods (de)."""
    from accelcal.bridge.runtime import RUNTIMES
    from accelcal.files import arguments as a
    from accelcal.files.arrays import as_input
    from accelcal.files.readers import path_of
    from accelcal.model.declared import register
    from accelcal.model.effects import ModelSpec
    path = as_input(path, rate, temp, time)
    runtime_name, say = runtime, progress or (lambda m: None)
    a.paths(required=("path",), path=path, plots=plots, effects=effects)
    a.choice("train", train)
    a.choice("runtime", runtime_name, RUNTIMES)
    if cfg is None:
        a.choice("profile", profile)
    elif not isinstance(cfg, Config):
        raise InputError(f"cfg {cfg!r:.60}: a Config (accelcal.Config.for_profile(...))")
    if methods is not None and not isinstance(methods, (str, list)):
        raise InputError(f"methods {methods!r:.60}: a list of names or a string \"lsq,device\"")
    register(effects)
    names = parse_methods(",".join(methods) if isinstance(methods, list) else methods)
    check_rule(split)   # before the file is read
    try:
        spec = ModelSpec.parse(model)
    except ValueError as e:
        raise InputError(str(e)) from None
    if cfg is None:   # the base model's settings; a composed model's rows: composed_config
        cfg = Config.for_profile(profile)
    if plots:
        check_output_dir(plots, [path_of(path)], "--plots")
    out, sp = compare_split(path, names, cfg, train, runtime_name, say, spec, split)
    if plots:
        say("training curve: every method on growing training sets (Gietzelt figure 3)")
        curve = training_curve(sp, names, cfg, runtime_name)
        png = Path(plots) / "training_curve.png"
        plot_curve(curve, png, f"{Path(str(path)).name}: held-out error against training vectors "
                               "(first n in time order)")
        out["training_curve"] = curve
        out["plots"] = [str(png)]
    return out
