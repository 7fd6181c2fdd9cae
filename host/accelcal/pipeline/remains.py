"""What remains when no catalogue effect explains the held-out residual: which regressor the
residual follows and how - a trend, a curve, or a step at one value (a moment in time, a
temperature) - and what kind of effect would fit it; and the floor a complete model is judged
against, what rest on a wrist allows.

Each regressor x (time, temperature, each corrected axis, |v|, each further recording column) is
tried with three shapes: a line, a parabola, and one step (the best split of the points sorted by
x, from cumulative sums).  In diagnose a shape is fitted to the training blocks' residual and
speaks only when it holds up the way a named effect must: subtracted from the held-out residual it
lowers the held-out error by MIN_GAIN_PCT and does so in MIN_BLOCK_SHARE of the held-out blocks
(diagnose's naming rule).  Among the shapes that hold up, the one that lowers the error most; a
curve must beat the line, a step the curve, by their margins.  Without training data
(what_remains(regs, r)) the shape explaining the largest share of r's variance (R^2) is described.

The wrist floor (wrist_floor): the held-out error a complete model would still leave.  A model
is smooth in orientation, time and temperature; what is not - the rest means' own noise, motion
left in a still window, the readings' grid (a recording's 1 mg digits read into the device's
1/1024 g samples), a posture's own idiosyncrasy - shows as the disagreement of rest means of nearly
the same posture (PAIR_DEG apart: far enough for the grid's error to differ, near enough for any
effect's), close in time (PAIR_S) and temperature (PAIR_DEGC), from different still segments.  The
floor is mean |r_i - r_j| / sqrt(2) over such pairs of the model's residuals (for two independent
residuals of one spread, E|r_i - r_j| = sqrt(2) E|r|)."""
from __future__ import annotations

import numpy as np

from acal.discover import rule

MIN_EXPLAINED = 0.05   # a shape explaining less than this share of the variance is not a finding
STEP_MARGIN = 1.2      # a step's R^2 (or held-out gain) must be this many times the parabola's
CURVE_MARGIN = 1.1     # a parabola's must be this many times the line's
MIN_SIDE = 0.05        # a step leaves at least this share of the points on either side
# held out: as diagnose's naming rule (acal/discover/rule.py)
MIN_GAIN_PCT = rule.MIN_IMPROVEMENT_PCT
MIN_BLOCK_SHARE = rule.MIN_BLOCK_SHARE_PCT / 100
# a step has a free split: on complete models steps in a reading or temperature gained 10-14 %
# in 72-89 % of blocks (the postures' own idiosyncrasies); a true shock 37 %
STEP_MIN_GAIN_PCT = 20.0
# the wrist floor's pairs: rest means of different still segments
PAIR_DEG = (2.0, 8.0)  # apart in orientation (the grid's error decorrelates beyond ~1.5 deg)
PAIR_S = 3600.0        # apart in time at most
PAIR_DEGC = 0.5        # apart in temperature at most
SEGMENT_GAP_S = 10.0   # rest means further apart in time (or turned) belong to different segments
MIN_PAIRS = 30

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


