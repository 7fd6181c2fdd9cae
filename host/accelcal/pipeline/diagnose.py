"""`accelcal diagnose`: compare the model with measurements, show where it fails, name the missing
effect.

Rest points and the split into training and held-out blocks: pipeline/restpoints.py.  Each model
and candidate is fitted in float by pipeline/composed_lsq.py on the training blocks and scored on
the held-out ones.

Metric: the paper's Table 3 calibration error, mean | |a| - 1 g | over held-out rest points, in mg.
Noise floor: the sensor's noise alone: the radial noise of each held-out mean,
sqrt(2/pi) sd(|v|) / sqrt(n), averaged.  Wrist floor: what a complete model would still leave,
the noise and all else rest on a wrist carries that no effect smooth in orientation, time and
temperature explains (pipeline/remains.py wrist_floor); "the model is complete" is judged
against it.  What remains is said only when its shape holds up in held-out blocks as a named
effect must (pipeline/remains.py).

Naming rule (does not cry wolf on clean data): the candidate with the lowest held-out error is
named when (1) it lowers the held-out error by at least MIN_IMPROVEMENT_PCT and (2) it lowers it
in at least MIN_BLOCK_SHARE of the held-out blocks (an effect is systematic; a fit that only
bends to a few blocks' noise is not); a step (its time searched) gives way to an effect without
one that comes within STEP_PARSIMONY of it.  Thresholds:
docs/model-discovery.md "Model discovery", chosen on clean and effect recordings of seeds that the
tests do not use.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from acal.discover import rule
from acal.core.effects import STEP

from accelcal.errors import InputError
from accelcal.files.outputs import check_output, check_output_dir, save_figure, write_text
from accelcal.model.effects import CATALOGUE, ModelSpec
from accelcal.pipeline.explain import (complete_text, few_blocks, named_text, noise_text,
                                      second_step_text)
from accelcal.pipeline.composed_lsq import (check_model, fit, fit_with_reference, prepare, refs,
                                            residuals)
from accelcal.pipeline.history import append_history, check_history, read_history
from accelcal.pipeline.remains import what_remains, wrist_floor
from accelcal.pipeline.restpoints import rest_points, split, usable
from accelcal.pipeline.results import DiagnoseResult
from accelcal.vocabulary import documented

# the acceptance rule, shared with the board's own discovery (acal/discover/rule.py)
MIN_IMPROVEMENT_PCT = rule.MIN_IMPROVEMENT_PCT
MIN_BLOCK_SHARE = rule.MIN_BLOCK_SHARE_PCT / 100
# A share of few blocks is weak evidence (3 of 3 better: one time in eight by chance alone):
# rule.clear, the sign test in integers, shared with the board.
# A step's time is searched over every split of the training points, and the 2-hour held-out
# blocks sit between training ones: a step can pass for a drift or a temperature pattern there.
# So a change-point effect is preferred only when it beats the best effect without one by this
# factor in held-out error.
STEP_PARSIMONY = rule.STEP_PARSIMONY_TENTHS / 10




@documented
def diagnose(path, model: str = "base", plots: str | None = None, *,
             history: str | None = None, report: str | None = None, force: bool = False,
             effects: str | None = None, rate: float | None = None, temp=None,
             time=None) -> DiagnoseResult:
    """`accelcal diagnose`: the model's held-out error beside the noise floor, where it fails,
    and the missing effect named (or none).  plots: a folder for its figures; history: a file
    this step is appended to; report: a folder for report.html (force: replace it); effects: a
    file of declared effects (registered; never written over).  Every output is checked before
    the analysis."""
    from accelcal.files.arguments import paths
    from accelcal.files.arrays import as_input
    from accelcal.files.readers import path_of
    from accelcal.model.declared import register
    path = as_input(path, rate, temp, time)
    paths(required=("path",), path=path, plots=plots, history=history, report=report, effects=effects)
    if not isinstance(model, str):
        raise InputError(f"model {model!r:.60}: a model name such as base or base+temp_offset")
    if not isinstance(force, bool):
        raise InputError(f"force={force!r:.40}: True or False")
    register(effects)
    try:
        ModelSpec.parse(model)   # before any output is checked or the file read
    except ValueError as e:
        raise InputError(str(e)) from None
    reads = [path_of(path), effects]
    if history:   # appended to, only if a history: checked here, before the analysis
        check_output(history, reads, True, "--history")
        check_history(history)
    if plots:
        check_output_dir(plots, reads, "--plots")
    page = None
    if report:
        rdir = check_output_dir(report, reads, "--report")
        page = check_output(rdir / "report.html", [*reads, history], force, "--report")
    spec, p = prepare(path, model)
    out = diagnose_points(spec, p, path, plots or report)
    if history:
        append_history(history, out.history_step())
    if page is not None:
        from accelcal.report import pages
        pngs = {Path(f).name: Path(f).read_bytes() for f in out["plots"]}
        steps = read_history(history) if history else None
        write_text(page, pages.diagnose_page(out, pngs, steps))
        out["report"] = str(page)
    return out


def diagnose_points(spec: ModelSpec, p, path: str, plots: str | None = None) -> DiagnoseResult:
    """diagnose() of usable rest points p (pipeline/restpoints.py) under model spec."""
    halves = split(p)   # both halves pass the coverage rule every fit shares
    train, test, test_block = halves
    if len(train) < 30 or len(test) < 30:
        raise InputError(f"{path}: {len(train)} training and {len(test)} held-out rest points; "
                         "need >= 30 each (a longer recording)")
    theta, ref = fit_with_reference(spec, train, refs(train, spec))
    _, r = residuals(spec, theta, test, ref)
    err = float(np.mean(np.abs(r)) * 1e3)
    floor = float(np.mean(np.sqrt(2 / np.pi) * test.noise) * 1e3)
    # a points file carries no samples, so no noise: its floor is not measured, not zero
    measured = bool(np.any(test.noise > 0))
    said = floor if measured else None
    regs = regressors(spec, theta, test, ref)
    where = where_it_fails(regs, r)
    # a column effect is a candidate where the file has its column (not listed elsewhere)
    pool = {n: e for n, e in CATALOGUE.items() if n not in spec.effects and e.candidate
            and (e.needs != "col" or e.column in p.cols)}
    cands = [candidate(spec.with_effect(e), p, train, test, test_block, ref, r, err, theta)
             for e in pool.values()]
    best = chosen(pool, cands)
    named = None
    if best and rule.names(err, best["heldout_error_mg"], best["blocks_improved"],
                           best["blocks"]):
        named = best["effect"]
    parts = {c["effect"]: [pool[c["effect"]]] for c in cands}
    for line, curve in curves(pool):   # a curve's two parts, tried together
        c = candidate(spec.with_effect(line).with_effect(curve), p, train, test, test_block, ref,
                      r, err, theta, added=2)
        cands.append(c)
        parts[c["effect"]] = [line, curve]
        single = best["heldout_error_mg"] if best else None
        if single and c["heldout_error_mg"]:
            c["single_ratio"] = single / c["heldout_error_mg"]
        if c["heldout_error_mg"] is not None and rule.names(
                err, c["heldout_error_mg"], c["blocks_improved"], c["blocks"]) and (
                named is None or not rule.plain_preferred(c["heldout_error_mg"],
                                                          best["heldout_error_mg"])):
            named, best = c["effect"], c
    if named is None:   # a curve on its straight part, judged again as the device fits it
        named, best = curve_as_device(spec, pool, cands, halves, best)
    # a curve's straight part named alone: the curve is judged only on top of it (its own gain
    # hides behind the straight part's), so a second step is due before the model is complete
    second = next((cv for ln, cv in curves(pool) if named in pool and ln is pool[named]), None)
    second_text = second_step_text(spec, named, second, cands) if second is not None else None
    if named:
        explanation = named_text(spec, named, parts[named], best, err, said, path)
        if second_text is not None:
            explanation += " " + second_text
    elif best:
        explanation = (f"No catalogue effect explains what remains: the best, {best['effect']}, lowers "
                       f"the held-out error by {best['improvement_pct']:.1f} % in "
                       f"{best['blocks_improved']} of {best['blocks']} held-out blocks "
                       f"({best['blocks_improved_pct']:.0f} %; naming needs >= "
                       f"{MIN_IMPROVEMENT_PCT:g} % in >= {100 * MIN_BLOCK_SHARE:.0f} %"
                       f"{few_blocks(best['blocks'])}). Error {err:.2f} mg against "
                       f"{noise_text(said)}.")
    else:
        explanation = "Every catalogue effect is in the model or cannot be tested on this file."
    _, r_all = residuals(spec, theta, p, ref)
    wrist = wrist_floor(p.t, p.v, p.temp, r_all * 1e3)
    remains = None if second is None else {
        "second_step": second.name, "model": f"{spec}+{named}", "text": second_text}
    if named is None:
        _, r_train = residuals(spec, theta, train, ref)
        remains = what_remains(regs, r * 1e3, (regressors(spec, theta, train, ref), r_train * 1e3),
                               test_block)
        explanation += " " + (remains["text"] if remains else
                              complete_text(err, said, wrist["floor_mg"]))
    out = DiagnoseResult(model=str(spec), input=str(path), split=halves.how,
                         rest_points={"train": len(train), "heldout": len(test)},
                         heldout_error_mg=err, noise_floor_mg=floor, noise_floor_measured=measured,
                         wrist_floor_mg=wrist["floor_mg"], wrist_floor_pairs=wrist["pairs"],
                         heldout_blocks=len(np.unique(test_block)), missing_effect=named,
                         candidates=cands, explanation=explanation, where_it_fails=where,
                         params=dict(zip(spec.param_names, theta.round(6).tolist())), reference=ref,
                         what_remains=remains)
    if plots:
        out["plots"] = make_plots(Path(plots), spec, theta, test, ref, r, cands, err, floor,
                                  train)
    return out


def curve_as_device(spec: ModelSpec, pool: dict, cands: list[dict], halves, best):
    """A curve whose straight part is in the model, not named by the fit on every training
    point: judged again as the device fits it, on its bins' selection, in both folds
    (pipeline/foldjudge.py: the bins keep the temperature extremes, so the model without the
    curve is fitted as its chord).  Its verdict goes in the candidate ("device_folds"); returns
    (the name, the candidate) when that judge names it, else (None, best)."""
    from accelcal.pipeline.foldjudge import device_folds
    for c in cands:
        e = pool.get(c["effect"])
        if e is None or c["heldout_error_mg"] is None or not any(
                (a, e) in curves({a.name: a, e.name: e}) for a in spec.parts):
            continue
        try:
            judged = device_folds(spec, spec.with_effect(e), halves)
        except (InputError, np.linalg.LinAlgError) as why:   # too few points kept to fit it
            c["device_folds_untestable"] = str(why)
            continue
        c["device_folds"] = judged
        if judged["named"]:
            c["evidence"] = "clear" if judged["clear"] else "weak"
            return c["effect"], c
    return None, best


def chosen(pool: dict, cands: list[dict]) -> dict | None:
    """The single candidate to name (None: none testable), chosen as the board chooses
    (acal.discover.rule.best, on the held-out errors in mg): the lowest error, a change point
    (the device's STEP, whatever its form) giving way to the best effect without one by the
    rule's parsimony factor."""
    kinds = [STEP if pool[c["effect"]].change_point else pool[c["effect"]].kind for c in cands]
    errs = [-1 if c["heldout_error_mg"] is None else c["heldout_error_mg"] for c in cands]
    i = rule.best(kinds, errs, len(cands))
    return cands[i] if i >= 0 else None


def curves(pool: dict) -> list[tuple]:
    """(straight, curve) pairs of the pool: an effect in a power of a regressor (temp_offset2)
    with its first power (temp_offset).  Alone, the curve hides behind its straight part, whose
    held-out gain is spread over every block while the curve's lies where the regressor is far
    from its reference; together they are named in one step when the curve is clear (docs/model-discovery.md
    "Curves")."""
    return [(a, b) for b in pool.values() for a in pool.values()
            if b.power == 2 and a.power == 1 and a.needs == b.needs == "temp"
            and a.form == b.form and not a.change_point and not b.change_point]


def candidate(cspec: ModelSpec, p, train, test, test_block, ref: dict, r, err: float,
              theta, added: int = 1) -> dict:
    """The model with `added` more effects (the last of cspec), fitted on the training blocks
    and scored on the held-out ones: its error, how much lower than err (that of the model
    without them, fitted as theta), in how many blocks."""
    new = cspec.parts[-added:]
    name = "+".join(e.name for e in new)
    try:
        ModelSpec.parse(str(cspec))   # one step per model
        check_model(cspec, p)
    except (InputError, ValueError) as why:
        return {"effect": name, "heldout_error_mg": None, "improvement_pct": None,
                "blocks_improved_pct": None, "untestable": str(why)}
    if added > 1:    # the straight part first: the curve starts from its fit
        theta, ref = fit_with_reference(ModelSpec(cspec.parts[:-1]), train, ref, rest_theta=theta)
    th, cref = fit_with_reference(cspec, train, ref, rest_theta=theta)
    _, rc = residuals(cspec, th, test, cref)
    ec = float(np.mean(np.abs(rc)) * 1e3)
    gain = np.abs(r) - np.abs(rc)
    blocks = np.unique(test_block)
    better = sum(bool(gain[test_block == b].mean() > 0) for b in blocks)
    out = {"effect": name, "heldout_error_mg": ec, "improvement_pct": 100 * (err - ec) / err,
           "blocks_improved_pct": 100 * better / len(blocks), "blocks_improved": better,
           "blocks": len(blocks),
           # judged where the share would name it: few blocks are weak evidence (block_evidence)
           "evidence": block_evidence(better, len(blocks))
           if rule.share_holds(int(better), len(blocks)) else None,
           "params": {k: v for i, e in enumerate(new) for k, v in zip(
               e.param_names, (th[len(th) - 3 * (added - i):][:3] * e.scale).round(4).tolist())},
           "param_unit": new[0].report_unit if added == 1 else ", ".join(
               f"{e.report_unit} ({e.param_names[0][0]})" for e in new)}
    if "ts" in cref and "ts" not in ref:
        out["step_time_s"] = cref["ts"]
        placed = place_step(cspec, th, train, test, cref)
        if placed:   # chosen on its placed error, leave-one-out, as the board chooses
            out.update(placed, heldout_error_unplaced_mg=ec,
                       heldout_error_mg=placed["heldout_error_placed_mg"],
                       improvement_pct=100 * (err - placed["heldout_error_placed_mg"]) / err)
    return out


def place_step(cspec: ModelSpec, theta, train, test, cref: dict) -> dict:
    """A step's time placed among the held-out points between the two training points that
    bracket the fitted one (the fit cannot tell where the shock lies between them): at the split
    of those points, between distinct times, whose | |a| - 1 | sums the lowest (of equal sums the
    later), halfway between its neighbours, as change_point places a time; as the board does
    (acal/discover/search.py, docs/model-discovery.md "Against the true sensor model").  Its held-out
    error leave-one-out (each gap point at the time the other gap points place) and in-sample;
    {} when no held-out point lies in the gap.  The step is chosen and named on the
    leave-one-out error (the points that place the time must not judge it); its blocks stay the
    fit's time's.  tests/pipeline/test_step_placement.py ties it to the board's."""
    ts = cref["ts"]
    before, after = train.t[train.t < ts], train.t[train.t >= ts]
    if not len(before) or not len(after):
        return {}
    lo, hi = before.max(), after.min()
    idx = np.flatnonzero((test.t > lo) & (test.t < hi))
    if not len(idx):
        return {}
    idx = idx[np.argsort(test.t[idx], kind="stable")]
    t = test.t[idx]
    stepped = np.abs(residuals(cspec, theta, test.take(idx), {**cref, "ts": -np.inf})[1])
    unstepped = np.abs(residuals(cspec, theta, test.take(idx), {**cref, "ts": np.inf})[1])
    n = len(idx)
    split_ok = np.r_[True, t[1:] > t[:-1], True]        # k points before the split, k = 0..n

    def best(left: int) -> int:
        c1, c0 = stepped.copy(), unstepped.copy()
        if left >= 0:
            c1[left] = c0[left] = 0.0
        cost = np.r_[0.0, np.cumsum(c0)] + np.r_[np.cumsum(c1[::-1])[::-1], 0.0]
        cost[~split_ok] = np.inf
        return int(n - np.argmin(cost[::-1]))          # of equal sums the later split

    k = best(-1)
    edges = np.r_[lo, t, hi]
    fitted = np.abs(residuals(cspec, theta, test, cref)[1])   # the fit's time halves the gap
    outside = fitted.sum() - fitted[idx].sum()
    insample = outside + unstepped[:k].sum() + stepped[k:].sum()
    loo = outside + sum(unstepped[j] if j < best(j) else stepped[j] for j in range(n))
    return {"step_time_placed_s": float(0.5 * (edges[k] + edges[k + 1])),
            "step_gap_points": n,
            "heldout_error_placed_mg": float(loo / len(test) * 1e3),
            "heldout_error_placed_insample_mg": float(insample / len(test) * 1e3)}


def block_evidence(better: int, blocks: int) -> str:
    """"clear" when `better` of `blocks` held-out blocks improving is a share the rule names and
    more than chance (rule.clear: a one-sided sign test, each block a coin toss, at one
    time in rule.CHANCE_ONE_IN), else "weak"."""
    return "clear" if rule.clear(int(better), int(blocks)) else "weak"


def regressors(spec, theta, test, ref) -> dict[str, np.ndarray]:
    """What a held-out residual is looked at against (report/figures.regressors, which the
    residuals figure draws): time (h), temperature where the file has it, each corrected axis,
    |v|, and each further column of the recording ("column:NAME", as an effect declares it)."""
    from accelcal.report.figures import regressors as listed
    a, _ = residuals(spec, theta, test, ref)
    return {key: x for key, _, x in listed(test, a)}


def where_it_fails(regs: dict, r) -> dict:
    """Held-out residuals against each regressor (regressors()): correlation and the residual's
    spread across the regressor's quintiles (mg) - a flat line is a model that does not fail
    there."""
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
    """residuals.png (where the model fails: accelcal.report.figures), candidates.png (each catalogue
    effect's held-out error) and, for a composed model, step.png: the residuals before and after
    its last effect, side by side on one y-range."""
    from accelcal.report import figures
    plt = figures.pyplot()
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
        before = ModelSpec(spec.parts[:-1])
        th0 = fit(before, train, ref)
        a0, r0 = residuals(before, th0, test, ref)
        fig = figures.before_after_figure(test, a0, r0 * 1e3, a, r * 1e3, floor, str(before),
                                          str(spec))
        f3 = d / "step.png"
        save_figure(fig, f3, dpi=70)
        plt.close(fig)
        out.append(str(f3))
    return out


def heldout_error_of(path: str, model: str, theta, ref: dict) -> float:
    """The held-out error (mg, same split as diagnose) of given parameters: for the truth."""
    spec = ModelSpec.parse(model)
    _, test, _ = split(usable(rest_points(path)))
    _, r = residuals(spec, np.asarray(theta, dtype=np.float64), test, ref)
    return float(np.mean(np.abs(r)) * 1e3)
