"""Figures that show where a model fails: held-out residuals against each regressor with robust
y-limits (from the bulk of the points, not its extremes), the points beyond them drawn as
markers at the edge and counted, the binned mean with its 95 % interval over the scatter, and
the noise floor as a band.  Every axis states its unit; every figure says what its lines mean.

The numbers behind a figure come from two small functions, robust_limits and binned_means,
tested against independent computations (tests/report/test_figures.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAD_TO_SD = 1.4826        # a normal distribution's sd per median absolute deviation
LIMIT_SDS = 8.0           # the y-range: the median +- 8 robust sd (a Gaussian bulk lies inside)
BINS = 10


def pyplot():
    """matplotlib's pyplot on the file backend, imported when a figure is first drawn (commands
    that draw none start faster)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def robust_limits(y: np.ndarray, floor: float = 0.0) -> tuple[float, float]:
    """(lo, hi) for a y-axis: the median +- LIMIT_SDS robust standard deviations (MAD), kept
    within the data's range and at least +-2 floor around 0 (so the noise band shows), padded
    by 5 %.  A few extreme points (false rest: hundreds of mg) do not set it."""
    y = np.asarray(y, dtype=float)
    y = y[np.isfinite(y)]
    if len(y) == 0:
        return -1.0, 1.0
    med = float(np.median(y))
    sd = MAD_TO_SD * float(np.median(np.abs(y - med)))
    if sd == 0:
        q1, q99 = np.quantile(y, [0.01, 0.99])
        lo, hi = float(q1), float(q99)
    else:
        lo = max(float(y.min()), med - LIMIT_SDS * sd)
        hi = min(float(y.max()), med + LIMIT_SDS * sd)
    lo, hi = min(lo, -2 * floor), max(hi, 2 * floor)
    if hi <= lo:
        lo, hi = lo - 1.0, hi + 1.0
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


@dataclass
class Binned:
    centre: np.ndarray   # median of x in each bin
    mean: np.ndarray     # mean of y
    ci95: np.ndarray     # half-width of the 95 % interval of the mean: 1.96 sd / sqrt(n)
    n: np.ndarray


def binned_means(x: np.ndarray, y: np.ndarray, bins: int = BINS) -> Binned:
    """y's mean in equal-count bins of x (edges at x's quantiles; a bin holds the points with
    edge_k <= x < edge_k+1, the last one its upper edge too), with the 95 % interval of each
    mean.  Bins with fewer than 2 points are left out."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    k = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, max(len(edges) - 2, 0))
    cs, ms, cis, ns = [], [], [], []
    for b in range(max(len(edges) - 1, 1)):
        sel = k == b
        n = int(sel.sum())
        if n < 2:
            continue
        yy = y[sel]
        cs.append(float(np.median(x[sel])))
        ms.append(float(yy.mean()))
        cis.append(float(1.96 * yy.std(ddof=1) / np.sqrt(n)))
        ns.append(n)
    return Binned(np.array(cs), np.array(ms), np.array(cis), np.array(ns, dtype=int))


def residual_panel(ax, x, r_mg, floor_mg, xlabel: str, limits=None, colour=None,
                   groups=None, title: str | None = None) -> dict:
    """One regressor: the scatter (light), its binned means with 95 % intervals, the noise
    floor band, robust limits with the points beyond them as edge markers, counted.  groups:
    (labels array, {label: colour}) to split the points (and their binned means) by a category.
    Returns what was drawn (limits, outliers beyond each edge)."""
    lo, hi = robust_limits(r_mg, floor_mg) if limits is None else limits
    ax.axhspan(-floor_mg, floor_mg, color="0.85", zorder=0,
               label=f"noise floor ±{floor_mg:.2f} mg")
    ax.axhline(0, color="k", lw=0.7, zorder=1)
    sets = [(np.ones(len(x), bool), colour or "tab:blue", None)]
    if groups is not None:
        labels, colours = groups
        sets = [(labels == g, c, g) for g, c in colours.items() if (labels == g).any()]
    for sel, c, g in sets:
        xs, ys = x[sel], r_mg[sel]
        inside = (ys >= lo) & (ys <= hi)
        ax.plot(xs[inside], ys[inside], ".", ms=2, alpha=0.25, color=c, zorder=2)
        b = binned_means(xs, ys)
        if len(b.n):
            ax.errorbar(b.centre, b.mean, yerr=b.ci95, fmt="o-", ms=3, lw=1.2, capsize=2,
                        color=c, zorder=4,
                        label=("binned mean, 95 % interval" if g is None else f"{g}: binned mean"))
    below, above = r_mg < lo, r_mg > hi
    span = hi - lo
    if below.any():
        ax.plot(x[below], np.full(below.sum(), lo + 0.01 * span), "v", ms=4, color="tab:red",
                zorder=3)
    if above.any():
        ax.plot(x[above], np.full(above.sum(), hi - 0.01 * span), "^", ms=4, color="tab:red",
                zorder=3)
    n_out = int(below.sum() + above.sum())
    if n_out:
        ax.text(0.99, 0.02, f"{n_out} beyond the axis (▲▼ at the edge)", transform=ax.transAxes,
                ha="right", va="bottom", fontsize=7, color="tab:red")
    ax.set_ylim(lo, hi)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("held-out |a| − 1 g (mg)")
    if title:
        ax.set_title(title, fontsize=9)
    return {"limits_mg": [lo, hi], "below": int(below.sum()), "above": int(above.sum())}


def gravity_axis(a: np.ndarray) -> np.ndarray:
    """Which axis carries gravity at each point ('x', 'y' or 'z': the largest |a|)."""
    return np.array(["x", "y", "z"])[np.argmax(np.abs(a), axis=1)]


AXIS_COLOURS = {"x": "tab:blue", "y": "tab:orange", "z": "tab:green"}


def regressors(test, a) -> list[tuple[str, str, np.ndarray]]:
    """(key, axis label with unit, values) of each regressor a residual may follow, at held-out
    points `test` with corrected readings a: the one list diagnose's "where it fails" and "what
    remains" read and the residuals figure draws."""
    regs = [("time_h", "time since the first rest point (h)", (test.t - test.t.min()) / 3600)]
    if test.temp is not None:
        regs.append(("temp_c", "temperature (°C)", np.asarray(test.temp, float)))
    regs += [(f"a{c}", f"corrected a_{c} (g)", a[:, i]) for i, c in enumerate("xyz")]
    regs.append(("abs_a", "|v| measured (g)", np.linalg.norm(test.v, axis=1)))
    regs += [(f"column:{c}", "the board's supply, column supply_mv (mV)" if c == "supply_mv"
              else f"recording column {c}", np.asarray(x, float))
             for c, x in getattr(test, "cols", {}).items()]
    return regs


