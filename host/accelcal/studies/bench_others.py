"""The other tools' calibrations on one recording, for `make bench` (accelcal.studies.bench_files).
Runs in its own environment (.venv-bench: scikit-digital-health and actipy), one tool per
process so that each one's peak memory is its own:

    python -m accelcal.studies.bench_others skdh|actipy RECORDING.csv WINDOWS.npz
    python -m accelcal.studies.bench_others heldout skdh|actipy FIT.csv TEST_WINDOWS.npz
    python -m accelcal.studies.bench_others fit skdh|skdh_lifted|actipy SAMPLES.npz
    python -m accelcal.studies.bench_others versions

(fit: the tool's calibration of the samples of SAMPLES.npz (t s, acc (n, 3) g, temp degC or
absent), its map read back as in heldout, for accelcal.studies.peers_real.)

Reads the CSV whole (Arrow, as both tools need the arrays in memory), calibrates with the tool's
own function and its defaults, and scores the tool's calibrated samples on accelcal's still
windows (WINDOWS.npz: each window's first sample index and the window length): the mean over
windows of | |mean of the calibrated samples| - 1 g |, in mg, the metric of every report here.
Prints one JSON object."""
from __future__ import annotations

import json
import sys
import time
import warnings

import numpy as np


def window_error_mg(acc: np.ndarray, starts: np.ndarray, length: int) -> float:
    total, n = 0.0, 0
    steps = np.arange(length)
    for a in range(0, len(starts), 4096):
        idx = starts[a:a + 4096, None] + steps[None, :]
        m = acc[idx].mean(axis=1)
        total += float(np.abs(np.linalg.norm(m, axis=1) - 1.0).sum())
        n += len(m)
    return 1e3 * total / max(1, n)


def read(path: str):
    import pyarrow.csv as pacsv
    tab = pacsv.read_csv(path)
    t = tab.column("t").to_numpy()
    acc = np.column_stack([tab.column(c).to_numpy() for c in "xyz"])
    temp = tab.column("temp").to_numpy() if "temp" in tab.column_names else None
    return t, acc, temp


def run_skdh(t, acc, temp, rate, min_hours=72):
    from skdh.preprocessing import CalibrateAccelerometer
    # skdh wants epoch-like seconds; its default needs >= 72 h of data
    res = CalibrateAccelerometer(min_hours=min_hours).predict(
        time=t + 1.6e9, accel=acc, fs=float(rate), temperature=temp, apply=True)
    return res["accel"], {"offset": np.asarray(res["offset"]).tolist(),
                          "scale": np.asarray(res["scale"]).tolist(),
                          "temperature_scale": np.asarray(res["temperature scale"]).tolist()}


def run_actipy(t, acc, temp, rate, **_):
    import pandas as pd
    from actipy.processing import calibrate_gravity
    idx = pd.to_datetime((t * 1e9).astype("int64") + 1_600_000_000_000_000_000)
    cols = {"x": acc[:, 0], "y": acc[:, 1], "z": acc[:, 2]}
    if temp is not None:
        cols["temperature"] = temp
    df = pd.DataFrame(cols, index=idx)
    del cols
    out, info = calibrate_gravity(df, _inplace=True)
    cal = out[["x", "y", "z"]].to_numpy()
    keep = {k: v for k, v in info.items() if isinstance(v, (int, float, str, bool, list))}
    return cal, keep


