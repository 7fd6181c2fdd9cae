"""A candidate judged as the device will fit it, in both folds of diagnose's split.

diagnose fits each candidate by least squares on every training rest point and scores it on the
held-out blocks.  The device fits fewer points: what its bins keep, and the wear profile's bins
keep each posture's extremes of temperature and time (acal/core/bins.py, spread slots).  For a curve
whose straight part is in the model this matters: the model without the curve, fitted on those
extremes, is the curve's chord, off where the wrist mostly is, and when the rare extremes (a
shower, the first hour) all fall in the held-out blocks neither fit on the training blocks sees
them (docs/model-discovery.md, "Curve seed 4, measured").  So here both models are fitted as the
device fits them, on the bins' selection of the training half, and each half is held out in turn:

    fold 1  train the split's training half, score its held-out half (diagnose's own);
    fold 2  the reverse (split() has checked that both halves cover the sphere);

the folds' held-out errors pooled (every rest point scored once) and their blocks counted
together, under the same rule (acal.discover.rule.names).
"""
from __future__ import annotations

import numpy as np

from acal.discover import rule
from acal.core import fixed
from acal.core.bins import COND
from accelcal.fixedpoint import physical
from accelcal.model.effects import ModelSpec
from accelcal.pipeline.composed_lsq import fit_with_reference, refs, residuals
from accelcal.pipeline.restpoints import Halves, RestPoints


def bins_selection(spec: ModelSpec, pts: RestPoints) -> RestPoints:
    """The rest points the device's bins (wear profile, spec's conditions) keep from pts and its
    fit keeps of those: what the device fits spec on."""
    from accelcal.bridge import runtime
    from accelcal.bridge.groups import PointsGroup
    from accelcal.pipeline.calibrate import _device_spec
    _, cfg = _device_spec(spec, "lsq", runtime.Config.for_profile("wear", True))
    g = PointsGroup("train", points=pts.v, temp=pts.temp, t=pts.t)
    r = runtime.run([g], cfg, "cpython")[0]
    sel = np.array(r.selected_int, dtype=np.int64).reshape(-1, 3 + COND)
    if r.kept is not None:
        sel = sel[np.asarray(r.kept, bool)]
    c = physical(sel[:, 3:], g.t_first)     # the bins' conditions as the host reads them
    return RestPoints(sel[:, :3] / fixed.POINT_ONE_G, c.time, c.temp, np.zeros(len(sel)), "bins")


def fold_gain(spec: ModelSpec, cspec: ModelSpec, train: RestPoints, test: RestPoints,
              test_block: np.ndarray, points: str = "bins"):
    """One fold: spec and cspec (spec with the candidate) fitted on train (points "bins": the
    device bins' selection for cspec; "all": every point), scored on test.  Returns |r| of each
    on the test points, how many of test's blocks improve and how many points were fitted."""
    pts = bins_selection(cspec, train) if points == "bins" else train
    th0, ref0 = fit_with_reference(spec, pts, refs(pts, spec))
    _, r0 = residuals(spec, th0, test, ref0)
    th, ref = fit_with_reference(cspec, pts, refs(pts, cspec), rest_theta=th0)
    _, rc = residuals(cspec, th, test, ref)
    gain = np.abs(r0) - np.abs(rc)
    better = sum(bool(gain[test_block == b].mean() > 0) for b in np.unique(test_block))
    return np.abs(r0), np.abs(rc), better, len(pts)


def device_folds(spec: ModelSpec, cspec: ModelSpec, halves: Halves) -> dict:
    """cspec judged against spec as the device fits them, both folds of halves pooled (module
    doc): held-out errors (mg) before and after, blocks better, and whether the rule names it."""
    train, test, test_block = halves
    folds = [fold_gain(spec, cspec, train, test, test_block),
             fold_gain(spec, cspec, test, train, halves.train_block)]
    before = float(np.mean(np.concatenate([f[0] for f in folds])) * 1e3)
    after = float(np.mean(np.concatenate([f[1] for f in folds])) * 1e3)
    better = sum(f[2] for f in folds)
    blocks = len(np.unique(test_block)) + len(np.unique(halves.train_block))
    return {"before_mg": before, "after_mg": after,
            "improvement_pct": 100 * (before - after) / before, "blocks_improved": better,
            "blocks": blocks, "named": bool(rule.names(before, after, better, blocks)),
            "clear": bool(rule.clear(int(better), blocks))}
