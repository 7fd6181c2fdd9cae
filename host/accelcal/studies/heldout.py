"""`make bench`: held-out accuracy on simulated wrists.

Each case is a wrist recording (accelcal.simulate.wearer) of FIT_DAYS + TEST_DAYS at 10 Hz with one hidden
effect or none.  Every calibration is fitted on the first FIT_DAYS only and scored on the last
TEST_DAYS (a step's shock falls in the fit days: one in the scored days is out of every fit's
reach - lsq on every point scored the same 10-18x the true model as the device), on still windows picked by a rule stricter than any profile's own rest test: 5 s with
max - min < 0.02 g on every axis (and |v| within 0.5-1.5 g).  The score is the calibration
error of every report here, mean | |a| - 1 g | over those windows, in mg.

Rows: raw; the device pipeline with the paper profile; with the wear profile (the default);
the wear profile after the discovery loop (diagnose on the fit part names an effect, the device
fits base+EFFECT, up to two steps); float least squares with the loop's model on the points the
device's bins selected and its fit kept (lsq_bins: what separates the device's fit from its
choice of points); on every rest point of the fit part (lsq_all); the same with every point's
temperature in whole degC, as the LIS3DH's OUT_ADC3 gives it (lsq_degc: what that resolution
leaves the model; the device's conditions hold quarter degrees, acal.core.fixed.TEMP_Q);
scikit-digital-health and actipy (offset and scale per axis, and a temperature term where the
file has temperature) fitted by their own functions on the fit part (--others);
the true sensor model; and wear_loop / true.

    python -m accelcal.studies.heldout [--seeds 1,2,3] [--effects clean,temp_offset,...] [--others PY] [--json]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from acal.core import fixed
from accelcal.model.effects import CATALOGUE, ModelSpec

FIT_DAYS, TEST_DAYS, RATE = 3, 2, 10
STRICT_G = 0.02
CASES = ("clean", "temp_offset", "temp_scale", "drift", "nonlinear", "temp_offset2", "step",
         "supply_offset")   # every catalogue effect diagnose tries


def split(path: Path, fit: Path, test: Path, fit_days: float = FIT_DAYS) -> None:
    """The recording's first fit_days into fit, the rest into test (CSV, same header)."""
    import pyarrow.compute as pc
    import pyarrow.csv as pacsv
    tab = pacsv.read_csv(path)
    cut = pc.less(tab.column("t"), fit_days * 86400.0)
    pacsv.write_csv(tab.filter(cut), fit)
    pacsv.write_csv(tab.filter(pc.invert(cut)), test)


def strict_windows(path: Path):
    """(v g, t s, temp degC or None, {column: values}) of the strictly still 5 s windows of a
    recording (its further columns, e.g. supply_mv, for the effects that follow them)."""
    from accelcal.files.recordings import open_recording
    from accelcal.pipeline.scan import scan
    rec = open_recording(str(path))
    thr = int(np.ceil(STRICT_G * fixed.SAMPLE_ONE_G))  # spread < 20.48 LSB
    sc = scan(rec, 5, thr, 3, extras=True)
    s = sc.segments.still
    v = sc.segments.mean[s] / float(fixed.POINT_ONE_G)
    mag = np.linalg.norm(v, axis=1)
    ok = (mag > 0.5) & (mag < 1.5)
    m = sc.seg_means[s][ok]
    cols = {c: sc.seg_column(c)[s][ok] for c in sc.columns}
    return v[ok], m[:, 0], (m[:, 1] if rec.has_temp else None), cols


def score_mg(model: str, theta, ref: dict | None, win) -> float:
    v, t, temp, cols = win
    spec = ModelSpec.parse(model)
    if theta is None:
        a = v
    else:
        a = spec.correct(np.asarray(theta, float), v, temp if temp is not None else np.zeros(len(t)),
                         t, ref or {"T0": 0.0, "t0": 0.0}, cols)
    return float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1.0)) * 1e3)


def device_fit(path: Path, profile: str, model: str = "base", method: str = "device",
               max_count: int | None = None):
    """The device pipeline's calibration of a file: (model, theta, reference) or None (method
    "lsq": float least squares on the points the device's bins selected and its fit kept);
    max_count: points per subset other than the profile's."""
    from accelcal.pipeline.calibrate import calibrate_recording
    from accelcal.bridge.runtime import Config
    spec = ModelSpec.parse(model)
    cfg = Config.for_profile(profile, bool(spec.effects), max_count=max_count)
    rec = calibrate_recording(str(path), cfg, method, "cpython", spec)
    if rec["status"] != "calibrated":
        return None, rec.get("reason")
    return (model, list(rec["params"].values()), rec.get("reference")), None


def others(python: str, fit: Path, win, workdir: Path) -> dict:
    """scikit-digital-health and actipy, each fitted on the fit part by its own function in
    its own environment (accelcal.studies.bench_others heldout), scored on the same windows."""
    wpath = workdir / f"{fit.stem}.windows.npz"
    v, _, temp, _ = win
    np.savez(wpath, v=v, temp=temp if temp is not None else np.zeros(len(v)))
    out = {}
    for tool in ("skdh", "actipy"):
        r = subprocess.run([python, "-m", "accelcal.studies.bench_others", "heldout", tool, str(fit),
                            str(wpath)], capture_output=True, text=True)
        out[tool] = json.loads(r.stdout)["heldout_error_mg"] if r.returncode == 0 else None
    wpath.unlink()
    return out


