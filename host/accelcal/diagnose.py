"""`accelcal diagnose`: compare the model with measurements, show where it fails, name the missing
effect.

Rest points come from the device's own rest detector (acal.rest) run over the recording; each
carries its mean (g), time, mean temperature and the spread of |v| inside it.

Split (why it is fair): the recording is cut into 2-hour blocks; even blocks train, odd blocks
test.  Both halves span the whole recording's time and temperature range, so an effect that
depends on either is seen by the fit and tested on it; no rest segment is split between them, and
postures held across a block edge are the only shared context.

Metric: the paper's Table 3 calibration error, mean | |a| - 1 g | over held-out rest points, in mg.
Noise floor: what the data implies a perfect model would still show: the radial noise of each
held-out mean, sqrt(2/pi) sd(|v|) / sqrt(n), averaged.

Naming rule (does not cry wolf on clean data): the candidate with the lowest held-out error is
named when (1) it lowers the held-out error by at least MIN_IMPROVEMENT_PCT and (2) it lowers it
in at least MIN_BLOCK_SHARE of the held-out blocks (an effect is systematic; a fit that only
bends to a few blocks' noise is not).  Thresholds: README "Model discovery", chosen on clean and
effect recordings of seeds that the tests do not use.
"""
from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from accelcal.effects import CATALOGUE, ModelSpec
from accelcal.io import InputError, Table, read_table
from accelcal.outputs import check_output, check_output_dir, save_figure, write_text
from accelcal.recording import is_recording

BLOCK_S = 2 * 3600
MIN_IMPROVEMENT_PCT = 10.0
MIN_BLOCK_SHARE = 0.7


@dataclass
class RestPoints:
    v: np.ndarray          # (N, 3) g
    t: np.ndarray          # (N,) s, segment middle
    temp: np.ndarray | None
    noise: np.ndarray      # (N,) g: sd(|v|) / sqrt(n) inside the segment
    source: str

    def __len__(self):
        return len(self.v)

    def take(self, sel):
        return RestPoints(self.v[sel], self.t[sel], None if self.temp is None else self.temp[sel],
                          self.noise[sel], self.source)


def rest_points(path, seconds: int = 5, threshold: int = 0, axis: int = 3) -> RestPoints:
    """path: a recording (any size or format: one streaming pass of the vectorised twin of the
    device's detector, accelcal.scan; the still segments calibrate keeps, gaps honoured, imputed,
    clipped and non-wear ones left out), or a points file or
    Table.  seconds, threshold (Q10 g; 0: from the noise), axis (3: all): the rest test, by
    default the wear profile's."""
    if not isinstance(path, Table) and not is_recording(path):
        path = read_table(path)
    if isinstance(path, Table):
        if path.kind != "points":
            raise InputError(f"{path.path}: recordings are read by name (streamed)")
        c = path.columns
        n = len(path.xyz)
        return RestPoints(path.xyz, c["t"] if "t" in c else np.arange(n, dtype=float),
                          c.get("temp"), np.zeros(n), path.path)
    from accelcal.recording import open_recording
    from accelcal.scan import scan
    rec = open_recording(path)
    sc = scan(rec, seconds, threshold, axis, extras=True)
    # the segments calibrate keeps: still, and not imputed, clipped or off the wrist (scan.masks)
    still = sc.masks()["kept"]
    if not still.any():
        raise InputError(f"{path}: no rest segments found (beside any imputed, clipped or "
                         "non-wear ones)")
    m = sc.seg_means[still]
    sd = np.sqrt(np.maximum(m[:, 3] - m[:, 2] ** 2, 0.0))
    return RestPoints(sc.segments.mean[still] / 65536.0, m[:, 0], m[:, 1] if rec.has_temp else None,
                      sd / np.sqrt(sc.length), str(path))


def usable(p: RestPoints) -> RestPoints:
    mag = np.linalg.norm(p.v, axis=1)
    return p.take((mag > 0.5) & (mag < 1.5))  # as the device's bins: not gravity otherwise


