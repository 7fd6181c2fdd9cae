"""Where the last tenth goes (issue 50 part 5): on clean held-back wrist wear (the protocol of
accelcal.studies.heldout: fitted on 3 days, scored on the next 2 days' strict still windows,
10 Hz), the default's error against the true sensor model's, taken apart.

Everything is scored on the recording's own values: each strict window's mean of the file's
samples (the simulator writes the LIS3DH's 1 mg steps), not of the device's Q10 samples.  The
device's samples are the 1 mg steps re-rounded onto 1/1024 g: since issue 50 part 5 with the
format's deterministic dither (acal.core.fixed.DITHER_STEP: floor(g * 1024 + d_i), d_i the
golden ratio's Weyl sequence over the sample's index), before it to the nearest LSB, which moved
every still window's mean by up to 0.49 mg, the same in every window of a posture.  Per seed, mg:

  true       the simulator's true sensor model
  lsq_all    float least squares on every rest point of the fit days, from the file's values
  lsq_bins   the same on the points the device's bins selected (from the file's values)
  lsq_bins_q10  the same points as the device sees them (means of its Q10 samples)
  device     the device's fit: the default's points and integers (`calibrate --model base`)
  device_file  the device's fit offered the file's values' means instead (the samples kept
             unrounded until the means)
  device_nearest  the device's fit offered means of Q10 samples rounded to the nearest LSB (the
             format before the dither)
  output     the device's parameters through `apply`'s path (the recording's Q10 samples in,
             the device's Q13 output: K - I in Q18 and K o in Q28, the output rounded with
             its dither, fixed.py "apply"), each window's mean of the output scored: the
             written output
  output_nearest  the same with the nearest-LSB Q10 samples in (and device_nearest's parameters)

Shares: the bins' points (lsq_bins - lsq_all), the Q10 rounding in the fit's points (device -
lsq_bins) and the output's rounding (output - device: the input samples' Q10 rounding carried
through the apply, device scored on the Q10 windows - device, and the Q13 output format, the
rest).  The device code is what `calibrate` and `apply` run; the nearest-LSB rows are a float
experiment on the host.

With --auto, also the default's auto model over the paper's model (auto_over_base, and
_nearest with both fitted on nearest-LSB Q10 means), on the file's own values.

    python -m accelcal.studies.tenth [--seeds 1,2,3] [--auto] [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from acal.core import fixed

COLUMNS = ("true", "lsq_all", "lsq_bins", "lsq_bins_q10", "device", "device_file",
           "device_nearest", "output", "output_nearest")


def _windows(path: Path, strict: bool):
    """(Q10 means g, the file's own means g, each window's first sample, length, the file's
    samples g, nearest-LSB Q10 means g, the nearest-LSB Q10 samples (ints), (t s, temp degC) of
    each window): the strict still windows (heldout's rule) or the wear profile's kept rest
    segments."""
    import pyarrow.csv as pacsv
    from accelcal.files.recordings import open_recording
    from accelcal.pipeline.scan import scan
    from accelcal.studies import heldout
    thr = int(np.ceil(heldout.STRICT_G * fixed.SAMPLE_ONE_G)) if strict else 0
    sc = scan(open_recording(str(path)), 5, thr, 3, extras=True)
    keep = sc.segments.still if strict else sc.masks()["kept"]
    q = sc.segments.mean[keep] / float(fixed.POINT_ONE_G)
    tab = pacsv.read_csv(path)
    xyz = np.column_stack([tab.column(c).to_numpy() for c in "xyz"])
    start = sc.segments.end[keep] + 1 - sc.length
    cs = np.vstack([np.zeros((1, 3)), np.cumsum(xyz, axis=0)])
    own = (cs[start + sc.length] - cs[start]) / sc.length
    n = np.clip(np.rint(xyz * fixed.SAMPLE_ONE_G), -fixed.SAMPLE_MAX, fixed.SAMPLE_MAX)
    cn = np.vstack([np.zeros((1, 3)), np.cumsum(n, axis=0)])
    near = (cn[start + sc.length] - cn[start]) / sc.length / fixed.SAMPLE_ONE_G
    mag = np.linalg.norm(q, axis=1)
    ok = (mag > 0.5) & (mag < 1.5)
    return (q[ok], own[ok], start[ok], sc.length, xyz, near[ok], n.astype(np.int64),
            sc.seg_means[keep][ok][:, :2])   # each window's t s, temp degC


def _points_fit(model: str, v, cond):
    """The device's fit of model on points v in stream order with their (t, temp): (spec,
    theta, reference); a composed model with the settings compare's composed row uses."""
    from dataclasses import replace
    from accelcal.bridge import runtime
    from accelcal.model.effects import ModelSpec
    from accelcal.pipeline.calibrate import Fit
    from accelcal.pipeline.compare import composed_config
    spec = ModelSpec.parse(model)
    cfg = runtime.Config.for_profile("wear", False)
    if spec.effects:
        cfg = replace(composed_config(cfg), kinds=spec.kinds)
        g = runtime.PointsGroup("train", points=v, temp=cond[:, 1], t=cond[:, 0])
    else:
        g = runtime.PointsGroup("train", points=v)
    rec = Fit(g, runtime.run([g], cfg, "cpython")[0], cfg, spec, "device").record({})
    if rec.get("status") != "calibrated":
        raise RuntimeError(rec.get("reason"))
    return spec, spec.from_int(list(rec["params_int"].values())), rec.get("reference") or {
        "T0": 0.0, "t0": 0.0}