def lsq_whole_degc(path: Path, model: str, win) -> float:
    """lsq_all with each rest point's temperature rounded to whole degC, as the LIS3DH's
    OUT_ADC3 gives it (a board's app; the device's conditions hold Q2 degC,
    fixedpoint.device_conditions): what whole degrees leave a model."""
    from dataclasses import replace
    from accelcal.pipeline.composed_lsq import fit_with_reference, prepare, refs
    spec, p = prepare(str(path), model)
    if p.temp is not None:
        p = replace(p, temp=np.rint(p.temp))
    theta, ref = fit_with_reference(spec, p, refs(p, spec))
    return score_mg(model, list(theta), ref, win)


def true_score_mg(truth: dict, win) -> float:
    """The true sensor model's score (the simulator's truth: base and its effects)."""
    theta = [truth["params"][n] for n in fixed.PARAM_NAMES]
    true_model, ref = "base", None
    for e in truth["effects"]:
        theta += list(e["params"].values())
        true_model += "+" + e["effect"]
        ref = e["reference"]
    return score_mg(true_model, theta, ref, win)


def run_case(case: tuple[str, int], workdir: str, others_python: str | None = None) -> dict:
    effect, seed = case
    from accelcal.simulate import wearer
    from accelcal.pipeline.composed_lsq import calibrate_model
    from accelcal.pipeline.diagnose import diagnose
    d = Path(workdir)
    name = f"{effect}_{seed}"
    whole, fit, test = d / f"{name}.csv", d / f"{name}.fit.csv", d / f"{name}.test.csv"
    truth = wearer.simulate_wrist(whole, FIT_DAYS + TEST_DAYS, RATE, seed,
                                  effect=[] if effect == "clean" else [effect],
                                  events_within_days=FIT_DAYS)
    split(whole, fit, test)
    whole.unlink()
    win = strict_windows(test)
    row = {"case": effect, "seed": seed, "windows": len(win[0])}
    row["raw"] = score_mg("base", None, None, win)
    for prof in ("paper", "wear"):
        got, why = device_fit(fit, prof)
        row[prof] = score_mg(*got, win) if got else None
        if why:
            row[f"{prof}_reason"] = why
    # the discovery loop on the fit part, the device fitting what it names
    model = "base"
    for _ in range(2):
        out = diagnose(str(fit), model)
        if not out["missing_effect"]:
            break
        model += "+" + out["missing_effect"]
    row["loop_model"] = model
    got, why = device_fit(fit, "wear", model) if model != "base" else (None, None)
    row["wear_loop"] = score_mg(*got, win) if got else row["wear"]
    if why:
        row["wear_loop_reason"] = why
    got, _ = device_fit(fit, "wear", model, "lsq")
    row["lsq_bins"] = score_mg(*got, win) if got else None
    lsq = calibrate_model(str(fit), model)
    row["lsq_all"] = score_mg(model, list(lsq["params"].values()), lsq["reference"], win)
    row["lsq_degc"] = lsq_whole_degc(fit, model, win)
    row["true"] = true_score_mg(truth, win)
    if others_python:
        row.update(others(others_python, fit, win, d))
    for f in (fit, test, fit.with_suffix(".truth.json"), whole.with_suffix(".truth.json")):
        f.unlink(missing_ok=True)
    return row


COLUMNS = ("raw", "paper", "wear", "wear_loop", "lsq_bins", "lsq_all", "lsq_degc", "skdh", "actipy", "true")


def table(rows: list[dict]) -> str:
    head = f"{'case':<12}{'seeds':>6}" + "".join(f"{c:>10}" for c in COLUMNS) + f"{'wear/true':>10}"
    lines = [head]
    for case in dict.fromkeys(r["case"] for r in rows):
        rs = [r for r in rows if r["case"] == case]

        def mean(c):
            v = [r[c] for r in rs if r[c] is not None]
            return float(np.mean(v)) if len(v) == len(rs) else None
        cells = [mean(c) if all(c in r for r in rs) else None for c in COLUMNS]
        ratio = (np.mean([r["wear_loop"] / r["true"] for r in rs])
                 if all(r["wear_loop"] is not None for r in rs) else None)
        lines.append(f"{case:<12}{len(rs):>6}" + "".join(f"{c:10.3f}" if c is not None else f"{'-':>10}"
                                                          for c in cells)
                     + (f"{ratio:10.2f}" if ratio is not None else f"{'-':>10}"))
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(allow_abbrev=False, prog="python -m accelcal.studies.heldout", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--effects", default=",".join(CASES))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--others", metavar="PYTHON",
                    help="interpreter with scikit-digital-health and actipy (make bench: "
                         ".venv-bench/bin/python); without it those columns are left out")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    cases = [(e, int(s)) for e in a.effects.split(",") for s in a.seeds.split(",")]
    for e, _ in cases:
        if e != "clean" and e not in CATALOGUE:
            ap.error(f"unknown effect {e}")
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(a.jobs) as pool:
        futs = [pool.submit(run_case, c, tmp, a.others) for c in cases]
        for f in futs:
            r = f.result()
            rows.append(r)
            print(json.dumps(r) if a.json else
                  f"{r['case']:<12} seed {r['seed']}: " + "  ".join(
                      f"{c} {r[c]:.3f}" if r.get(c) is not None else f"{c} -" for c in COLUMNS)
                  + f"  (loop: {r['loop_model']})", file=sys.stdout if a.json else sys.stderr,
                  flush=True)
    if not a.json:
        print(f"held-out calibration error (mg), fit on {FIT_DAYS} days, scored on the next "
              f"{TEST_DAYS} days' strictly still windows (max-min < {STRICT_G} g on every axis); "
              f"wear/true per recording, after the loop; {time.perf_counter() - t0:.0f} s")
        print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
