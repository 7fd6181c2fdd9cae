"""What remains when no catalogue effect explains the held-out residual: which regressor the
residual follows and how - a trend, a curve, or a step at one value (a moment in time, a
temperature) - and what kind of effect would fit it.  diagnose says it (text and --json) when the
error stands well above the noise floor and nothing was named.

Each regressor x (time, temperature, each corrected axis, |v|, each further recording column) is
tried with three shapes, fitted to the held-out residual r by least squares: a line, a parabola,
and one step (the best split of the points sorted by x, from cumulative sums).  The shape that explains the largest share of r's
variance (R^2) wins; a step must beat the parabola by STEP_MARGIN, as it has a free split."""
from __future__ import annotations

import numpy as np

WELL_ABOVE = 1.5       # held-out error / noise floor above which what remains is worth a look
MIN_EXPLAINED = 0.05   # a shape explaining less than this share of the variance is not a finding
STEP_MARGIN = 1.2      # a step's R^2 must be this many times the parabola's
MIN_SIDE = 0.05        # a step leaves at least this share of the points on either side

LABELS = {"time_h": "time", "temp_c": "temperature", "ax": "the x axis reading",
          "ay": "the y axis reading", "az": "the z axis reading", "abs_a": "|a|"}
UNITS = {"time_h": "h", "temp_c": "degC", "ax": "g", "ay": "g", "az": "g", "abs_a": "g"}
# (regressor, shape) -> the kind of effect that would fit it.
SUGGEST = {
    ("time_h", "trend"): "an offset drifting with time: the catalogue's drift",
    ("time_h", "curve"): "ageing that is not linear: drift with time_offset2 (the device's shape "
                         "for time squared, named in --model; it runs on the board), or an effect "
                         "you declare on a power of time (--effects FILE)",
    ("time_h", "step"): "an offset that jumps once (a shock, a re-mounting): the catalogue's step",
    ("temp_c", "trend"): "an offset or sensitivity moving with temperature: temp_offset or temp_scale",
    ("temp_c", "curve"): "an offset curved in temperature: temp_offset2",
    ("temp_c", "step"): "a response that changes at one temperature (hysteresis, a heater): "
                        "temp_offset2 or temp_offset3 follow it smoothly; a step in temperature "
                        "cannot be declared yet (a step is in time only)",
    ("abs_a", "trend"): "a common scale error: check the base fit's points cover every axis",
    ("abs_a", "curve"): "a response not linear in the reading: nonlinear",
    ("abs_a", "step"): "a response that differs by orientation: declare an effect on the reading",
}
AXIS_SUGGEST = {"trend": "a scale or offset error on that axis the base fit missed (points not "
                         "covering it?)",
                "curve": "a response not linear in that axis's reading: nonlinear",
                "step": "a response that depends on which side of zero that axis reads (a "
                        "sign-dependent offset): declare an effect on the reading"}


def _column_suggest(name: str, shape: str) -> str:
    # a further column of the recording ("column:NAME"): a declared effect follows it, or for
    # the board's own supply the catalogue's supply_offset
    if name == "column:supply_mv" and shape == "trend":
        return ("an offset following the board's supply: the catalogue's supply_offset (it runs "
                "on the board)")
    power = {"trend": "", "curve": ", power=2", "step": ""}[shape]
    extra = "; a step in a column cannot be declared, a power of it (power=2..4) follows a sharp " \
            "change smoothly" if shape == "step" else ""
    return (f"an offset following that column: declare one with regressor='{name}'{power} "
            f"(--effects FILE){extra}")


def _r2(y: np.ndarray, fitted: np.ndarray) -> float:
    ss = float(np.sum((y - y.mean()) ** 2))
    return 0.0 if ss == 0 else 1.0 - float(np.sum((y - fitted) ** 2)) / ss


def _poly(x, y, deg) -> float:
    xs = (x - x.mean()) / (x.std() or 1.0)
    return _r2(y, np.polyval(np.polyfit(xs, y, deg), xs))


def _step(x, y) -> tuple[float, float]:
    """(R^2, where) of the best single step in y along x."""
    order = np.argsort(x, kind="stable")
    xs, ys = x[order], y[order]
    n = len(ys)
    csum = np.cumsum(ys)
    k = np.arange(max(1, int(MIN_SIDE * n)), min(n - 1, int((1 - MIN_SIDE) * n)))
    k = k[xs[k] > xs[k - 1]]
    if not len(k):
        return 0.0, float("nan")
    left = csum[k - 1] / k
    right = (csum[-1] - csum[k - 1]) / (n - k)
    between = k * (left - ys.mean()) ** 2 + (n - k) * (right - ys.mean()) ** 2
    ss = float(np.sum((ys - ys.mean()) ** 2))
    best = int(np.argmax(between))
    return (float(between[best]) / ss if ss else 0.0), float(0.5 * (xs[k[best] - 1] + xs[k[best]]))


def what_remains(regressors: dict[str, np.ndarray], r_mg: np.ndarray) -> dict | None:
    """The regressor and shape that the residual r_mg (held-out, mg) follows best, with the share of
    its variance explained and the effect that would fit; None if no shape explains
    MIN_EXPLAINED of it."""
    best = None
    for name, x in regressors.items():
        x = np.asarray(x, dtype=np.float64)
        if np.ptp(x) == 0 or len(x) < 20:
            continue
        trend, curve = _poly(x, r_mg, 1), _poly(x, r_mg, 2)
        step, at = _step(x, r_mg)
        shapes = [("trend", trend, None), ("curve", curve, None)]
        if step > STEP_MARGIN * curve:
            shapes.append(("step", step, at))
        shape, r2, where = max(shapes, key=lambda s: s[1])
        if shape == "curve" and curve < 1.1 * trend:
            shape, r2 = "trend", trend          # a parabola is a line unless it does better
        if best is None or r2 > best["explained_pct"] / 100:
            best = {"regressor": name, "shape": shape, "explained_pct": round(100 * r2, 1)}
            if where is not None:
                best["at"] = round(where, 3)
    if best is None or best["explained_pct"] < 100 * MIN_EXPLAINED:
        return None
    name, shape = best["regressor"], best["shape"]
    what = {"trend": "a trend", "curve": "a curve", "step": "a step"}[shape]
    unit = f" {UNITS[name]}" if name in UNITS else ""
    where = f" at {best['at']:g}{unit}" if "at" in best else ""
    suggest = SUGGEST.get((name, shape)) or (AXIS_SUGGEST[shape] if name in ("ax", "ay", "az")
                                             else _column_suggest(name, shape))
    best["suggests"] = suggest
    label = LABELS.get(name) or f"the recording's column {name.split(':', 1)[-1]}"
    best["text"] = (f"What remains follows {label}: {what}{where}, explaining "
                    f"{best['explained_pct']:.0f} % of the held-out residual's variance "
                    f"(residuals.png, its panel). An effect that would fit it: {suggest}.")
    return best