def residual_figure(test, a, r_mg, floor_mg, title: str, limits=None):
    """Every regressor's panel, plus residual against temperature split by the axis that
    carries gravity (temp_scale shows as opposite slopes); the figure and what each panel drew."""
    plt = pyplot()
    regs = regressors(test, a)
    n = len(regs) + (1 if test.temp is not None else 0)
    cols = 3
    rows = -(-n // cols)
    fig, axs = plt.subplots(rows, cols, figsize=(13, 3.4 * rows), squeeze=False)
    lim = robust_limits(r_mg, floor_mg) if limits is None else limits
    drawn = {}
    flat = list(axs.flat)
    for ax, (key, label, x) in zip(flat, regs):
        drawn[key] = residual_panel(ax, x, r_mg, floor_mg, label, lim)
    if test.temp is not None:
        ax = flat[len(regs)]
        drawn["temp_by_gravity_axis"] = residual_panel(
            ax, np.asarray(test.temp, float), r_mg, floor_mg, "temperature (°C)", lim,
            groups=(gravity_axis(a), AXIS_COLOURS),
            title="split by the axis carrying gravity: temp_scale shows as opposite slopes")
        ax.legend(fontsize=7, loc="upper left")
    for ax in flat[n:]:
        ax.axis("off")
    flat[0].legend(fontsize=7, loc="upper left")
    fig.suptitle(title + "\nheld-out residual (mg) against each regressor: dots the points, "
                 "line the binned mean with its 95 % interval, grey band the noise floor",
                 fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.3 / fig.get_figheight()))
    return fig, drawn


def before_after_figure(test, a0, r0_mg, a1, r1_mg, floor_mg, before: str, after: str):
    """The same regressors for two models side by side, on one y-range: the fall is seen where
    it happened."""
    plt = pyplot()
    regs0 = regressors(test, a0)
    regs1 = regressors(test, a1)
    lim = robust_limits(np.r_[r0_mg, r1_mg], floor_mg)
    fig, axs = plt.subplots(len(regs0), 2, figsize=(11, 2.8 * len(regs0)), squeeze=False)
    for k, ((key, label, x0), (_, _, x1)) in enumerate(zip(regs0, regs1)):
        residual_panel(axs[k, 0], x0, r0_mg, floor_mg, label, lim,
                       title=f"before: {before}" if k == 0 else None)
        residual_panel(axs[k, 1], x1, r1_mg, floor_mg, label, lim,
                       title=f"after: {after}" if k == 0 else None)
    axs[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"held-out residual (mg) before and after the step {before} → {after} "
                 "(one y-range; binned mean with 95 % interval; grey: noise floor)", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / fig.get_figheight()))
    return fig


def _plain(text: str, limit: int = 40) -> str:
    """Text from a file as a label: shown as written ('$' is not matplotlib's mathtext), cut."""
    text = text if len(text) <= limit else text[:limit - 3] + "..."
    return text.replace("$", r"\$")


def steps_figure(steps: list[dict]):
    """The held-out error and noise floor at each model step of a diagnose history."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(max(5, 1.6 * len(steps)), 4))
    x = np.arange(len(steps))
    ax.plot(x, [s["heldout_error_mg"] for s in steps], "o-", label="held-out error")
    ax.plot(x, [s["noise_floor_mg"] for s in steps], "r--", label="noise floor")
    ax.set_xticks(x, [_plain(s["model"].replace("base+", "+")) for s in steps], rotation=20)
    ax.set_ylabel("calibration error (mg)")
    ax.set_title("held-out calibration error at each model step", fontsize=10)
    ax.set_ylim(bottom=0)
    ax.legend()
    fig.tight_layout()
    return fig


def calibrations_figure(cals: list[dict], rate: int | None):
    """A board's calibrations over its running time (by number when the rate is unknown): scales
    and offsets."""
    plt = pyplot()
    x = [c["index"] / rate / 3600 if rate else c["number"] for c in cals]
    fig, axs = plt.subplots(1, 2, figsize=(11, 3.5))
    for k in ("kxx", "kyy", "kzz"):
        axs[0].plot(x, [c[k] for c in cals], "o-", label=k)
    for k in ("ox", "oy", "oz"):
        axs[1].plot(x, [c[k] * 1e3 for c in cals], "o-", label=k)
    axs[0].set_ylabel("scale (dimensionless)")
    axs[1].set_ylabel("offset (mg)")
    for ax in axs:
        ax.set_xlabel("running time (h)" if rate else "calibration number")
        ax.legend(fontsize=8)
    fig.suptitle("the board's calibrations over time", fontsize=10)
    fig.tight_layout()
    return fig
