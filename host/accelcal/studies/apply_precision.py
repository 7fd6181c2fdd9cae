"""What the device apply's output format costs a still wrist (issue 30, part 1).

Each case is a simulated wrist (accelcal.simulate.wearer, no hidden effect) of FIT_DAYS + TEST_DAYS
at 10 Hz and one full scale.  One float fit - the 9-parameter least squares on every rest point of
the fit part (composed_lsq.calibrate_model) - is scored on the test part's strictly still 5 s
windows (heldout.STRICT_G), mean | |a| - 1 g | in mg, with a each window's mean of the calibrated
samples, written three ways: the samples as read corrected in floats; the device's samples (Q10
g, what the apply takes in) corrected in floats, the yardstick; and those through the device's
apply as `accelcal apply` writes it (pipeline/apply.py, the twin of acal.core.calibration, in the
apply's output format, fixed.py).  The last two differ by what the apply's formats cost.

    python -m accelcal.studies.apply_precision [--seeds 1,2,3] [--ranges 2,8] [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from acal.core import fixed

FIT_DAYS, TEST_DAYS, RATE, SECONDS = 3, 2, 10, 5


def still_windows(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(samples m x 3 in g as read, window starts): the strictly still 5 s windows of a
    recording (heldout.STRICT_G on every axis, |mean| within 0.5-1.5 g)."""
    from accelcal.files.recordings import open_recording
    from accelcal.pipeline.scan import scan
    from accelcal.studies.heldout import STRICT_G
    rec = open_recording(str(path))
    xyz = np.concatenate([c.xyz for c in rec.chunks()])
    sc = scan(open_recording(str(path)), SECONDS, int(np.ceil(STRICT_G * fixed.SAMPLE_ONE_G)), 3)
    seg = sc.segments
    mag = np.linalg.norm(seg.mean / float(fixed.POINT_ONE_G), axis=1)
    keep = seg.still & (mag > 0.5) & (mag < 1.5)
    return xyz, seg.end[keep] - (SECONDS * RATE - 1)


def score_mg(a: np.ndarray, starts: np.ndarray) -> float:
    """mean | |window mean| - 1 g | in mg over the windows starting at `starts`."""
    idx = starts[:, None] + np.arange(SECONDS * RATE)[None, :]
    means = a[idx].mean(axis=1)
    return float(np.mean(np.abs(np.linalg.norm(means, axis=1) - 1.0)) * 1e3)


def run_case(case: tuple[int, int], workdir: str) -> dict:
    range_g, seed = case
    from accelcal.fixedpoint import g_to_sample, sample_to_g
    from accelcal.methods import correct
    from accelcal.pipeline.apply import apply_to_samples
    from accelcal.pipeline.composed_lsq import calibrate_model
    from accelcal.simulate import wearer
    from accelcal.studies.heldout import split
    d = Path(workdir)
    whole, fit, test = (d / f"w{range_g}_{seed}{s}.csv" for s in ("", ".fit", ".test"))
    wearer.simulate_wrist(whole, FIT_DAYS + TEST_DAYS, RATE, seed, range_g=range_g)
    split(whole, fit, test)
    lsq = calibrate_model(str(fit), "base")
    theta = np.array(list(lsq["params"].values()))
    p_int = list(lsq["params_int"].values())
    xyz, starts = still_windows(test)
    # the windows are whole segments of consecutive samples (no gaps in a simulated wrist)
    row = {"range_g": range_g, "seed": seed, "windows": len(starts),
           "output_q": fixed.APPLY_OUT_Q - fixed.apply_range_shift(range_g),
           "float_as_read_mg": score_mg(correct(theta, xyz), starts),
           # the yardstick: the device's own input (Q10 samples: its rounding is the sensor's
           # digit's, not the apply's), corrected in floats
           "float_mg": score_mg(correct(theta, sample_to_g(g_to_sample(xyz))), starts),
           "device_mg": score_mg(apply_to_samples(p_int, xyz, range_g=range_g), starts)}
    for f in d.glob(f"w{range_g}_{seed}*"):
        f.unlink()
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(allow_abbrev=False, prog="python -m accelcal.studies.apply_precision",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--ranges", default="2,8")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    cases = [(int(r), int(s)) for r in a.ranges.split(",") for s in a.seeds.split(",")]
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(a.jobs) as pool:
        rows = list(pool.map(run_case, cases, [tmp] * len(cases)))
    if a.json:
        print(json.dumps(rows))
        return 0
    for r in rows:
        print(f"+-{r['range_g']:<2} g seed {r['seed']}: {r['windows']:5d} windows, float as read "
              f"{r['float_as_read_mg']:.3f} mg, float of Q10 samples {r['float_mg']:.3f} mg, "
              f"device (Q{r['output_q']}) {r['device_mg']:.3f} mg")
    for rg in dict.fromkeys(r["range_g"] for r in rows):
        rs = [r for r in rows if r["range_g"] == rg]
        print(f"+-{rg} g, mean of {len(rs)} seeds: " + ", ".join(
            f"{k} {np.mean([r[k + '_mg'] for r in rs]):.3f} mg"
            for k in ("float_as_read", "float", "device")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