def _basis(f: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Columns of a shape f (N, k) in the residual: as it is, and as an offset along each axis
    following it, seen radially as n_axis f (the first-order form of an offset effect, whose
    sign flips with the posture)."""
    return np.concatenate([f, *(f * n[:, [i]] for i in range(3))], axis=1)


def _step_split(x, y, n) -> float:
    """Where one step of _basis form best explains y along x: every split scored by the
    least-squares gain b^T S^-1 b of the points after it, from reverse cumulative sums
    (MIN_SIDE of the points on either side); nan if no split."""
    order = np.argsort(x, kind="stable")
    xs, u = x[order], _basis(np.ones((len(x), 1)), n[order])
    S = np.cumsum(np.einsum("ni,nj->nij", u, u)[::-1], axis=0)[::-1]
    bb = np.cumsum((u * y[order][:, None])[::-1], axis=0)[::-1]
    k = np.arange(max(1, int(MIN_SIDE * len(xs))), min(len(xs) - 1, int((1 - MIN_SIDE) * len(xs))))
    k = k[xs[k] > xs[k - 1]]
    if not len(k):
        return float("nan")
    gain = np.einsum("ki,ki->k", bb[k], np.linalg.solve(S[k] + 1e-9 * np.eye(4),
                                                         bb[k][:, :, None])[:, :, 0])
    best = int(k[np.argmax(gain)])
    return float(0.5 * (xs[best - 1] + xs[best]))


def _fitted_shapes(x, y, n, scalar: bool) -> list[tuple[str, object, float | None]]:
    """(shape, predict(x', n'), where) of each shape fitted to y along x (points of directions
    n) by least squares in _basis form, or as it is (scalar: for a reading, where an offset
    along each axis following it would be a surface over the postures, fitting any of their
    idiosyncrasies)."""
    basis = (lambda f, _: f) if scalar else _basis
    m, sd = float(x.mean()), float(x.std()) or 1.0
    def powers(z, deg):       # with the orders below: the model fitted without the shape
        u = (z - m) / sd        # took up what of it looks like them (a drift, an offset)
        return np.column_stack([u ** k for k in range(deg + 1)])
    shapes = [("trend", lambda z: powers(z, 1), None), ("curve", lambda z: powers(z, 2), None)]
    at = _step_split(x, y, n) if not scalar else _step(x, y)[1]
    if at == at:      # not nan: a split exists
        shapes.append(("step", lambda z: np.column_stack([powers(z, 1), z >= at]), at))
    out = []
    for shape, f, where in shapes:
        c = np.linalg.lstsq(basis(f(x), n), y, rcond=None)[0]
        out.append((shape, lambda z, nz, f=f, c=c: basis(f(z), nz) @ c, where))
    return out


def _directions(regs) -> np.ndarray:
    a = np.column_stack([np.asarray(regs[k], dtype=np.float64) for k in ("ax", "ay", "az")])
    return a / np.linalg.norm(a, axis=1)[:, None]


def _beats(pct: float, rival: float, margin: float) -> bool:
    """A gain (%) beats a simpler shape's by margin: it removes margin times as much, or leaves
    1/margin of what that one leaves."""
    return pct >= margin * rival or 100 - pct <= (100 - rival) / margin


def _holds_up(regressors, r_mg, train, blocks) -> dict | None:
    """The shape, fitted on the training residual, that lowers the held-out error most and
    holds up (MIN_GAIN_PCT, MIN_BLOCK_SHARE of the held-out blocks); None if none does."""
    regs_tr, r_tr = train
    n, n_tr = _directions(regressors), _directions(regs_tr)
    ids = np.unique(blocks)
    err = float(np.mean(np.abs(r_mg)))
    found = []
    for name, x in regressors.items():
        x, xt = np.asarray(x, dtype=np.float64), np.asarray(regs_tr.get(name, []), dtype=np.float64)
        if len(xt) < 20 or len(x) < 20 or np.ptp(xt) == 0:
            continue
        gains = {}
        axis = name in ("ax", "ay", "az", "abs_a")
        for shape, predict, at in _fitted_shapes(xt, r_tr, n_tr, axis):
            left = np.abs(r_mg - predict(x, n))
            gain = np.abs(r_mg) - left
            share = float(np.mean([gain[blocks == b].mean() > 0 for b in ids]))
            gains[shape] = (100 * (err - float(left.mean())) / err, share, at)
        if "curve" in gains and not _beats(gains["curve"][0], gains["trend"][0], CURVE_MARGIN):
            del gains["curve"]          # a parabola is a line unless it does better
        rival = gains.get("curve", gains["trend"])[0]
        if "step" in gains and not _beats(gains["step"][0], rival, STEP_MARGIN):
            del gains["step"]           # a step has a free split
        for shape, (pct, share, at) in gains.items():
            if pct >= (STEP_MIN_GAIN_PCT if shape == "step" else MIN_GAIN_PCT) and \
                    share >= MIN_BLOCK_SHARE:
                found.append({"regressor": name, "shape": shape, "heldout_gain_pct": round(pct, 1),
                              "blocks_improved_pct": round(100 * share), "blocks": len(ids),
                              **({"at": round(at, 3)} if at is not None else {})})
    return max(found, key=lambda f: f["heldout_gain_pct"]) if found else None


def _pooled(regressors, r_mg) -> dict | None:
    """The shape explaining the largest share of r_mg's variance (no held-out test)."""
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
        if shape == "curve" and curve < CURVE_MARGIN * trend:
            shape, r2 = "trend", trend          # a parabola is a line unless it does better
        if best is None or r2 > best["explained_pct"] / 100:
            best = {"regressor": name, "shape": shape, "explained_pct": round(100 * r2, 1)}
            if where is not None:
                best["at"] = round(where, 3)
    if best is None or best["explained_pct"] < 100 * MIN_EXPLAINED:
        return None
    return best


def what_remains(regressors: dict[str, np.ndarray], r_mg: np.ndarray, train=None,
                 blocks=None) -> dict | None:
    """The regressor and shape that the residual r_mg (held-out, mg) follows, with the effect
    that would fit it, or None.  train: (regressors, residual mg) of the training blocks, blocks:
    the held-out block of each point - the shape must then hold up in held-out blocks
    (_holds_up); without them, the shape explaining the largest share of r_mg's variance, if it
    explains MIN_EXPLAINED of it."""
    best = _pooled(regressors, r_mg) if train is None else _holds_up(regressors, r_mg, train,
                                                                        blocks)
    if best is None:
        return None
    name, shape = best["regressor"], best["shape"]
    what = {"trend": "a trend", "curve": "a curve", "step": "a step"}[shape]
    unit = f" {UNITS[name]}" if name in UNITS else ""
    where = f" at {best['at']:g}{unit}" if "at" in best else ""
    suggest = SUGGEST.get((name, shape)) or (AXIS_SUGGEST[shape] if name in ("ax", "ay", "az")
                                             else _column_suggest(name, shape))
    best["suggests"] = suggest
    label = LABELS.get(name) or f"the recording's column {name.split(':', 1)[-1]}"
    if train is None:
        evidence = f"explaining {best['explained_pct']:.0f} % of the held-out residual's variance"
    else:
        evidence = (f"fitted on the training blocks, it lowers the held-out error by "
                    f"{best['heldout_gain_pct']:.0f} %, in {best['blocks_improved_pct']:.0f} % of "
                    f"the {best['blocks']} held-out blocks")
    best["text"] = (f"What remains follows {label}: {what}{where}; {evidence} (residuals.png, its "
                    f"panel). An effect that would fit it: {suggest}.")
    return best


def _segments(t, n) -> np.ndarray:
    """Still segment of each time-sorted rest mean: a new one after a gap or a turn."""
    new = np.r_[True, (np.diff(t) > SEGMENT_GAP_S)
                | (np.sum(n[1:] * n[:-1], axis=1) < np.cos(np.radians(0.5)))]
    return np.cumsum(new) - 1


def wrist_floor(t, v, temp, r_mg, seed: int = 0) -> dict:
    """The wrist floor (module doc) of residuals r_mg of rest means v (g) at times t (s) and
    temperatures temp (degC or None): {"floor_mg", "pairs"}; floor_mg None below MIN_PAIRS."""
    order = np.argsort(t, kind="stable")
    t, v, r = t[order], v[order], r_mg[order]
    temp = np.zeros(len(t)) if temp is None else temp[order]
    n = v / np.linalg.norm(v, axis=1)[:, None]
    seg = _segments(t, n)
    ns = int(seg[-1]) + 1
    count = np.bincount(seg, minlength=ns)
    first = np.r_[0, np.cumsum(count)[:-1]]
    st = np.bincount(seg, t, ns) / count
    sT = np.bincount(seg, temp, ns) / count
    sn = np.stack([np.bincount(seg, n[:, k], ns) for k in range(3)], axis=1)
    sn /= np.linalg.norm(sn, axis=1)[:, None]
    # candidate partner segments within PAIR_S of each (segments are in time order)
    hi = np.searchsorted(st, st + PAIR_S, side="right")
    lo = np.searchsorted(st, st - PAIR_S, side="left")
    i = np.repeat(np.arange(ns), hi - lo)
    j = np.arange(len(i)) - np.repeat(np.cumsum(hi - lo) - (hi - lo), hi - lo) + np.repeat(lo, hi - lo)
    cos = np.sum(sn[i] * sn[j], axis=1)
    ok = ((i != j) & (cos <= np.cos(np.radians(PAIR_DEG[0])))
          & (cos >= np.cos(np.radians(PAIR_DEG[1]))) & (np.abs(sT[i] - sT[j]) <= PAIR_DEGC))
    i, j = i[ok], j[ok]
    if not len(i):
        return {"floor_mg": None, "pairs": 0}
    rng = np.random.default_rng(seed)
    # one partner segment per segment at random, one partner point per point at random
    cand = np.bincount(i, minlength=ns)
    start = np.r_[0, np.cumsum(cand)[:-1]]
    has = cand > 0
    partner = np.full(ns, -1)
    partner[has] = j[start[has] + (rng.random(has.sum()) * cand[has]).astype(int)]
    pts = np.flatnonzero(partner[seg] >= 0)
    ps = partner[seg[pts]]
    other = first[ps] + (rng.random(len(pts)) * count[ps]).astype(int)
    if len(pts) < MIN_PAIRS:
        return {"floor_mg": None, "pairs": int(len(pts))}
    return {"floor_mg": float(np.mean(np.abs(r[pts] - r[other])) / np.sqrt(2)),
            "pairs": int(len(pts))}