def heldout(tool: str, path: str, windows: str) -> dict:
    """The tool calibrates FIT.csv with its own function; its map, per axis affine in the
    reading and the temperature (skdh: (v + o) s + (T - Tm) m; actipy/GGIR the same form), is
    read back from its calibrated samples by least squares on [1, v, T, v T] (exact for those
    forms) and applied to the held-out windows' means (v, T): the error in mg."""
    t, acc, temp = read(path)
    rate = int(round(1.0 / float(np.median(np.diff(t[:100000])))))
    kw = {}
    if tool == "skdh":  # its hours in steps of 12 (72 by default): what the fit part has
        kw["min_hours"] = max(12, int((t[-1] - t[0]) / 3600) // 12 * 12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal, params = (run_skdh if tool == "skdh" else run_actipy)(t, acc, temp, rate, **kw)
    w = np.load(windows)
    v, wt = w["v"], w["temp"]
    T = temp if temp is not None else np.zeros(len(t))
    idx = np.linspace(0, len(t) - 1, min(len(t), 400_000)).astype(int)
    out = np.empty_like(v)
    for i in range(3):
        X = np.column_stack([np.ones(len(idx)), acc[idx, i], T[idx], acc[idx, i] * T[idx]])
        coef, *_ = np.linalg.lstsq(X, cal[idx, i], rcond=None)
        out[:, i] = coef[0] + coef[1] * v[:, i] + coef[2] * wt + coef[3] * v[:, i] * wt
    err = float(np.mean(np.abs(np.linalg.norm(out, axis=1) - 1.0)) * 1e3)
    return {"tool": tool, "heldout_error_mg": err, "params": params, **kw}


def versions() -> dict:
    from importlib.metadata import version
    return {"scikit-digital-health": version("scikit-digital-health"),
            "actipy": version("actipy"), "numpy": np.__version__}


def read_back(acc, temp, cal) -> tuple[list, float]:
    """The tool's map as applied to acc: per axis i, cal_i = c0 + c1 v_i + c2 T + c3 v_i T,
    fitted by least squares on up to 400 000 samples spread over the recording (both peers'
    forms are exactly this: skdh (v + o) s + (T - Tm) m, actipy/GGIR o + s v + m (T - Tm));
    and the largest residual over those samples (g), which shows that the form holds."""
    T = temp if temp is not None else np.zeros(len(acc))
    idx = np.linspace(0, len(acc) - 1, min(len(acc), 400_000)).astype(int)
    coefs, worst = [], 0.0
    for i in range(3):
        X = np.column_stack([np.ones(len(idx)), acc[idx, i], T[idx], acc[idx, i] * T[idx]])
        c, *_ = np.linalg.lstsq(X, cal[idx, i], rcond=None)
        worst = max(worst, float(np.abs(X @ c - cal[idx, i]).max()))
        coefs.append([float(v) for v in c])
    return coefs, worst


def fit(tool: str, path: str) -> dict:
    """The tool's own calibration of every sample of path, with its defaults, except
    scikit-digital-health's min_hours (72 h by default, rounded up to a multiple of 12 h, its
    lower limit 12 h): the largest multiple of 12 h the samples span (at least 12), from which
    it takes more in 12-hour steps up to all of them; skdh_lifted: the whole hours the samples
    span (at least 1), its 12-hour floor lifted (set on the object after its constructor
    rounded it up), a variant outside its documented settings, labelled so wherever shown.
    A tool that declines (skdh: too few hours or no valid calibration after all the data;
    actipy: CalibOK 0) gives fitted false and its reason; no map.  actipy "fits" with no
    iteration where its error is under its tolerance: the identity, said in left_as_is."""
    z = np.load(path)
    t, acc = z["t"], np.ascontiguousarray(z["acc"], dtype=np.float64)
    temp = z["temp"] if "temp" in z.files else None
    rate = float(1.0 / np.median(np.diff(t[:100000])))
    out = {"tool": tool, "samples": int(len(t)), "hours": float(len(t) / rate / 3600),
           "rate_hz": rate, "versions": versions()}
    raw = acc.copy()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if tool in ("skdh", "skdh_lifted"):
            hours = int(len(t) / rate / 3600)
            from skdh.preprocessing import CalibrateAccelerometer
            if tool == "skdh":   # its constructor rounds min_hours up to a multiple of 12
                skdh = CalibrateAccelerometer(min_hours=max(12, hours // 12 * 12))
            else:                # its 12-hour floor lifted: set after the constructor rounded it
                skdh = CalibrateAccelerometer(min_hours=12)
                skdh.min_hours = max(1, hours)
            out["min_hours"] = skdh.min_hours
            res = skdh.predict(
                time=t + 1.6e9, accel=acc, fs=rate, temperature=temp, apply=True)
            said = [str(w.message) for w in caught if "alibration" in str(w.message)]
            ok = bool(res) and not said
            reason = "; ".join(said) or (None if ok else "no result")
            cal = res.get("accel") if ok else None
            params = {k: np.asarray(res[k]).tolist() for k in ("offset", "scale",
                                                                "temperature scale")} if res else {}
        else:
            cal, params = run_actipy(t, acc, temp, rate)
            ok = bool(params.get("CalibOK"))
            reason = None if ok else f"CalibOK {params.get('CalibOK')}"
            if ok and not params.get("CalibNumIters"):   # its error under its 10 mg tolerance
                out["left_as_is"] = ("its error before calibrating, %.2f mg on its %d stationary "
                                     "windows, under its 10 mg tolerance: samples left as they are"
                                     % (params["CalibErrorBefore(mg)"], params["CalibNumSamples"]))
    out.update(fitted=ok, reason=reason, params=params)
    if ok:
        out["map"], out["map_residual_g"] = read_back(raw, temp, np.asarray(cal))
    return out


def main(argv=None) -> int:
    argv = argv or sys.argv[1:]
    if argv[0] == "versions":
        print(json.dumps(versions()))
        return 0
    if argv[0] == "fit":
        print(json.dumps(fit(argv[1], argv[2])))
        return 0
    if argv[0] == "heldout":
        print(json.dumps(heldout(*argv[1:4])))
        return 0
    tool, path, windows = argv[:3]
    w = np.load(windows)
    t0 = time.perf_counter()
    t, acc, temp = read(path)
    rate = int(round(1.0 / float(np.median(np.diff(t[:100000])))))
    t1 = time.perf_counter()
    before = window_error_mg(acc, w["starts"], int(w["length"]))
    t1b = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal, params = (run_skdh if tool == "skdh" else run_actipy)(t, acc, temp, rate)
    t2 = time.perf_counter()
    after = window_error_mg(cal, w["starts"], int(w["length"]))
    print(json.dumps({"tool": tool, "read_s": t1 - t0, "calibrate_s": t2 - t1b,
                      "error_before_mg": before, "error_after_mg": after, "params": params}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
