"""What `diagnose` says in words: an effect named (and why), a second step due, or no effect
named and how far what remains stands above the floors (pipeline/diagnose.py builds the
figures; the rule is acal/discover/rule.py's)."""
from __future__ import annotations

from acal.discover import rule
from accelcal.files.recordings import sensor_of
from accelcal.model.effects import ModelSpec

# held-out error / wrist floor up to which a model with no lead is called complete (the floor's
# pairs see fewer postures than the held-out points; complete models measured 1.0-1.8x it)
COMPLETE_WITHIN = 1.25


def noise_text(noise: float | None) -> str:
    """The noise floor in words (None: not measured, the rest points carry no samples)."""
    return (f"a noise floor of {noise:.2f} mg" if noise is not None else
            "no noise floor (the rest points carry no samples to measure the sensor's noise on)")


def few_blocks(blocks: int) -> str:
    """When even the least share of blocks the rule names would be weak evidence (rule.
    clear: a count chance alone gives too often), that a longer recording would tell."""
    least = -(-rule.MIN_BLOCK_SHARE_PCT * blocks // 100)
    return "" if rule.clear(least, blocks) else (
        f"; with {blocks} held-out blocks even {least} of {blocks} better would be weak "
        "evidence: a longer recording (more 2-hour blocks) would tell")


def complete_text(err: float, noise: float | None, wrist: float | None) -> str:
    """What diagnose says when no effect is named and nothing that remains holds up."""
    sensor = f"{noise:.2f} mg" if noise is not None else "not measured here"
    against = (f"a wrist floor of {wrist:.2f} mg (what rest on a wrist carries beyond the "
               f"sensor's noise, {sensor})" if wrist is not None else
               f"{noise_text(noise)} (too few pairs of nearby postures to estimate the wrist "
               "floor)")
    if wrist is not None and err <= COMPLETE_WITHIN * wrist:
        return (f"The model is complete: it explains the data to within what rest on a wrist "
                f"allows (held-out error {err:.2f} mg against {against}); nothing that remains "
                "holds up in held-out blocks.")
    if wrist is not None:   # more remains than a wrist carries, but nothing shows where
        return (f"Held-out error {err:.2f} mg is {err / wrist:.1f}x {against}: more remains "
                "than rest on a wrist carries, but no shape of it holds up in held-out blocks, "
                "so there is no lead to follow.")
    return (f"Held-out error {err:.2f} mg against {against}; no shape of what remains holds up "
            "in held-out blocks, so there is no lead to follow.")


def named_text(spec: ModelSpec, named: str, parts: list, best: dict, err: float, floor: float,
               path: str) -> str:
    """What diagnose says when it names an effect (parts: its effects, a curve's two)."""
    host = " --method lsq --points all (it runs on the host only)" \
        if any(e.kind is None for e in parts) else ""
    weak = "" if best["evidence"] == "clear" else (
        " Weak evidence: so few blocks better is a count chance alone gives too often; "
        "confirm it on a longer recording.")
    both = "" if len(parts) == 1 or "single_ratio" not in best else (
        f" Both parts at once: with its straight part the curve leaves "
        f"{best['single_ratio']:.1f}x less held-out error than the best single effect "
        f"({rule.STEP_PARSIMONY_TENTHS / 10:g}x needed).")
    gain = (f"Adding it lowers the held-out error from {err:.2f} to "
            f"{best['heldout_error_mg']:.2f} mg, better in {best['blocks_improved']} of "
            f"{best['blocks']} held-out blocks ({noise_text(floor)})")
    judged = best.get("device_folds")
    if judged:   # named by curve_as_device
        gain = (f"Fitted as the device fits it (on what its bins keep) with each half of the split "
                f"held out in turn, adding it lowers the held-out error from "
                f"{judged['before_mg']:.2f} to {judged['after_mg']:.2f} mg, better in "
                f"{judged['blocks_improved']} of {judged['blocks']} blocks (fitted on every "
                f"training point and scored on the held-out half alone: {err:.2f} to "
                f"{best['heldout_error_mg']:.2f} mg, {best['blocks_improved']} of "
                f"{best['blocks']}; the device's bins keep the rare temperature extremes, where "
                f"a straight line is the curve's chord; {noise_text(floor)})")
    return (f"{named}: {parts[-1].explain(sensor_of(path))}{both} Fitted here: "
            + ", ".join(f"{k} {v:+g}" for k, v in best["params"].items())
            + f" {best['param_unit']}. {gain}.{weak} Next: "
            f"accelcal calibrate --model {spec}+{named}{host}")


def second_step_text(spec: ModelSpec, named: str, curve, cands: list[dict]) -> str:
    """What diagnose says when it names a curve's straight part alone: a second step is due, the
    curve judged on top of it (docs/model-discovery.md "Curves")."""
    pair = next((c for c in cands if c["effect"] == f"{named}+{curve.name}"), None)
    seen = ""
    if pair is not None and pair["heldout_error_mg"] is not None:
        seen = (f" (here both parts at once left {pair['heldout_error_mg']:.2f} mg held out, "
                f"better in {pair['blocks_improved']} of {pair['blocks']} blocks: not enough to "
                "name them in one step)")
    return (f"A second step is due: {curve.name}, the curve {named} may be the straight part "
            f"of, is judged only with {named} in the model{seen}; run accelcal diagnose --model "
            f"{spec}+{named} next.")