def check_coverage(p: RestPoints) -> None:
    """Exit-2 reason for rest points that cannot pin a calibration: fewer than the 9 parameters,
    or all on one side of a plane through 0 g (one orientation or one hemisphere: a device lying
    still, in a temperature chamber say); the fit would only extrapolate to the other side.
    calibrate (its bins, its methods' checks) and compare refuse the same data."""
    from accelcal.methods import one_side_margin
    if len(p) < 9:
        raise InputError(f"{p.source}: {len(p)} usable rest points; a calibration needs at "
                         "least 9, in different orientations")
    if one_side_margin(p.v) > 1e-9:
        raise InputError(f"{p.source}: the {len(p)} rest points cover one hemisphere only (all lie "
                         "on one side of a plane through 0 g: one orientation, or a device that "
                         "never turned over); a calibration needs both sides of every axis")


def check_model(spec: ModelSpec, p: RestPoints) -> None:
    """Exit-2 reasons for a model the data cannot support."""
    try:
        spec.check_data(p.temp, p.t, p.source)
    except ValueError as e:
        raise InputError(str(e)) from None


def prepare(path: str, model: str) -> tuple[ModelSpec, RestPoints]:
    """The model spec and the file's usable rest points, or a one-line reason why not."""
    try:
        spec = ModelSpec.parse(model)
    except ValueError as e:
        raise InputError(str(e)) from None
    p = usable(rest_points(path))
    check_coverage(p)
    check_model(spec, p)
    return spec, p


def refs(p: RestPoints) -> dict:
    """The effects' reference: mean temperature rounded to a whole degC (the device's resolution:
    a saved lsq model applies there exactly), first time."""
    return {"T0": float(np.round(np.mean(p.temp))) if p.temp is not None else 0.0,
            "t0": float(p.t.min())}


def fit(spec: ModelSpec, p: RestPoints, ref: dict) -> np.ndarray:
    """Float least squares of | |a| - 1 | over the points for a composed model."""
    n_eff = len(spec.effects)
    x0 = np.r_[1, 1, 1, 0, 0, 0, 0, 0, 0, np.zeros(3 * n_eff)]
    lo = np.r_[[0.5] * 3, [-0.5] * 3, [-0.5] * 3]
    hi = np.r_[[2.0] * 3, [0.5] * 3, [0.5] * 3]
    for name in spec.effects:
        b = CATALOGUE[name].bound
        lo, hi = np.r_[lo, [-b] * 3], np.r_[hi, [b] * 3]
    temp = p.temp if p.temp is not None else np.zeros(len(p.t))

    def resid(th):
        return np.linalg.norm(spec.correct(th, p.v, temp, p.t, ref), axis=1) - 1.0
    return least_squares(resid, x0, bounds=(lo, hi), x_scale="jac", method="trf").x


def residuals(spec, theta, p, ref):
    temp = p.temp if p.temp is not None else np.zeros(len(p.t))
    a = spec.correct(theta, p.v, temp, p.t, ref)
    return a, np.linalg.norm(a, axis=1) - 1.0