def auto_over_base(fq, fnear, fcond, wown, wcond) -> dict:
    """The default's auto model (base+temp_offset) over the paper's model, each fitted by the
    device on the fit days' points (its Q10 means, and nearest-LSB Q10 means), scored on the
    file's own values of the strict windows."""
    out = {}
    for src, v in (("", fq), ("_nearest", fnear)):
        err = {}
        for m in ("base", "base+temp_offset"):
            spec, theta, ref = _points_fit(m, v, fcond)
            a = spec.correct(theta, wown, wcond[:, 1], wcond[:, 0], ref, {})
            err[m] = float(np.mean(np.abs(np.linalg.norm(a, axis=1) - 1.0)) * 1e3)
        out[f"auto_over_base{src}"] = err["base+temp_offset"] / err["base"]
    return out


def _output_means(out, start, length) -> np.ndarray:
    """Each window's mean of a calibrated output of the whole file (g)."""
    idx = start[:, None] + np.arange(length)[None, :]
    return out[idx.ravel()].reshape(len(start), length, 3).mean(axis=1)


def _written(p_int, xyz) -> np.ndarray:
    """The written output of the whole file: apply's path (the recording's Q10 samples, from
    its first sample's index, in; the device's Q13 output)."""
    from accelcal.pipeline.apply import apply_to_samples
    return apply_to_samples(list(p_int), xyz)


def _written_nearest(p_int, q) -> np.ndarray:
    """The same apply (its twin, bit-exact) of the nearest-LSB Q10 samples q."""
    from accelcal.bridge import twin
    return twin.apply_params(list(p_int), q) / float(1 << fixed.apply_out_q(2))


def run_seed(seed: int, workdir: Path, auto: bool = False) -> dict:
    from accelcal import methods
    from accelcal.bridge import runtime
    from accelcal.fixedpoint import params_to_int
    from accelcal.pipeline import compare
    from accelcal.simulate import wearer
    from accelcal.studies import heldout
    whole, fit, test = (workdir / f"{seed}{x}.csv" for x in ("", ".fit", ".test"))
    truth = wearer.simulate_wrist(whole, heldout.FIT_DAYS + heldout.TEST_DAYS, heldout.RATE, seed,
                                  effect=[])
    heldout.split(whole, fit, test)
    wq, wown, wstart, wlen, wxyz, _, wnear, wcond = _windows(test, True)
    fq, fown, _, _, _, fnear, _, fcond = _windows(fit, False)
    cfg = runtime.Config.for_profile("wear", False)
    dev, sel, why = compare.device_fit(fq, cfg)
    if why:
        raise RuntimeError(why)
    rows = {tuple(r) for r in np.asarray(sel)}
    pick = np.array([tuple(r) in rows for r in fq])
    dev_file, _, _ = compare.device_fit(fown, cfg)
    dev_near, _, _ = compare.device_fit(fnear, cfg)
    lsq = methods.METHODS["lsq"]
    fits = {"true": np.array([truth["params"][n] for n in fixed.PARAM_NAMES]),
            "lsq_all": lsq(fown), "lsq_bins": lsq(fown[pick]), "lsq_bins_q10": lsq(fq[pick]),
            "device": dev, "device_file": dev_file, "device_nearest": dev_near}
    out = {"seed": seed, "windows": int(len(wown)), "rest_points": int(len(fq)),
           "bins_points": int(pick.sum())}
    out.update({k: methods.calibration_error_mg(p, wown) for k, p in fits.items()})
    out["output"] = methods.calibration_error_mg(None, _output_means(
        _written(params_to_int(dev), wxyz), wstart, wlen))
    out["output_nearest"] = methods.calibration_error_mg(None, _output_means(
        _written_nearest(params_to_int(dev_near), wnear), wstart, wlen))
    if auto:
        out.update(auto_over_base(fq, fnear, fcond, wown, wcond))
    out["device_q10_windows"] = methods.calibration_error_mg(dev, wq)
    out["true_q10_windows"] = methods.calibration_error_mg(fits["true"], wq)
    for f in (whole, fit, test, whole.with_suffix(".truth.json")):
        f.unlink(missing_ok=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(allow_abbrev=False, prog="python -m accelcal.studies.tenth",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--auto", action="store_true", help="also the default's auto model over the "
                    "paper's model, fitted on the device's Q10 means and on nearest-LSB ones")
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for s in a.seeds.split(","):
            r = run_seed(int(s), Path(tmp), a.auto)
            rows.append(r)
            print(json.dumps(r) if a.json else f"seed {s}: " + "  ".join(
                f"{c} {r[c]:.3f}" for c in COLUMNS) + f"  (device / true {r['device'] / r['true']:.2f})"
                + "".join(f"  {k} {r[k]:.3f}" for k in r if k.startswith("auto_")),
                flush=True)
    if not a.json:
        m = {c: float(np.mean([r[c] for r in rows])) for c in (*COLUMNS, "device_q10_windows")}
        print(f"mean mg: " + "  ".join(f"{c} {m[c]:.3f}" for c in COLUMNS))
        print("over the true model, mean (range): " + "  ".join(
            f"{c} {m[c] / m['true']:.2f} ({min(r[c] / r['true'] for r in rows):.2f}-"
            f"{max(r[c] / r['true'] for r in rows):.2f})" for c in COLUMNS[1:]))
        print(f"shares, mg: the bins' points {m['lsq_bins'] - m['lsq_all']:+.3f}, the Q10 "
              f"rounding in the fit's points {m['device'] - m['lsq_bins']:+.3f}, the output's "
              f"rounding {m['output'] - m['device']:+.3f} (the input's Q10 rounding carried "
              f"through {m['device_q10_windows'] - m['device']:+.3f}, the Q13 output format "
              f"{m['output'] - m['device_q10_windows']:+.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
