"""How `diagnose`'s judge would name one candidate if it judged the fit the device makes, and in
both folds of its split (issue 30 part 2: curve seed 4; docs/model-discovery.md "Curves").

A wrist (accelcal.simulate.wearer, as the held-out study makes it: FIT_DAYS at 10 Hz with one
hidden effect or none) gives its rest points; they are cut into diagnose's 2-hour blocks.  For
each fold (train on the even blocks and score the odd ones, diagnose's own; and the reverse) the
model and the model with the candidate are fitted by float least squares on

    all   every training rest point (what diagnose fits today), or
    bins  the points the device's bins (wear profile, the candidate model's conditions) select
          from the training rest points and its fit keeps (what the device will fit),

and scored on the other fold's rest points: the held-out error (mg), how many blocks improve,
and whether acal.discover.rule.names would name the candidate.  "both" pools the two folds (every
rest point scored once, the blocks of both).  diagnose judges a curve on its straight part so
("bins", both folds: pipeline/foldjudge.py) when its fit on every point does not name it.

    python -m accelcal.studies.judge_folds CASE SEED MODEL CANDIDATE
    e.g. python -m accelcal.studies.judge_folds temp_offset2 4 base+temp_offset temp_offset2
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from acal.discover import rule
from accelcal.model.effects import CATALOGUE, ModelSpec
from accelcal.pipeline.foldjudge import fold_gain
from accelcal.pipeline.restpoints import BLOCK_S


def judge(path: str, model: str, cand: str) -> list[dict]:
    """One row per fit (all, bins) and fold (even, odd: the blocks trained on; both)."""
    from accelcal.pipeline.composed_lsq import prepare
    spec, p = prepare(path, model)
    cspec = spec.with_effect(CATALOGUE[cand])
    block = ((p.t - p.t.min()) // BLOCK_S).astype(int)
    rows = []
    for how in ("all", "bins"):
        pooled = []
        for parity, fold in ((0, "even"), (1, "odd")):
            tr = block % 2 == parity
            r0, rc, better, points = fold_gain(spec, cspec, p.take(tr), p.take(~tr), block[~tr],
                                               how)
            nb = len(np.unique(block[~tr]))
            pooled.append((r0, rc, better, nb))
            rows.append(row(how, fold, points, r0, rc, better, nb))
        rows.append(row(how, "both", None, np.concatenate([x[0] for x in pooled]),
                        np.concatenate([x[1] for x in pooled]), sum(x[2] for x in pooled),
                        sum(x[3] for x in pooled)))
    return rows


def row(how, fold, points, r0, rc, better, blocks) -> dict:
    before, after = float(r0.mean() * 1e3), float(rc.mean() * 1e3)
    return {"fit": how, "train": fold, "points": points, "before_mg": before, "after_mg": after,
            "improvement_pct": 100 * (before - after) / before, "blocks_improved": better,
            "blocks": blocks, "named": bool(rule.names(before, after, better, blocks))}


def main(argv=None) -> int:
    from accelcal.simulate import wearer
    from accelcal.studies.heldout import FIT_DAYS, RATE
    ap = argparse.ArgumentParser(allow_abbrev=False, prog="python -m accelcal.studies.judge_folds", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("case", help="clean or a catalogue effect hidden in the wrist")
    ap.add_argument("seed", type=int)
    ap.add_argument("model", help="the model diagnosed, e.g. base+temp_offset")
    ap.add_argument("candidate", help="the effect judged, e.g. temp_offset2")
    a = ap.parse_args(argv)
    for e in (a.case, a.candidate):
        if e != "clean" and e not in CATALOGUE:
            ap.error(f"unknown effect {e}")
    try:
        ModelSpec.parse(a.model)
    except ValueError as why:
        ap.error(str(why))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{a.case}_{a.seed}.csv"
        wearer.simulate_wrist(path, FIT_DAYS, RATE, a.seed,
                              effect=[] if a.case == "clean" else [a.case])
        rows = judge(str(path), a.model, a.candidate)
    for r in rows:
        print(f"{a.case} seed {a.seed}: {a.model} +{a.candidate}, fit on {r['fit']:<4} train "
              f"{r['train']:<4} {r['before_mg']:.3f} -> {r['after_mg']:.3f} mg "
              f"({r['improvement_pct']:+.1f} %), {r['blocks_improved']}/{r['blocks']} blocks"
              f"{', named' if r['named'] else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
