"""The board's own discovery as `calibrate --discover` reports it (acal/discover/search.py, the runner's
V, W and H records; docs/model-discovery.md "Discovery on the board"): each round's effect
adopted or closest candidate, the held-out error before and after, its blocks and candidates."""
from __future__ import annotations

import numpy as np

from acal.core import effects as deff
from acal.core import fixed
from acal.discover.search import MIN_BLOCKS, MIN_HELD, N_ALL
from accelcal.bridge import runtime
from accelcal.fixedpoint import physical, seconds
from accelcal.bridge.boardlog import model_kinds, model_name
from accelcal.model.effects import ModelSpec


def heldout_mg(err: int, weight: int) -> float | None:
    """A held-out error of the board (score.py: the sum of | |a|^2 - 1 g^2 |, Q16 g^2, each
    point's weighted by the rest means it stands for, `weight` in all) as mean | |a| - 1 g | in mg,
    near 1 g: |a|^2 - 1 ~ 2 (|a| - 1)."""
    return err / weight / (2 * fixed.POINT_ONE_G) * 1e3 if weight and err >= 0 else None


def heldout_set(r: runtime.DeviceResult, t_first: float) -> dict:
    """The board's held-out points (the runner's H records) in physical units, as lists: xyz_g,
    temp (degC), time (s on the recording's clock), supply (mV) and weight (the rest means each
    stands for)."""
    h = np.array(r.heldout, dtype=np.int64).reshape(-1, 7)
    c = physical(h[:, 3:6], t_first)
    return {"xyz_g": (h[:, :3] / fixed.POINT_ONE_G).tolist(), "temp": c.temp.tolist(),
            "time": c.time.tolist(), "supply": c.supply.tolist(), "weight": h[:, 6].tolist()}


def discovery_record(r: runtime.DeviceResult, t_first: float = 0.0) -> dict:
    """The board's own discovery (acal/discover/search.py, the runner's V and W records): the effect
    adopted (None: none) or the closest candidate, the held-out error before and after (the
    board's integers and in mg), its blocks, each candidate, and the adopted model's parameters;
    `heldout_set`; `rounds`, each later round (after an adoption, from the adopted model, up to
    the model's limit) so; `effects`, every effect adopted, in order."""
    if r.discovery is None:
        return {"effect": None, "closest": None, "reason": "no discovery ran (the base fit did "
                "not end OK)", "rounds": [], "effects": []}
    out = _round(r, r.discovery, r.candidates, t_first, "base")
    out["heldout_set"] = heldout_set(r, t_first)
    out["rounds"] = []
    for v, w in r.rounds:   # each from the model the round before adopted
        base = (out["rounds"] or [out])[-1].get("model", "base")
        out["rounds"].append(_round(r, v, w, t_first, base))
    adopted = [d["effect"] for d in [out] + out["rounds"] if d["effect"]]
    out["effects"] = adopted[-1].split("+") if adopted else []
    return out


def _round(r: runtime.DeviceResult, v: list[int], cands: list, t_first: float,
           base: str) -> dict:
    # one round's V record and its W records, from the model `base`
    adopted, closest, before, after, betters, blocks, held, weight, step_time = v[:9]
    p_int = v[9:9 + N_ALL]
    fitted_time, unplaced, placed_insample, gap_n = v[9 + N_ALL:13 + N_ALL]
    out = {"effect": model_name(adopted), "closest": model_name(closest),
           "heldout_points": held, "heldout_rest_means": weight,
           "heldout_before": before, "heldout_after": after,
           "heldout_error_before_mg": heldout_mg(before, weight),
           "heldout_error_after_mg": heldout_mg(after, weight) if closest else None,
           "blocks_better": betters, "blocks": blocks,
           "candidates": [{"effect": model_name(k), "heldout": e, "heldout_error_mg":
                           heldout_mg(e, weight), "blocks_better": b} for k, e, b in cands]}
    if held < MIN_HELD or blocks < MIN_BLOCKS or before <= 0:
        out["reason"] = (f"{held} held-out rest points in {blocks} held-out 2-hour blocks "
                         f"(the board tries from {MIN_HELD} in {MIN_BLOCKS})")
    if closest:
        spec = ModelSpec.parse(f"base+{out['closest']}")
        p_int = p_int[:len(spec.param_names)]
        out["model"] = str(spec) if adopted else base
        out["params_int"] = dict(zip(spec.param_names, map(int, p_int)))
        out["params"] = dict(zip(spec.param_names, spec.from_int(p_int).tolist()))
        if deff.STEP in model_kinds(closest):
            out["step_time_s"] = t_first + seconds(r.ref[fixed.C_TIME] + step_time)
            if placed_insample >= 0:
                # the step's time placed in its gap (acal/discover/stepplace.py): its error (after) the
                # placed one's, leave-one-out; the fit's time's and in-sample beside it
                out["step_time_fitted_s"] = t_first + seconds(r.ref[fixed.C_TIME] + fitted_time)
                out["step_gap_points"] = gap_n
                out["heldout_unplaced"] = unplaced
                out["heldout_error_unplaced_mg"] = heldout_mg(unplaced, weight)
                out["heldout_error_placed_insample_mg"] = heldout_mg(placed_insample, weight)
    return out




def discovered_model(d: dict) -> tuple[str, list[int], float | None] | None:
    """The model a discovery ended with (the last round that adopted an effect): its name, its
    integer parameters (Q24, relative to the device fit's references) and, for a step, the
    step's time (s on the recording's clock); None when nothing was adopted."""
    adopted = [x for x in [d] + list(d.get("rounds", ())) if x.get("effect")]
    if not adopted:
        return None
    last = adopted[-1]
    spec = ModelSpec.parse(last["model"])
    return str(spec), [int(last["params_int"][n]) for n in spec.param_names], \
        last.get("step_time_s")