def split(p: RestPoints):
    block = ((p.t - p.t.min()) // BLOCK_S).astype(int)
    train = block % 2 == 0
    return p.take(train), p.take(~train), block[~train]


def diagnose(path: str, model: str = "base", plots: str | None = None) -> dict:
    spec, p = prepare(path, model)
    train, test, test_block = split(p)
    if len(train) < 30 or len(test) < 30:
        raise InputError(f"{path}: {len(train)} training and {len(test)} held-out rest points; "
                         "need >= 30 each (a longer recording)")
    ref = refs(train)
    theta = fit(spec, train, ref)
    _, r = residuals(spec, theta, test, ref)
    err = float(np.mean(np.abs(r)) * 1e3)
    floor = float(np.mean(np.sqrt(2 / np.pi) * test.noise) * 1e3)
    where = where_it_fails(spec, theta, test, ref, r)
    cands = []
    for name, e in CATALOGUE.items():
        if name in spec.effects:
            continue
        cspec = spec.with_effect(name)
        try:
            check_model(cspec, p)
        except InputError as why:
            cands.append({"effect": name, "heldout_error_mg": None, "improvement_pct": None,
                          "blocks_improved_pct": None, "untestable": str(why)})
            continue
        th = fit(cspec, train, ref)
        _, rc = residuals(cspec, th, test, ref)
        ec = float(np.mean(np.abs(rc)) * 1e3)
        gain = np.abs(r) - np.abs(rc)
        blocks = np.unique(test_block)
        share = float(np.mean([gain[test_block == b].mean() > 0 for b in blocks]))
        cands.append({"effect": name, "heldout_error_mg": ec, "improvement_pct": 100 * (err - ec) / err,
                      "blocks_improved_pct": 100 * share,
                      "params": dict(zip(e.param_names, (th[9 + 3 * len(spec.effects):] * e.scale).round(4).tolist())),
                      "param_unit": e.report_unit})
    testable = [c for c in cands if c["heldout_error_mg"] is not None]
    best = min(testable, key=lambda c: c["heldout_error_mg"]) if testable else None
    named = None
    if best and best["improvement_pct"] >= MIN_IMPROVEMENT_PCT and \
            best["blocks_improved_pct"] >= 100 * MIN_BLOCK_SHARE:
        named = best["effect"]
    if named:
        explanation = (f"{named}: {CATALOGUE[named].explanation} Adding it lowers the held-out error "
                       f"from {err:.2f} to {best['heldout_error_mg']:.2f} mg "
                       f"(noise floor {floor:.2f} mg). Next: accelcal calibrate --model {spec.with_effect(named)}")
    elif best:
        explanation = (f"No catalogue effect explains what remains: the best, {best['effect']}, lowers "
                       f"the held-out error by {best['improvement_pct']:.1f} % in "
                       f"{best['blocks_improved_pct']:.0f} % of held-out blocks (naming needs >= "
                       f"{MIN_IMPROVEMENT_PCT:g} % in >= {100 * MIN_BLOCK_SHARE:.0f} %). Error "
                       f"{err:.2f} mg against a noise floor of {floor:.2f} mg.")
    else:
        explanation = "Every catalogue effect is in the model or cannot be tested on this file."
    out = {"model": str(spec), "input": path, "split": "2-hour blocks: even train, odd held out",
           "rest_points": {"train": len(train), "heldout": len(test)},
           "heldout_error_mg": err, "noise_floor_mg": floor, "missing_effect": named,
           "candidates": cands, "explanation": explanation, "where_it_fails": where,
           "params": dict(zip(spec.param_names, theta.round(6).tolist())), "reference": ref}
    if plots:
        out["plots"] = make_plots(Path(plots), spec, theta, test, ref, r, cands, err, floor,
                                  train)
    return out


def where_it_fails(spec, theta, test, ref, r) -> dict:
    """Held-out residuals against each regressor: correlation and the residual's spread across
    the regressor's quintiles (mg) - a flat line is a model that does not fail there."""
    a, _ = residuals(spec, theta, test, ref)
    regs = {"time_h": (test.t - test.t.min()) / 3600, "ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2],
            "abs_a": np.linalg.norm(test.v, axis=1)}
    if test.temp is not None:
        regs["temp_c"] = test.temp
    out = {}
    for k, x in regs.items():
        if np.ptp(x) == 0:
            continue
        q = np.quantile(x, [0, .2, .4, .6, .8, 1])
        binned = [float(np.mean(r[(x >= lo) & (x <= hi)]) * 1e3) for lo, hi in zip(q[:-1], q[1:])]
        out[k] = {"corr": float(np.corrcoef(x, r)[0, 1]), "quintile_mean_residual_mg": [round(b, 3) for b in binned],
                  "range_mg": round(max(binned) - min(binned), 3)}
    return out


def make_plots(d: Path, spec, theta, test, ref, r, cands, err, floor, train=None) -> list[str]:
    """residuals.png (where the model fails: accelcal.figures), candidates.png (each catalogue
    effect's held-out error) and, for a composed model, step.png: the residuals before and after
    its last effect, side by side on one y-range."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from accelcal import figures
    d.mkdir(parents=True, exist_ok=True)
    a, _ = residuals(spec, theta, test, ref)
    fig, _ = figures.residual_figure(test, a, r * 1e3, floor,
                                     f"model {spec}: held-out error {err:.2f} mg, noise floor "
                                     f"{floor:.2f} mg")
    f1 = d / "residuals.png"
    save_figure(fig, f1, dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4))
    names = [c["effect"] for c in cands if c["heldout_error_mg"] is not None]
    vals = [c["heldout_error_mg"] for c in cands if c["heldout_error_mg"] is not None]
    ax.barh([str(spec)] + [f"+{n}" for n in names], [err] + vals)
    ax.axvline(floor, color="r", ls="--", label=f"noise floor {floor:.2f} mg")
    ax.set_xlabel("held-out calibration error (mg): mean | |a| − 1 g | over held-out rest points")
    ax.set_title(f"model {spec} and each catalogue effect added to it", fontsize=10)
    ax.legend()
    fig.tight_layout()
    f2 = d / "candidates.png"
    save_figure(fig, f2, dpi=80)
    plt.close(fig)
    out = [str(f1), str(f2)]
    if spec.effects and train is not None:
        before = ModelSpec(spec.effects[:-1])
        th0 = fit(before, train, ref)
        a0, r0 = residuals(before, th0, test, ref)
        fig = figures.before_after_figure(test, a0, r0 * 1e3, a, r * 1e3, floor, str(before),
                                          str(spec))
        f3 = d / "step.png"
        save_figure(fig, f3, dpi=70)
        plt.close(fig)
        out.append(str(f3))
    return out


def print_report(out: dict) -> None:
    print(f"{out['input']}: model {out['model']}, {out['rest_points']['train']} training / "
          f"{out['rest_points']['heldout']} held-out rest points ({out['split']})")
    print(f"held-out calibration error {out['heldout_error_mg']:.2f} mg, noise floor {out['noise_floor_mg']:.2f} mg")
    print("where the model fails (held-out residual, mean per quintile of each regressor, mg):")
    for k, w in out["where_it_fails"].items():
        print(f"  {k:<8} corr {w['corr']:+.2f}  spread {w['range_mg']:6.2f}  "
              + " ".join(f"{b:+6.2f}" for b in w["quintile_mean_residual_mg"]))
    print("candidates:")
    for c in out["candidates"]:
        if c["heldout_error_mg"] is None:
            print(f"  +{c['effect']:<12} not testable: {c['untestable']}")
        else:
            print(f"  +{c['effect']:<12} {c['heldout_error_mg']:6.2f} mg  {c['improvement_pct']:+6.1f} %  "
                  f"better in {c['blocks_improved_pct']:3.0f} % of blocks")
    print(f"missing effect: {out['missing_effect'] or 'none'}")
    print(out["explanation"])
    for f in out.get("plots", []):
        print(f"plot: {f}")
    if out.get("report"):
        print(f"report: {out['report']}")


def diagnose_main(args) -> int:
    if args.history:   # appended to: checked here, before the analysis, not replaced
        check_output(args.history, [args.input], True, "--history")
    if args.plots:
        check_output_dir(args.plots, [args.input], "--plots")
    page = None
    if args.report:
        rdir = check_output_dir(args.report, [args.input], "--report")
        page = check_output(rdir / "report.html", [args.input], args.force, "--report")
    out = diagnose(args.input, args.model, args.plots or args.report)
    if args.history:
        append_history(args.history, out)
    if page is not None:
        from accelcal import report_html
        pngs = {Path(f).name: Path(f).read_bytes() for f in out["plots"]}
        steps = read_history(args.history) if args.history else None
        write_text(page, report_html.diagnose_page(out, pngs, steps))
        out["report"] = str(page)
    if args.json:
        print(json.dumps(out))
    else:
        print_report(out)
    return 0


def calibrate_model(path: str, model: str) -> dict:
    """`calibrate --model SPEC --method lsq`: the composed model fitted (float) on every usable
    rest point of the file; error before/after on the same points."""
    from accelcal.methods import calibration_error_mg
    spec, p = prepare(path, model)
    ref = refs(p)
    theta = fit(spec, p, ref)
    a, r = residuals(spec, theta, p, ref)
    p_int = spec.to_int(theta)  # the device's integers (device/acal/effects.py)
    return {"model": str(spec), "method": "lsq", "status": "calibrated",
            "params": dict(zip(spec.param_names, theta.tolist())),
            "params_int": dict(zip(spec.param_names, p_int)), "reference": ref,
            "rest_points": len(p), "points": len(p), "iterations": None,
            "error_before_mg": calibration_error_mg(None, p.v),
            "error_after_mg": float(np.mean(np.abs(r)) * 1e3)}


def append_history(path: str, out: dict) -> None:
    rec = {k: out[k] for k in ("model", "input", "heldout_error_mg", "noise_floor_mg", "missing_effect")}
    # the old steps and the new one, written whole: a cut leaves the old history or the new one
    try:
        old = Path(path).read_text() if Path(path).exists() else ""
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot read the history to append to ({e})") from None
    if old and not old.endswith("\n"):
        old += "\n"
    write_text(path, old + json.dumps(rec) + "\n")


def _history_step(path, i, line):
    # One line of a diagnose history, checked: model, held-out and floor mg, named, input.
    bad = f"{path}:{i}: not a diagnose history line"
    try:
        rec = json.loads(line, parse_constant=lambda c: float("nan"))
    except ValueError:
        raise InputError(bad + " (not JSON)") from None
    if not isinstance(rec, dict):
        raise InputError(bad + " (not a JSON object)")
    model = rec.get("model")
    if not isinstance(model, str) or not model:
        raise InputError(f"{path}:{i}: 'model' must be a model name, found {model!r:.40}")
    vals = []
    for k, lo in (("heldout_error_mg", 0.0), ("noise_floor_mg", 0.0)):
        v = rec.get(k)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v < lo or (k == "heldout_error_mg" and v == 0):
            raise InputError(f"{path}:{i}: {k} must be a finite number of mg"
                             + (" above 0" if k == "heldout_error_mg" else " >= 0")
                             + f", found {v!r:.40}")
        vals.append(float(v))
    named = rec.get("missing_effect")
    if named is not None and not isinstance(named, str):
        raise InputError(f"{path}:{i}: missing_effect must be an effect name or null")
    return {"model": model, "heldout_error_mg": vals[0], "noise_floor_mg": vals[1],
            "missing_effect": named, "input": str(rec.get("input", ""))}


def read_history(path) -> list[dict]:
    """The steps of a diagnose history, each line checked (_history_step)."""
    try:
        lines = Path(path).read_bytes().decode("utf-8").splitlines()
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a diagnose history (not UTF-8 text)") from None
    return [_history_step(path, i, line) for i, line in enumerate(lines, 1) if line.strip()]


def report_main(args) -> int:
    """`accelcal report HISTORY`: each model step with its held-out error, as a table and a plot."""
    if args.plot:   # a figure, regenerated from the history it reads: replaced if it exists
        check_output(args.plot, [args.history], True, "--plot")
    if Path(args.history).is_dir():
        return board_report(args)
    if args.html:
        check_output(args.html, [args.history], args.force, "--html")
    steps = read_history(args.history)
    if not steps:
        raise InputError(f"{args.history}: no steps (run diagnose --history {args.history})")
    if args.json:
        print(json.dumps(steps))
    else:
        print(f"{'step':<5}{'model':<36}{'held-out mg':>12}{'floor mg':>10}{'change':>9}  named next")
        prev = None
        for k, st in enumerate(steps, 1):
            e = st["heldout_error_mg"]
            ch = "" if prev is None else f"{100 * (e - prev) / prev:+.0f} %"
            print(f"{k:<5}{st['model']:<36}{e:12.2f}{st['noise_floor_mg']:10.2f}{ch:>9}  "
                  f"{st['missing_effect'] or '-'}")
            prev = e
    if args.plot or args.html:
        import io
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(max(5, 1.6 * len(steps)), 4))
        x = np.arange(len(steps))
        ax.plot(x, [s["heldout_error_mg"] for s in steps], "o-", label="held-out error")
        ax.plot(x, [s["noise_floor_mg"] for s in steps], "r--", label="noise floor")
        ax.set_xticks(x, [s["model"].replace("base+", "+") for s in steps], rotation=20)
        ax.set_ylabel("calibration error (mg)")
        ax.set_title("held-out calibration error at each model step", fontsize=10)
        ax.set_ylim(bottom=0)
        ax.legend()
        fig.tight_layout()
        if args.plot:
            save_figure(fig, args.plot, dpi=90)
            print(f"plot: {args.plot}", file=sys.stderr)
        if args.html:
            from accelcal import report_html
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=80)
            write_text(args.html, report_html.history_page(args.history, steps,
                                                           {"steps.png": buf.getvalue()}))
            print(f"report: {args.html}", file=sys.stderr)
        plt.close(fig)
    return 0


def board_report(args) -> int:
    """`accelcal report PULLED_DIR`: the board's calibrations over time (table; --html a page
    with their figure; --json the summary)."""
    from accelcal import boardlog
    d = Path(args.history)
    if not (d / "log.bin").exists():
        raise InputError(f"{d}: a folder report reads is one `pull` wrote (no log.bin in it)")
    if args.html:
        check_output(args.html, [d / "log.bin"], args.force, "--html")
    summ = boardlog.summary(d)
    boots = boardlog.decode(d / "log.bin").dicts(boardlog.log.BOOT)
    rate = boots[-1]["rate_hz"] if boots else None
    cals = summ["calibrations"]
    if args.json:
        print(json.dumps(summ))
    else:
        print(f"{'number':>6} {'hours':>7} {'status':<34} {'points':>6}  kxx      kyy      kzz      "
              "ox mg   oy mg   oz mg")
        for c in cals:
            h = f"{c['index'] / rate / 3600:7.2f}" if rate else "      -"
            print(f"{c['number']:>6} {h} {c['status']:<34} {c['points']:>6}  {c['kxx']:.5f}  "
                  f"{c['kyy']:.5f}  {c['kzz']:.5f}  {c['ox'] * 1e3:6.2f}  {c['oy'] * 1e3:6.2f}  "
                  f"{c['oz'] * 1e3:6.2f}")
    if args.html:
        import io
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from accelcal import report_html
        pngs = {}
        if cals:
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
            buf = io.BytesIO()
            fig.savefig(buf, format="png", dpi=80)
            plt.close(fig)
            pngs["calibrations.png"] = buf.getvalue()
        write_text(args.html, report_html.board_page(str(d), summ, pngs, rate))
        print(f"report: {args.html}", file=sys.stderr)
    return 0


def heldout_error_of(path: str, model: str, theta, ref: dict) -> float:
    """The held-out error (mg, same split as diagnose) of given parameters: for the truth."""
    spec = ModelSpec.parse(model)
    _, test, _ = split(usable(rest_points(path)))
    _, r = residuals(spec, np.asarray(theta, dtype=np.float64), test, ref)
    return float(np.mean(np.abs(r)) * 1e3)
